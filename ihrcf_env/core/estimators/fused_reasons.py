"""Reason codes of the IMU-fused filter (:class:`~ihrcf_env.core.estimators.fused.FusedEstimator`).

The filter's reason for an invalid estimate has two parts: the outer state of the output (time
went backwards, bad IMU sample, not initialised, converging, ...) and, inside it, why the frame
gave no measurement (the frame's own reason, a timeout, IHRCF's and ATDA's reasons, every block
gated out). Array implementations of the filter (the JAX backend, :mod:`ihrcf_env.fast`) return
the two codes and the numbers they need; :data:`OUTER` and :data:`INNER` are the templates that
write the text exactly as :class:`~ihrcf_env.core.estimators.fused.FusedEstimator` does (IHRCF's
and ATDA's own codes: :mod:`ihrcf_env.core.estimators.reasons`).
"""

from __future__ import annotations

# outer codes
OK = 0
TIME_BACKWARDS = 1
IMU_NONFINITE = 2
IMU_ZERO = 3
NUMERICAL = 4
ARRIVAL_NONFINITE = 5
ARRIVAL_ZERO = 6
NOT_INITIALISED = 7
POSITION_NOT_INITIALISED = 8
CONVERGING_UPDATES = 9
CONVERGING_POSITION = 10
CONVERGING_ANGLE = 11

_IMU_NONFINITE = "non-finite IMU sample: frame ignored"
_IMU_ZERO = "zero IMU quaternion: frame ignored"

#: Templates of the outer codes (``a``, ``b`` the code's two numbers; ``inner`` the inner reason).
OUTER: tuple[str, ...] = (
    "",
    "time went backwards ({a:.6g} s < {b:.6g} s): frame ignored",
    _IMU_NONFINITE,
    _IMU_ZERO,
    "numerical failure: filter reset",
    f"arrival {_IMU_NONFINITE}",
    f"arrival {_IMU_ZERO}",
    "not initialised: {inner}",
    "position not initialised: {inner}",
    "converging: {a:.0f}/{b:.0f} updates",
    "converging: position sigma {a:.3g} m > {b:.3g} m",
    "converging: angle sigma {a:.3g} deg > {b:.3g} deg",
)

# inner codes
NONE = 0
CORNERS = 1
TAG_LOST = 2
NO_ATT = 3
NO_POS = 4
BOTH_FAILED = 5
IHRCF_FAILED = 6
ALL_REJECTED = 7
#: ATDA code of a filter without ATDA (no K, or neither ATDA block used).
ATDA_NOT_USED = -1

#: Templates of the inner codes (``t`` the timeout's duration; ``timeout`` the parameter).
INNER: tuple[str, ...] = (
    "",
    "{corners}",
    "tag lost for {t:.3g} s > {timeout:.3g} s",
    "no att measurement for {t:.3g} s > {timeout:.3g} s",
    "no pos measurement for {t:.3g} s > {timeout:.3g} s",
    "IHRCF: {ihrcf}; ATDA: {atda}",
    "IHRCF: {ihrcf}",
    "every measurement rejected by the gate",
)

__all__ = [
    "ALL_REJECTED",
    "ARRIVAL_NONFINITE",
    "ARRIVAL_ZERO",
    "ATDA_NOT_USED",
    "BOTH_FAILED",
    "CONVERGING_ANGLE",
    "CONVERGING_POSITION",
    "CONVERGING_UPDATES",
    "CORNERS",
    "IHRCF_FAILED",
    "IMU_NONFINITE",
    "IMU_ZERO",
    "INNER",
    "NONE",
    "NOT_INITIALISED",
    "NO_ATT",
    "NO_POS",
    "NUMERICAL",
    "OK",
    "OUTER",
    "POSITION_NOT_INITIALISED",
    "TAG_LOST",
    "TIME_BACKWARDS",
]
