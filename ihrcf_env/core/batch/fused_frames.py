"""N :class:`~ihrcf_env.core.estimators.base.SensorFrame` s as arrays: the per-step input of the
batched fused filter (:class:`~ihrcf_env.core.batch.fused.BatchFused`).

Absent parts of a frame are masks: ``detected`` (corners or not), ``imu_present`` (IMU sample or
None), ``arrival_present`` (arrival IMU sample or None); unknown times are NaN as in the frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch.pnp import PnPCandidates
from ihrcf_env.core.batch.result import PNP_NO_SOLUTION, REASONS
from ihrcf_env.core.estimators.atda import Candidate
from ihrcf_env.core.estimators.base import TAG_NOT_FOUND, SensorFrame

F64 = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class BatchFrames:
    """N sensor frames (row i = one env's frame).

    Attributes:
        time: (N,) exposure time, s (NaN: one nominal interval after the last frame).
        detected: (N,) bool, tag corners present; corners: (N, 4, 2) px (ignored where not detected).
        corners_reason: N reasons for an undetected tag ('' where detected).
        ranges: (N, 4) m; ranges_valid: (N, 4) bool; ranges_time: (N,) s (NaN: at ``time``).
        imu_present: (N,) bool; quaternion (N, 4) x, y, z, w; angular_velocity (N, 3) rad/s;
            specific_force (N, 3) m/s^2 (body frame).
        arrival_time: (N,) s (NaN: no latency); arrival_present: (N,) bool, an arrival IMU sample
            is given in ``arrival_quaternion`` (N, 4), ``arrival_angular_velocity`` (N, 3),
            ``arrival_specific_force`` (N, 3).
    """

    time: F64
    detected: NDArray[np.bool_]
    corners: F64
    corners_reason: tuple[str, ...]
    ranges: F64
    ranges_valid: NDArray[np.bool_]
    ranges_time: F64
    imu_present: NDArray[np.bool_]
    quaternion: F64
    angular_velocity: F64
    specific_force: F64
    arrival_time: F64
    arrival_present: NDArray[np.bool_]
    arrival_quaternion: F64
    arrival_angular_velocity: F64
    arrival_specific_force: F64

    def __len__(self) -> int:
        return len(self.time)


def stack_frames(frames: Sequence[SensorFrame | None]) -> BatchFrames:
    """The :class:`BatchFrames` of N frames (None: a placeholder row for an env not stepped, e.g.
    one whose camera frame is held; give it an ``active`` mask of False)."""
    n = len(frames)
    time = np.full(n, math.nan)
    detected = np.zeros(n, dtype=bool)
    corners = np.zeros((n, 4, 2))
    reasons = [TAG_NOT_FOUND] * n
    ranges, valid = np.zeros((n, 4)), np.zeros((n, 4), dtype=bool)
    ranges_time, arrival_time = np.full(n, math.nan), np.full(n, math.nan)
    imu_p, arr_p = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    q, w, f = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))
    aq, aw, af = q.copy(), w.copy(), f.copy()
    for k, fr in enumerate(frames):
        if fr is None:
            continue
        time[k] = fr.time
        if fr.corners is not None:
            detected[k] = True
            corners[k] = fr.corners
            reasons[k] = ""
        else:
            reasons[k] = fr.corners_reason
        ranges[k], valid[k] = fr.ranges, fr.ranges_valid
        ranges_time[k], arrival_time[k] = fr.ranges_time, fr.arrival_time
        if fr.imu is not None:
            imu_p[k] = True
            q[k], w[k], f[k] = fr.imu.quaternion, fr.imu.angular_velocity, fr.imu.specific_force
        if fr.arrival_imu is not None:
            arr_p[k] = True
            s = fr.arrival_imu
            aq[k], aw[k], af[k] = s.quaternion, s.angular_velocity, s.specific_force
    return BatchFrames(
        time, detected, corners, tuple(reasons), ranges, valid, ranges_time, imu_p, q, w, f,
        arrival_time, arr_p, aq, aw, af,
    )  # fmt: skip


def stack_atda_candidates(results: Sequence[list[Candidate] | str]) -> PnPCandidates:
    """:class:`PnPCandidates` of N results of the single ATDA's
    :func:`~ihrcf_env.core.estimators.atda.atda_candidates` (a list of up to two candidates, or the
    reason there are none): the batched filter then chooses among the single ATDA's own poses."""
    n = len(results)
    rot = np.tile(np.eye(3), (n, 2, 1, 1))
    pos, err = np.zeros((n, 2, 3)), np.full((n, 2), np.inf)
    usable = np.zeros((n, 2), dtype=bool)
    code = np.zeros(n, dtype=np.int8)
    for k, res in enumerate(results):
        if isinstance(res, str):
            code[k] = REASONS.index(res) if res in REASONS else PNP_NO_SOLUTION
            continue
        for s, (e, R, p) in enumerate(res[:2]):
            err[k, s], rot[k, s], pos[k, s], usable[k, s] = e, R, p, True
    return PnPCandidates(rot, pos, err, usable, code)


__all__ = [
    "BatchFrames",
    "stack_atda_candidates",
    "stack_frames",
]
