"""Gymnasium wrappers over :class:`~ihrcf_env.envs.DeckLandingEnv`: the deck-pose estimates as
sensors (:class:`DeckPoseObservation`, Dict or flat) and the landing task's flat observation
(:class:`LandingObservation`)."""

from ihrcf_env.wrappers.estimates import DeckPoseObservation, flat_slices, hover_layout, make_deck_hover
from ihrcf_env.wrappers.estimator_stage import EstimatorStage, estimator_from_calibration
from ihrcf_env.wrappers.landing_obs import (
    LandingObservation,
    landing_obs_fields,
    make_deck_landing_v1,
    make_deck_landing_v2,
    make_landing,
)

__all__ = [
    "DeckPoseObservation",
    "EstimatorStage",
    "LandingObservation",
    "estimator_from_calibration",
    "flat_slices",
    "hover_layout",
    "landing_obs_fields",
    "make_deck_hover",
    "make_deck_landing_v1",
    "make_deck_landing_v2",
    "make_landing",
]
