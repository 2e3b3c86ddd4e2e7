"""Gymnasium environments."""

from ihrcf_env.envs.deck_landing import DeckLandingEnv

__all__ = ["DeckLandingEnv"]
