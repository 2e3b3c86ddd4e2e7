"""The output of the batched fused filter (:class:`BatchFusedOutput`) and its reason codes.

The single filter's reason of an invalid estimate is built from two parts: the outer state of
the output (time went backwards, bad IMU sample, not initialised, converging, ...) and, inside
it, why the frame gave no measurement (the frame's own reason, a timeout, IHRCF's and ATDA's
reasons, every block gated out). :data:`OUTER` and :data:`INNER` are their templates; the codes
and the numbers they need are arrays, and :meth:`BatchFusedOutput.reason` writes the text exactly
as :class:`~ihrcf_env.core.estimators.fused.FusedEstimator` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch import result as rs
from ihrcf_env.core.estimators.base import PoseEstimate
from ihrcf_env.core.estimators.fused_params import FusedParams

F64 = NDArray[np.float64]

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


@dataclass(frozen=True, eq=False)
class BatchFusedOutput:
    """The N filters' outputs after one step (rows of envs not stepped hold their last output).

    Attributes:
        position (N, 3) m, euler (N, 3) rad, rotation (N, 3, 3) ``R_body_deck``, valid (N,),
            residual (N,) m (the 1-sigma position spread): as :class:`PoseEstimate`.
        velocity (N, 3) m/s, normal_rate (N, 3) 1/s, motion_valid (N,): ``FusedEstimator.motion()``
            (zeros where it is None).
        frame_time (N,) s: the time of the frame behind each row (NaN before the first).
        outer, outer_num (N, 2), inner, inner_num (N,), ihrcf_code, ihrcf_rms (N,), atda_code (N,),
            corners_reason: the reason's parts (module docstring).
    """

    position: F64
    euler: F64
    rotation: F64
    valid: NDArray[np.bool_]
    residual: F64
    velocity: F64
    normal_rate: F64
    motion_valid: NDArray[np.bool_]
    frame_time: F64
    outer: NDArray[np.int8]
    outer_num: F64
    inner: NDArray[np.int8]
    inner_num: F64
    ihrcf_code: NDArray[np.int8]
    ihrcf_rms: F64
    atda_code: NDArray[np.int8]
    corners_reason: tuple[str, ...]
    params: FusedParams
    max_residual: float

    def __len__(self) -> int:
        return len(self.valid)

    def ages(self, now: float | F64) -> F64:
        """Age (s) at ``now`` of the frame behind each row (NaN before the first frame)."""
        return np.asarray(now, dtype=np.float64) - self.frame_time

    def _ihrcf_reason(self, i: int) -> str:
        c = int(self.ihrcf_code[i])
        if c == rs.FIT_RESIDUAL:
            return rs.REASONS[c].format(rms=float(self.ihrcf_rms[i]), max_residual=self.max_residual)
        return rs.REASONS[c]

    def inner_reason(self, i: int) -> str:
        """Why row ``i``'s last frame gave no measurement ('' if it did)."""
        c = int(self.inner[i])
        a = int(self.atda_code[i])
        return INNER[c].format(
            corners=self.corners_reason[i],
            t=float(self.inner_num[i]),
            timeout=self.params.lost_timeout,
            ihrcf=self._ihrcf_reason(i) if c in (BOTH_FAILED, IHRCF_FAILED) else "",
            atda="ATDA not used" if a == ATDA_NOT_USED else rs.REASONS[a],
        )

    def reason(self, i: int) -> str:
        """Reason text of row ``i`` ('' when valid), as the single filter writes it."""
        c = int(self.outer[i])
        if c == OK:
            return ""
        a, b = (float(x) for x in self.outer_num[i])
        inner = self.inner_reason(i)
        if c in (NOT_INITIALISED, POSITION_NOT_INITIALISED):
            return OUTER[c].format(inner=inner or "no measurement yet")
        text = OUTER[c].format(a=a, b=b)
        if c in (CONVERGING_UPDATES, CONVERGING_POSITION, CONVERGING_ANGLE) and inner:
            text += f" ({inner})"
        return text

    def reasons(self) -> list[str]:
        return [self.reason(i) for i in range(len(self))]

    def estimate(self, i: int) -> PoseEstimate:
        """Row ``i`` as a :class:`PoseEstimate`."""
        if not self.valid[i]:
            return PoseEstimate.invalid(self.reason(i))
        return PoseEstimate(self.position[i], self.euler[i], self.rotation[i], True, float(self.residual[i]))


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
    "BatchFusedOutput",
]
