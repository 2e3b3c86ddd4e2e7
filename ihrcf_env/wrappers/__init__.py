"""Gymnasium wrappers over :class:`~ihrcf_env.envs.DeckLandingEnv`."""

from ihrcf_env.wrappers.estimates import DeckPoseObservation, estimator_from_calibration, make_deck_landing

__all__ = ["DeckPoseObservation", "estimator_from_calibration", "make_deck_landing"]
