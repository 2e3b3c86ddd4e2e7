""":class:`~ihrcf_env.sim.drone.VelocityController` batched over N drones, with per-row state.

Velocity set-points (heading frame) -> rotor speeds, at the physics rate: the position set-point
integrating the command with its leash, the horizontal PID (the classic loop with its per-axis
integrator clamp, or the wind-holding loop with conditional integration, a norm-limited integral
and the disturbance observer), the vertical PID, the tilt limit, the yaw reference, the geometric
SO(3) attitude loop and the saturating mixer (:class:`~ihrcf_env.sim.batched.mixer.BatchedMixer`).
Every row follows the scalar controller's operations in their order (branches become per-row
selections), so a row equals the scalar controller's output bit for bit, whatever N.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.batched.dynamics import motor_lag
from ihrcf_env.sim.batched.floatmath import (
    atan2,
    hypot2,
    hypot_over,
    matrices_from_quaternions,
    remainder,
)
from ihrcf_env.sim.batched.mixer import BatchedMixer

if TYPE_CHECKING:
    from ihrcf_env.config.vehicle import QuadParams, VelocityGains

Array = NDArray[np.float64]

#: Integral state clamp (m s) of the classic loop: the value of
#: :data:`ihrcf_env.sim.drone.CLASSIC_I_CLAMP` (kept equal by a test; this package imports no PyBullet).
CLASSIC_I_CLAMP = 2.0
_TWO_PI = 2 * math.pi


class BatchedVelocityController:
    """N velocity controllers sharing ``params`` and ``gains`` (a
    :class:`~ihrcf_env.config.vehicle.VelocityGains`), each with its own state: ``p_ref`` (N, 3) m,
    ``yaw_ref`` (N,) rad, ``integral`` (N, 3) m s, ``disturbance`` (N, 2) m/s^2 (world x, y)."""

    def __init__(self, params: QuadParams, gains: VelocityGains, n: int) -> None:
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n must be a positive integer, got {n!r}")
        self.params = params
        self.gains = gains
        self.n = int(n)
        self.mixer = BatchedMixer(params)
        self._tan_tilt = math.tan(gains.max_tilt)
        self._lag_dt = math.nan
        self._lag = 1.0
        self.p_ref = np.zeros((self.n, 3))
        self.yaw_ref = np.zeros(self.n)
        self.integral = np.zeros((self.n, 3))
        self.disturbance = np.zeros((self.n, 2))
        self._v_prev = np.zeros((self.n, 2))
        self._has_v_prev = np.zeros(self.n, dtype=bool)
        self._thrust_model = np.zeros(self.n)
        self._a_model = np.zeros((self.n, 2))
        self._saturated = np.zeros(self.n, dtype=bool)
        self._f_cmd = np.zeros((self.n, 2))
        self.reset(np.zeros(3), 0.0)

    def _rows(self, rows: ArrayLike | None) -> NDArray[np.intp]:
        return np.arange(self.n) if rows is None else np.asarray(rows, dtype=np.intp).reshape(-1)

    def reset(self, position: ArrayLike, yaw: ArrayLike, rows: ArrayLike | None = None) -> None:
        """Hold ``position`` ((3,) or (k, 3), world m) and heading ``yaw`` (rad) on ``rows`` (all by
        default); their integrals and disturbance estimates start from zero."""
        idx = self._rows(rows)
        self.p_ref[idx] = np.broadcast_to(np.asarray(position, dtype=np.float64), (idx.size, 3))
        self.yaw_ref[idx] = np.broadcast_to(np.asarray(yaw, dtype=np.float64), (idx.size,))
        self.integral[idx] = 0.0
        self.disturbance[idx] = 0.0
        self._has_v_prev[idx] = False
        self._v_prev[idx] = 0.0
        self._thrust_model[idx] = self.params.mass * GRAVITY
        self._a_model[idx] = 0.0
        self._saturated[idx] = False
        self._f_cmd[idx] = 0.0

    def trim(self, acceleration: ArrayLike, rows: ArrayLike | None = None) -> None:
        """Start ``rows`` as if converged on a constant disturbance ``acceleration`` ((3,) or (k, 3),
        m/s^2, world), as :meth:`~ihrcf_env.sim.drone.VelocityController.trim`."""
        idx = self._rows(rows)
        acc = np.broadcast_to(np.asarray(acceleration, dtype=np.float64), (idx.size, 3))
        ax, ay, az = acc[:, 0], acc[:, 1], acc[:, 2]
        g, m = self.gains, self.params.mass
        if g.wind_hold and g.dob_tau > 0.0:
            n = hypot2(ax, ay)
            with np.errstate(divide="ignore", invalid="ignore"):
                k = np.where(n > 0, np.minimum(1.0, g.i_limit / n), 1.0)
            self.disturbance[idx] = np.stack([ax * k, ay * k], axis=1)
            self._v_prev[idx] = 0.0
            self._has_v_prev[idx] = True
        elif g.ki_pos > 0.0 and g.wind_hold:
            i0, i1 = -ax / g.ki_pos, -ay / g.ki_pos
            cap, n = g.i_limit / g.ki_pos, hypot2(i0, i1)
            with np.errstate(divide="ignore", invalid="ignore"):
                k = np.where(n > 0, np.minimum(1.0, cap / n), 1.0)
            self.integral[idx, 0], self.integral[idx, 1] = i0 * k, i1 * k
        elif g.ki_pos > 0.0:
            c = CLASSIC_I_CLAMP
            self.integral[idx, 0] = np.minimum(c, np.maximum(-c, -ax / g.ki_pos))
            self.integral[idx, 1] = np.minimum(c, np.maximum(-c, -ay / g.ki_pos))
        gz = GRAVITY - az
        self._thrust_model[idx] = m * np.sqrt(ax * ax + ay * ay + gz * gz)
        self._a_model[idx] = np.stack([-ax, -ay], axis=1)

    def compute(
        self,
        setpoint: Array,
        dt: float,
        pos: Array,
        quat: Array,
        vel: Array,
        omega: Array,
        rotation: Array | None = None,
    ) -> Array:
        """Rotor speed commands (N, 4) rad/s for ``setpoint`` (N, 4) = (vx, vy, vz, yaw_rate) (m/s,
        rad/s), on positions ``pos`` (N, 3), quaternions ``quat`` (N, 4) (x, y, z, w), velocities
        ``vel`` (N, 3) and angular velocities ``omega`` (N, 3) (world frame). ``rotation``: the
        matrices (N, 3, 3) of ``quat`` when already computed (e.g.
        :meth:`~ihrcf_env.sim.batched.dynamics.BatchedQuadrotor.reported_rotation`)."""
        g = self.gains
        m = self.params.mass
        r = matrices_from_quaternions(quat) if rotation is None else rotation
        r00, r01, r02 = r[:, 0, 0], r[:, 0, 1], r[:, 0, 2]
        r10, r11, r12 = r[:, 1, 0], r[:, 1, 1], r[:, 1, 2]
        r20, r21, r22 = r[:, 2, 0], r[:, 2, 1], r[:, 2, 2]
        yaw = atan2(r10, r00)
        cy, sy = np.cos(yaw), np.sin(yaw)
        sp_x, sp_y, sp_z, sp_r = setpoint[:, 0], setpoint[:, 1], setpoint[:, 2], setpoint[:, 3]
        vc0, vc1, vc2 = cy * sp_x - sy * sp_y, sy * sp_x + cy * sp_y, sp_z
        pr = self.p_ref
        pr[:, 0] += vc0 * dt
        pr[:, 1] += vc1 * dt
        pr[:, 2] += vc2 * dt
        e = pr - pos
        e0, e1, e2 = e[:, 0], e[:, 1], e[:, 2]
        n = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        leash = g.leash
        far = n > leash
        if far.any():
            k = leash / np.where(far, n, 1.0)
            e0, e1, e2 = (np.where(far, c * k, c) for c in (e0, e1, e2))
            pr[far] = (pos + np.stack([e0, e1, e2], axis=1))[far]
        integ = self.integral
        kp, kd, ki = g.kp_pos, g.kd_vel, g.ki_pos
        v0, v1, v2 = vel[:, 0], vel[:, 1], vel[:, 2]
        if not g.wind_hold:
            c = CLASSIC_I_CLAMP
            for j, ej in enumerate((e0, e1, e2)):
                integ[:, j] = np.minimum(c, np.maximum(-c, integ[:, j] + ej * dt))
            i0, i1, i2 = integ[:, 0], integ[:, 1], integ[:, 2]
            fx = kp * e0 + kd * (vc0 - v0) + ki * i0
            fy = kp * e1 + kd * (vc1 - v1) + ki * i1
        else:
            fx, fy, i2 = self._wind_hold(dt, e0, e1, e2, vc0, vc1, v0, v1)
        acc_z = g.kp_z * e2 + g.kd_z * (vc2 - v2) + g.ki_z * i2
        fz = np.maximum(acc_z + GRAVITY, 0.2 * GRAVITY)
        lim = fz * self._tan_tilt
        clip, nxy = hypot_over(fx, fy, lim)
        self._saturated = clip & g.wind_hold
        if clip.any():
            den = np.where(clip, nxy, 1.0)
            fx = np.where(clip, fx * lim / den, fx)
            fy = np.where(clip, fy * lim / den, fy)
        self._f_cmd[:, 0], self._f_cmd[:, 1] = fx, fy
        F0, F1, F2 = m * fx, m * fy, m * fz
        self.yaw_ref = remainder(self.yaw_ref + sp_r * dt, _TWO_PI)
        nF = np.sqrt(F0 * F0 + F1 * F1 + F2 * F2)
        z0, z1, z2 = F0 / nF, F1 / nF, F2 / nF
        xc0, xc1 = np.cos(self.yaw_ref), np.sin(self.yaw_ref)
        y0, y1, y2 = -z2 * xc1, z2 * xc0, z0 * xc1 - z1 * xc0
        ny = np.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
        y0, y1, y2 = y0 / ny, y1 / ny, y2 / ny
        x0, x1, x2 = y1 * z2 - y2 * z1, y2 * z0 - y0 * z2, y0 * z1 - y1 * z0
        thrust = F0 * r02 + F1 * r12 + F2 * r22
        # geometric SO(3) attitude loop: e_R = vee(Rd^T R - R^T Rd) / 2 (see the scalar controller)
        e_R0 = 0.5 * ((z0 * r01 + z1 * r11 + z2 * r21) - (y0 * r02 + y1 * r12 + y2 * r22))
        e_R1 = 0.5 * ((x0 * r02 + x1 * r12 + x2 * r22) - (z0 * r00 + z1 * r10 + z2 * r20))
        e_R2 = 0.5 * ((y0 * r00 + y1 * r10 + y2 * r20) - (x0 * r01 + x1 * r11 + x2 * r21))
        w0, w1, w2 = omega[:, 0], omega[:, 1], omega[:, 2]
        wb0 = r00 * w0 + r10 * w1 + r20 * w2
        wb1 = r01 * w0 + r11 * w1 + r21 * w2
        wb2 = r02 * w0 + r12 * w1 + r22 * w2
        J0, J1, J2 = self.params.inertia
        Jw0, Jw1, Jw2 = J0 * wb0, J1 * wb1, J2 * wb2
        ka0, ka1, ka2 = g.k_att
        kr0, kr1, kr2 = g.k_rate
        tx = -ka0 * e_R0 - kr0 * (wb0 - sp_r * r20) + (wb1 * Jw2 - wb2 * Jw1)
        ty = -ka1 * e_R1 - kr1 * (wb1 - sp_r * r21) + (wb2 * Jw0 - wb0 * Jw2)
        tz = -ka2 * e_R2 - kr2 * (wb2 - sp_r * r22) + (wb0 * Jw1 - wb1 * Jw0)
        speeds = self.mixer.speeds(thrust, tx, ty, tz)
        if g.wind_hold and g.dob_tau > 0.0:
            # the commanded collective thrust through the motor lag model, along body z now
            if dt != self._lag_dt:
                self._lag_dt, self._lag = dt, motor_lag(dt, self.params.motor_tau)
            s0, s1, s2, s3 = speeds[:, 0], speeds[:, 1], speeds[:, 2], speeds[:, 3]
            t_cmd = self.params.kf * (s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
            s_model = np.sqrt(self._thrust_model)
            s_model = s_model + self._lag * (np.sqrt(t_cmd) - s_model)
            self._thrust_model = s_model * s_model
            self._a_model[:, 0] = self._thrust_model * r02 / m
            self._a_model[:, 1] = self._thrust_model * r12 / m
        return speeds

    def _wind_hold(
        self,
        dt: float,
        e0: Array,
        e1: Array,
        e2: Array,
        vc0: Array,
        vc1: Array,
        v0: Array,
        v1: Array,
    ) -> tuple[Array, Array, Array]:
        """The wind-holding horizontal loop: conditional, norm-limited integral, vertical integral
        and the disturbance observer; returns the horizontal acceleration command and ``i2``."""
        g = self.gains
        integ = self.integral
        kp, kd, ki = g.kp_pos, g.kd_vel, g.ki_pos
        lim_i = g.i_limit
        if ki > 0.0:
            free = ~self._saturated | (e0 * self._f_cmd[:, 0] + e1 * self._f_cmd[:, 1] <= 0.0)
            i0, i1 = integ[:, 0] + e0 * dt, integ[:, 1] + e1 * dt
            cap = lim_i / ki
            over, ni = hypot_over(i0, i1, cap)
            den = np.where(over, ni, 1.0)
            i0 = np.where(over, i0 * cap / den, i0)
            i1 = np.where(over, i1 * cap / den, i1)
            integ[:, 0] = np.where(free, i0, integ[:, 0])
            integ[:, 1] = np.where(free, i1, integ[:, 1])
        else:
            integ[:, 0] = integ[:, 1] = 0.0
        if g.ki_z > 0.0:
            cap_z = g.i_limit_z / g.ki_z
            integ[:, 2] = np.minimum(cap_z, np.maximum(-cap_z, integ[:, 2] + e2 * dt))
        else:
            integ[:, 2] = 0.0
        d = self.disturbance
        if g.dob_tau > 0.0:
            has = self._has_v_prev
            vp = self._v_prev
            k = dt / (g.dob_tau + dt)
            d0 = d[:, 0] + k * ((v0 - vp[:, 0]) / dt - self._a_model[:, 0] - d[:, 0])
            d1 = d[:, 1] + k * ((v1 - vp[:, 1]) / dt - self._a_model[:, 1] - d[:, 1])
            over, nd = hypot_over(d0, d1, lim_i)
            den = np.where(over, nd, 1.0)
            d0 = np.where(over, d0 * lim_i / den, d0)
            d1 = np.where(over, d1 * lim_i / den, d1)
            d[:, 0] = np.where(has, d0, d[:, 0])
            d[:, 1] = np.where(has, d1, d[:, 1])
            vp[:, 0], vp[:, 1] = v0, v1
            self._has_v_prev[:] = True
        fx = kp * e0 + kd * (vc0 - v0) + ki * integ[:, 0] - d[:, 0]
        fy = kp * e1 + kd * (vc1 - v1) + ki * integ[:, 1] - d[:, 1]
        return fx, fy, integ[:, 2]


__all__ = [
    "CLASSIC_I_CLAMP",
    "Array",
    "BatchedVelocityController",
]
