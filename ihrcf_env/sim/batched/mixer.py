"""The PX4-style saturating mixer of :meth:`~ihrcf_env.sim.drone.Quadrotor.wrench_to_speeds`,
batched over N drones: collective thrust (N) and body torque (N m) -> rotor speeds (rad/s).

Where every motor thrust fits in ``[0, max_thrust]`` the wrench is realised exactly. Otherwise
roll/pitch and thrust are fitted first (their spread scaled down to the motor range, then the
thrust shifted into it), then as much of the yaw torque as every motor's remaining margin allows.
Each row is computed with the scalar code's operations in its order, so rows equal the scalar
mixer's output bit for bit and do not depend on the other rows.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ihrcf_env.config.vehicle import QuadParams

Array = NDArray[np.float64]


class BatchedMixer:
    """Wrench -> rotor speeds for the quadrotor ``params`` (rows of the inverse mixer matrix)."""

    def __init__(self, params: QuadParams) -> None:
        inv = np.linalg.inv(params.mixer)  # as Quadrotor does, so the coefficients are the same
        self.rows = [tuple(float(v) for v in r) for r in inv.tolist()]
        self.fmax = float(params.max_thrust)
        self.kf = float(params.kf)

    def thrusts(self, thrust: Array, tx: Array, ty: Array, tz: Array | None) -> Array:
        """Per-motor thrusts (N, 4) of the wrench without limits (``tz`` None: no yaw torque)."""
        out = np.empty((np.shape(thrust)[0], 4))
        for i, r in enumerate(self.rows):
            f = r[0] * thrust + r[1] * tx + r[2] * ty
            out[:, i] = f if tz is None else f + r[3] * tz
        return out

    def speeds(self, thrust: Array, tx: Array, ty: Array, tz: Array) -> Array:
        """Rotor speeds (N, 4) rad/s for collective thrusts ``thrust`` (N,) N and body torques
        ``tx, ty, tz`` (N,) N m, within the motor limits."""
        fmax = self.fmax
        f = self.thrusts(thrust, tx, ty, tz)
        sat = (f.min(axis=1) < 0.0) | (f.max(axis=1) > fmax)
        if sat.any():
            idx = np.flatnonzero(sat)
            f[idx] = self._saturated(thrust[idx], tx[idx], ty[idx], tz[idx])
        return np.sqrt(np.minimum(np.maximum(f, 0.0), fmax) / self.kf)

    def _saturated(self, thrust: Array, tx: Array, ty: Array, tz: Array) -> Array:
        """Motor thrusts (k, 4) of the rows that do not fit: roll/pitch and thrust first, then
        the largest fraction of the yaw torque every motor's margin allows."""
        fmax = self.fmax
        f = self.thrusts(thrust, tx, ty, None)
        spread = f.max(axis=1) - f.min(axis=1)
        big = spread > fmax
        f = np.where(big[:, None], f * fmax / np.where(big, spread, 1.0)[:, None], f)
        lo = f.min(axis=1)
        f = np.where((lo < 0.0)[:, None], f - lo[:, None], f)
        hi = f.max(axis=1)
        f = np.where((hi > fmax)[:, None], f - (hi - fmax)[:, None], f)
        yaw = np.empty_like(f)
        for i, r in enumerate(self.rows):
            yaw[:, i] = r[3] * tz
        scale = np.ones(f.shape[0])
        with np.errstate(divide="ignore", invalid="ignore"):
            up = (fmax - f) / yaw
            down = f / -yaw
        for i in range(4):
            yi = yaw[:, i]
            cand = np.where(yi > 0.0, up[:, i], np.where(yi < 0.0, down[:, i], np.inf))
            scale = np.where(cand < scale, cand, scale)  # min(scale, cand) keeping scale on ties
        scale = np.where(scale < 0.0, 0.0, scale)
        return f + scale[:, None] * yaw


__all__ = [
    "Array",
    "BatchedMixer",
]
