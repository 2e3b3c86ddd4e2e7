"""Reason codes of IHRCF and ATDA: small integers indexing :data:`REASONS`, the texts the
single-frame estimators (:mod:`ihrcf_env.core.estimators.ihrcf`, :mod:`~ihrcf_env.core.estimators.atda`)
write into an invalid :class:`~ihrcf_env.core.estimators.base.PoseEstimate`.

Array implementations of the estimators (the JAX backend, :mod:`ihrcf_env.fast`) return these
codes instead of strings: code ``c`` of a frame is invalid with reason ``REASONS[c]``, the
first check that fails in the single estimator's order (:data:`FIT_RESIDUAL` is a template
filled with the rigid-fit RMS and the threshold, m; :data:`NOT_DETECTED` stands for the frame's
own reason when it has one).
"""

from __future__ import annotations

from ihrcf_env.core.estimators.base import TAG_NOT_FOUND

OK = 0
NOT_DETECTED = 1
NONFINITE_CORNERS = 2
FEW_RANGES = 3
PLANE_COINCIDENT = 4
PLANE_COLLINEAR = 5
PLANE_PARALLEL = 6
PREDICTED_RANGE = 7
OUTSIDE_TABLE = 8
NONFINITE_TOUCH = 9
DEGENERATE_LAYOUT = 10
DEGENERATE_TOUCH = 11
HOMOGRAPHY_NOT_UNIQUE = 12
HOMOGRAPHY_H22 = 13
CORNER_AT_INFINITY = 14
CORNER_BEHIND = 15
FIT_NONFINITE = 16
FIT_COLLINEAR = 17
FIT_RESIDUAL = 18
DEGENERATE_TAG = 19
PNP_NO_SOLUTION = 20
TAG_BEHIND = 21

#: Reason text of each code, as the single estimators write it (the geometry kernels' ValueError
#: texts of :mod:`ihrcf_env.core.geometry` inside IHRCF's).
REASONS: tuple[str, ...] = (
    "",
    TAG_NOT_FOUND,
    "non-finite tag corners",
    "fewer than 3 valid ranges",
    "deck plane undefined: points are all coincident: plane undefined",
    "deck plane undefined: points are collinear: plane undefined",
    "deck plane undefined: plane is parallel to the z axis: z is undefined",
    "predicted range not positive",
    "range outside calibration table",
    "non-finite touch pixels",
    "degenerate sensor layout",
    "degenerate touch pixels",
    "homography failed: degenerate point configuration: homography is not unique",
    "homography failed: homography has H[2, 2] = 0 and cannot be normalised",
    "tag corner maps to infinity",
    "tag corner behind the camera",
    "rigid fit failed: non-finite corners",
    "rigid fit failed: P is collinear or coincident: rotation undefined",
    "fit residual {rms:.4g} m > {max_residual:.4g} m",
    "degenerate tag corners",
    "solvePnP found no solution",
    "tag behind the camera",
)


def reason_text(code: int, fit_rms: float = float("nan"), max_residual: float = float("nan")) -> str:
    """The text of ``code`` (:data:`FIT_RESIDUAL` filled with ``fit_rms`` and ``max_residual``)."""
    c = int(code)
    if c == FIT_RESIDUAL:
        return REASONS[c].format(rms=float(fit_rms), max_residual=float(max_residual))
    return REASONS[c]


__all__ = [
    "CORNER_AT_INFINITY",
    "CORNER_BEHIND",
    "DEGENERATE_LAYOUT",
    "DEGENERATE_TAG",
    "DEGENERATE_TOUCH",
    "FEW_RANGES",
    "FIT_COLLINEAR",
    "FIT_NONFINITE",
    "FIT_RESIDUAL",
    "HOMOGRAPHY_H22",
    "HOMOGRAPHY_NOT_UNIQUE",
    "NONFINITE_CORNERS",
    "NONFINITE_TOUCH",
    "NOT_DETECTED",
    "OK",
    "OUTSIDE_TABLE",
    "PLANE_COINCIDENT",
    "PLANE_COLLINEAR",
    "PLANE_PARALLEL",
    "PNP_NO_SOLUTION",
    "PREDICTED_RANGE",
    "REASONS",
    "TAG_BEHIND",
    "reason_text",
]
