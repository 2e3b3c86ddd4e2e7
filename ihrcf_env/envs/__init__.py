"""Gymnasium environments and their validated configuration."""

from ihrcf_env.envs.config import DeckLandingConfig, ObservationConfig, make_config
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.envs.task_config import TaskConfig

__all__ = ["DeckLandingConfig", "DeckLandingEnv", "ObservationConfig", "TaskConfig", "make_config"]
