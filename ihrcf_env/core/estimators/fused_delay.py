"""The fused estimator's delay compensation: a frame that reached the filter after its exposure is
fused at its exposure time, then the filter is predicted to the frame's arrival for the output.

The filter (:mod:`~ihrcf_env.core.estimators.fused`) runs on the frames' exposure times, each
fused with the IMU sample of its exposure; frames arrive in exposure order (a fixed pipeline
latency), so no replay is needed: :func:`predict_ahead` predicts copies of the filters over the
latency on the accelerometer, and the output is read from them in the body frame of the arrival.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators.base import ImuSample
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.estimators.imm import Imm
from ihrcf_env.core.frames import matrix_from_quat

_G_WORLD = np.array([0.0, 0.0, -GRAVITY])


def imu_sample(imu: ImuSample) -> tuple[NDArray[np.float64], NDArray[np.float64]] | str:
    """(R_wb, drone acceleration in the world (m/s^2)) of a sample, or why the frame is ignored."""
    q, f = imu.quaternion, imu.specific_force
    if not math.isfinite(float(q @ q) + float(f @ f) + float(imu.angular_velocity @ imu.angular_velocity)):
        return "non-finite IMU sample: frame ignored"  # (or absurdly large: > 1e154)
    if float(q @ q) < 1e-12:
        return "zero IMU quaternion: frame ignored"
    R_wb = matrix_from_quat(q)
    return R_wb, R_wb @ f + _G_WORLD


def predict_ahead(
    pos: Imm | None,
    att: Imm | None,
    params: FusedParams,
    dt: float,
    a_then: NDArray[np.float64] | None,
    a_now: NDArray[np.float64] | None,
) -> tuple[Imm | None, Imm | None]:
    """Copies of the position and attitude filters predicted ``dt`` s ahead (the filters are
    unchanged): the position on the drone's acceleration (world, m/s^2; ``a_now`` at the end,
    averaged with ``a_then`` at the start under ``accel_hold="trapezoid"``), with the IMU tilt
    wander's noise as in the filter's own prediction."""
    u = a_now
    if a_now is not None and params.accel_hold == "trapezoid" and a_then is not None:
        u = 0.5 * (a_now + a_then)
    pos_ahead = att_ahead = None
    if pos is not None:
        r = pos.x[0:3]
        q_value = params.imu_attitude_walk**2 * (float(r @ r) * np.eye(3) - np.outer(r, r))
        pos_ahead = pos.predicted(dt, None if u is None else -u, q_value)
    if att is not None:
        att_ahead = att.predicted(dt)
    return pos_ahead, att_ahead


__all__ = [
    "imu_sample",
    "predict_ahead",
]
