"""Deck-pose estimators (pure numpy / scipy / OpenCV; no simulator).

Every estimator reports the pose of the **deck** frame in the drone **body** frame as a
:class:`PoseEstimate`. ``ihrcf`` (the paper's method), ``atda`` (AprilTag + PnP baseline),
``detector`` (tag corners), ``pipeline`` (one frame through all of them).
"""

from ihrcf_env.core.estimators.atda import AMBIGUITY_RATIO, R_DECK_MARKER, atda_estimate
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL, PoseEstimate
from ihrcf_env.core.estimators.detector import APRILTAG_CORNER_OFFSET_PX, TagDetector
from ihrcf_env.core.estimators.ihrcf import TouchPixels, ihrcf_estimate
from ihrcf_env.core.estimators.pipeline import DeckPoseEstimator

__all__ = [
    "AMBIGUITY_RATIO",
    "APRILTAG_CORNER_OFFSET_PX",
    "DEGENERATE_REL_TOL",
    "R_DECK_MARKER",
    "DeckPoseEstimator",
    "PoseEstimate",
    "TagDetector",
    "TouchPixels",
    "atda_estimate",
    "ihrcf_estimate",
]
