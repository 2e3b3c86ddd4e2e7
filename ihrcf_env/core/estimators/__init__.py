"""Deck-pose estimators (pure numpy / scipy / OpenCV; no simulator).

Every estimator reports the pose of the **deck** frame in the drone **body** frame as a
:class:`PoseEstimate`, and implements :class:`DeckPoseSource` (``name``, ``reset()``,
``update(SensorFrame) -> PoseEstimate``). ``base`` (the shared records and the protocol), ``ihrcf``
(the paper's method), ``atda`` (AprilTag + PnP baseline), ``fused`` (IHRCF + ATDA's attitude + the
IMU in a causal Kalman filter; with ``fused_params``, ``fused_measurements`` and ``imm``, the
interacting-multiple-model Kalman bank), ``detector`` (tag corners), ``registry`` (name -> estimator: the one
place to add one), ``pipeline`` (one frame through all of them).
"""

from ihrcf_env.core.estimators.atda import (
    AMBIGUITY_RATIO,
    R_DECK_MARKER,
    ATDAEstimator,
    atda_candidates,
    atda_choose,
    atda_estimate,
)
from ihrcf_env.core.estimators.base import (
    DEGENERATE_REL_TOL,
    TAG_NOT_FOUND,
    DeckPoseSource,
    ImuSample,
    PoseEstimate,
    SensorFrame,
)
from ihrcf_env.core.estimators.detector import APRILTAG_CORNER_OFFSET_PX, TagDetector
from ihrcf_env.core.estimators.fused import FusedEstimator, FusedParams
from ihrcf_env.core.estimators.ihrcf import (
    IHRCFCorners,
    IHRCFEstimator,
    TouchPixels,
    ihrcf_corners,
    ihrcf_estimate,
    ihrcf_fit,
    ihrcf_measure,
)
from ihrcf_env.core.estimators.pipeline import DeckPoseEstimator
from ihrcf_env.core.estimators.registry import (
    DEFAULT_ESTIMATORS,
    ESTIMATORS,
    EstimatorConfig,
    build_estimators,
    check_estimator_names,
)

__all__ = [
    "AMBIGUITY_RATIO",
    "APRILTAG_CORNER_OFFSET_PX",
    "DEFAULT_ESTIMATORS",
    "DEGENERATE_REL_TOL",
    "ESTIMATORS",
    "R_DECK_MARKER",
    "TAG_NOT_FOUND",
    "ATDAEstimator",
    "DeckPoseEstimator",
    "DeckPoseSource",
    "EstimatorConfig",
    "FusedEstimator",
    "FusedParams",
    "IHRCFCorners",
    "IHRCFEstimator",
    "ImuSample",
    "PoseEstimate",
    "SensorFrame",
    "TagDetector",
    "TouchPixels",
    "atda_candidates",
    "atda_choose",
    "atda_estimate",
    "build_estimators",
    "check_estimator_names",
    "ihrcf_corners",
    "ihrcf_estimate",
    "ihrcf_fit",
    "ihrcf_measure",
]
