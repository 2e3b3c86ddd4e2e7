"""Gymnasium environments of the deck tasks; their configuration is :mod:`ihrcf_env.config`."""

from ihrcf_env.envs.deck_landing import DeckLandingEnv

__all__ = ["DeckLandingEnv"]
