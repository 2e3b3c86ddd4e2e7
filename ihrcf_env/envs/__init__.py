"""Gymnasium environments and their validated configuration."""

from ihrcf_env.envs.config import DeckLandingConfig, TaskConfig, make_config
from ihrcf_env.envs.deck_landing import DeckLandingEnv

__all__ = ["DeckLandingConfig", "DeckLandingEnv", "TaskConfig", "make_config"]
