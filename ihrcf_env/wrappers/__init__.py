"""Gymnasium wrappers over :class:`~ihrcf_env.envs.DeckLandingEnv`."""

from ihrcf_env.wrappers.estimates import (
    DeckPoseObservation,
    check_wrapper_options,
    estimator_from_calibration,
    flat_slices,
    make_deck_landing,
)

__all__ = [
    "DeckPoseObservation",
    "check_wrapper_options",
    "estimator_from_calibration",
    "flat_slices",
    "make_deck_landing",
]
