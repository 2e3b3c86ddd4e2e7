"""Quadrotor dynamics (motor model, forces) and its flight controllers.

Motors (X configuration, body frame FLU): motor i at ``(±l/√2, ±l/√2, 0)`` in the order
front-left, front-right, rear-right, rear-left; spin directions (+1 = counter-clockwise seen from
above) ``(+1, -1, +1, -1)``; a counter-clockwise rotor pushes the body with a clockwise (-z) torque.
Thrust ``kf w^2`` along body +z, reaction torque ``-dir * km w^2`` about body z, rotor speeds
``w`` follow the commanded speeds through a first-order lag ``motor_tau``.

The controllers run at the physics rate (a flight controller's inner loop) on the state they are
given: :class:`VelocityController` closes its position and velocity loops on the ``pos`` and
``vel`` passed to :meth:`VelocityController.compute` (the world passes the true state, or the
autopilot's navigation estimate with ``autopilot_feedback="estimated"``, see
:mod:`ihrcf_env.sim.navigation`) and its attitude loop on ``quat`` and ``omega`` (always the true
attitude and body rates).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.vehicle import QuadParams, VelocityGains
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.assets import asset_path


class Quadrotor:
    """The quadrotor body in one PyBullet client, with its motor state."""

    def __init__(self, client: int, params: QuadParams) -> None:
        self.client = client
        self.params = params
        self.body = p.loadURDF(
            str(asset_path("quadrotor.urdf")),
            flags=p.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=client,
        )
        p.changeDynamics(
            self.body, -1, linearDamping=0.0, angularDamping=0.0, lateralFriction=1.0, physicsClientId=client
        )
        self._mixer_inv = np.linalg.inv(params.mixer)
        self._mixer_rows = [tuple(r) for r in self._mixer_inv.tolist()]
        self._fmax = params.max_thrust
        self.rotor_speed: list[float] = [0.0] * 4  # rad/s
        self._kf = params.kf
        self._km = params.km
        self._xy_list = params.motor_xy.tolist()
        self._spin_list = params.spin.tolist()
        self._lag_dt = math.nan  # apply(): the rotor lag factor of the last dt
        self._lag = 1.0

    def reset(self, position: NDArray[np.float64], yaw: float, hover: bool = True) -> None:
        """Place the drone level at ``position`` (world, m) with heading ``yaw`` (rad), at rest;
        rotors spinning at hover speed when ``hover``."""
        q = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        p.resetBasePositionAndOrientation(
            self.body, list(map(float, position)), q, physicsClientId=self.client
        )
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)
        w_hover = math.sqrt(self.params.mass * GRAVITY / 4 / self.params.kf)
        self.rotor_speed = [w_hover if hover else 0.0] * 4

    def state(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """World position, quaternion (x, y, z, w), linear velocity, angular velocity."""
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        v, w = p.getBaseVelocity(self.body, physicsClientId=self.client)
        return pos, quat, v, w

    def thrusts_to_speeds(self, thrusts: Sequence[float]) -> list[float]:
        """Rotor speeds (rad/s) for per-motor thrusts (N), clipped to the motor limits."""
        fmax, kf = self._fmax, self._kf
        return [math.sqrt(min(max(float(f), 0.0), fmax) / kf) for f in thrusts]

    def wrench_to_speeds(self, thrust: float, torque: Sequence[float]) -> list[float]:
        """Rotor speeds realising a collective thrust (N) and body torque (N m) as well as the limits allow.

        When saturated, roll/pitch and thrust are fitted first (roll/pitch authority scaled down and
        the thrust shifted to fit the motor range), then as much of the yaw torque as the remaining
        margin of every motor allows (a PX4-style mixer: yaw is scaled down, not dropped, so a yaw
        command under saturation still turns the drone, slower). Scalar maths (physics rate).
        """
        tx, ty, tz = torque
        M = self._mixer_rows
        f = [r[0] * thrust + r[1] * tx + r[2] * ty + r[3] * tz for r in M]
        fmax = self._fmax
        if min(f) < 0.0 or max(f) > fmax:
            f = [r[0] * thrust + r[1] * tx + r[2] * ty for r in M]
            spread = max(f) - min(f)
            if spread > fmax:
                f = [fi * fmax / spread for fi in f]
            lo = min(f)
            if lo < 0.0:
                f = [fi - lo for fi in f]
            hi = max(f)
            if hi > fmax:
                f = [fi - (hi - fmax) for fi in f]
            yaw = [r[3] * tz for r in M]
            scale = 1.0
            for fi, yi in zip(f, yaw, strict=True):
                if yi > 0.0:
                    scale = min(scale, (fmax - fi) / yi)
                elif yi < 0.0:
                    scale = min(scale, fi / -yi)
            scale = max(scale, 0.0)
            f = [fi + scale * yi for fi, yi in zip(f, yaw, strict=True)]
        kf = self._kf
        return [math.sqrt(min(max(fi, 0.0), fmax) / kf) for fi in f]

    def apply(
        self,
        speed_cmd: Sequence[float],
        dt: float,
        pos: tuple[float, ...],
        quat: tuple[float, ...],
        vel: tuple[float, ...],
        thrust_scale: Sequence[float] | None = None,
    ) -> None:
        """Advance the rotor lag by ``dt`` and apply this physics step's rotor forces and drag
        (scalar maths: this runs at the physics rate).

        ``thrust_scale``: per-rotor thrust factors at the same rotor speed (e.g. the ground effect
        of :class:`~ihrcf_env.sim.ground_effect.GroundEffect`); ``None`` (default) is 1 for all. The
        rotors' reaction (yaw) torques are not scaled."""
        if dt != self._lag_dt:
            tau = self.params.motor_tau
            self._lag_dt, self._lag = dt, (min(1.0, dt / tau) if tau > 0 else 1.0)
        a = self._lag
        w0, w1, w2, w3 = self.rotor_speed
        c0, c1, c2, c3 = speed_cmd
        w0, w1, w2, w3 = w0 + a * (c0 - w0), w1 + a * (c1 - w1), w2 + a * (c2 - w2), w3 + a * (c3 - w3)
        self.rotor_speed = [w0, w1, w2, w3]
        kf, km = self._kf, self._km
        f0, f1, f2, f3 = kf * w0 * w0, kf * w1 * w1, kf * w2 * w2, kf * w3 * w3
        (x0, y0), (x1, y1), (x2, y2), (x3, y3) = self._xy_list
        s0, s1, s2, s3 = self._spin_list
        tz = -(km / kf) * (s0 * f0 + s1 * f1 + s2 * f2 + s3 * f3)
        if thrust_scale is not None:
            k0, k1, k2, k3 = thrust_scale
            f0, f1, f2, f3 = f0 * k0, f1 * k1, f2 * k2, f3 * k3
        thrust = f0 + f1 + f2 + f3
        tx = f0 * y0 + f1 * y1 + f2 * y2 + f3 * y3
        ty = -(f0 * x0 + f1 * x1 + f2 * x2 + f3 * x3)
        R = p.getMatrixFromQuaternion(quat)
        drag = self.params.drag
        # body z axis and torque in world coordinates
        force = (
            R[2] * thrust - drag * vel[0],
            R[5] * thrust - drag * vel[1],
            R[8] * thrust - drag * vel[2],
        )
        torque = (
            R[0] * tx + R[1] * ty + R[2] * tz,
            R[3] * tx + R[4] * ty + R[5] * tz,
            R[6] * tx + R[7] * ty + R[8] * tz,
        )
        p.applyExternalForce(self.body, -1, force, pos, p.WORLD_FRAME, physicsClientId=self.client)
        p.applyExternalTorque(self.body, -1, torque, p.WORLD_FRAME, physicsClientId=self.client)


#: Integral state clamp (m s) of the classic loop (``VelocityGains.wind_hold=False``).
CLASSIC_I_CLAMP = 2.0


class VelocityController:
    """Velocity set-points (heading frame) -> rotor speeds, at the physics rate.

    ``vx, vy`` are horizontal velocities in the heading frame (x forward along the current yaw,
    y left), ``vz`` is the world vertical velocity, ``yaw_rate`` about world z. A position
    set-point integrates the commanded velocity, so a zero command holds position (as an
    autopilot's position-hold mode does); the error to it is limited to ``leash``. The position
    held is that of the ``pos`` given to :meth:`compute`: with a drifting navigation estimate the
    drone drifts with it.

    Horizontally the commanded acceleration is ``kp e + kd (v_c - v) + ki I - d_hat``:

    * ``I``, the integral of the position error, is limited so that ``ki |I| <= i_limit`` and is
      frozen while the tilt limit clips the command and the error would push further into it
      (conditional integration: no wind-up while saturated);
    * ``d_hat`` (:attr:`disturbance`, m/s^2, world x/y) is a disturbance observer's estimate of the
      unmodelled horizontal acceleration (wind, drag, a side load): the acceleration measured by
      differencing the velocity feedback minus the one the autopilot commanded (its own collective
      thrust, through a model of the motor lag, along the measured body z axis), low-pass filtered
      with time constant ``dob_tau``, magnitude at most ``i_limit``. It uses only what the autopilot
      sees (its velocity feedback, its attitude and its own commands), never the wind itself.
    """

    def __init__(self, quad: Quadrotor, gains: VelocityGains | None = None) -> None:
        self.quad = quad
        self.gains = gains if gains is not None else VelocityGains()
        tau = quad.params.motor_tau
        self._lag_dt = math.nan  # compute(): the motor lag factor of the last dt
        self._lag = 1.0
        self._motor_tau = tau
        self.reset(np.zeros(3), 0.0)

    def reset(self, position: NDArray[np.float64], yaw: float) -> None:
        """Hold ``position`` (world, m) and heading ``yaw`` (rad); integrals and the disturbance
        estimate start from zero."""
        self.p_ref = [float(x) for x in position]
        self.yaw_ref = float(yaw)
        self.integral = [0.0, 0.0, 0.0]
        #: the disturbance observer's estimate (m/s^2, world x, y)
        self.disturbance = [0.0, 0.0]
        self._v_prev: tuple[float, float] | None = None
        self._thrust_model = self.quad.params.mass * GRAVITY  # N, collective thrust through the lag model
        self._a_model = (0.0, 0.0)  # m/s^2, horizontal acceleration commanded at the last step
        self._saturated = False  # the tilt limit clipped the last command
        self._f_cmd = (0.0, 0.0)  # m/s^2, the last horizontal acceleration command (after the clip)

    def trim(self, acceleration: NDArray[np.float64]) -> None:
        """Start as if the loop had converged on a constant disturbance ``acceleration`` (m/s^2,
        world; force over mass): the wind-holding loop's observer estimate (at most ``i_limit``),
        or the classic loop's horizontal integral (within its clamp); the thrust model at the
        thrust that balances it."""
        g, m = self.gains, self.quad.params.mass
        ax, ay, az = (float(v) for v in acceleration[:3])
        if g.wind_hold and g.dob_tau > 0.0:
            n = math.hypot(ax, ay)
            k = min(1.0, g.i_limit / n) if n > 0 else 1.0
            self.disturbance = [ax * k, ay * k]
            self._v_prev = (0.0, 0.0)
        elif g.ki_pos > 0.0 and g.wind_hold:
            i0, i1 = -ax / g.ki_pos, -ay / g.ki_pos
            cap, n = g.i_limit / g.ki_pos, math.hypot(i0, i1)
            k = min(1.0, cap / n) if n > 0 else 1.0
            self.integral[0], self.integral[1] = i0 * k, i1 * k
        elif g.ki_pos > 0.0:
            c = CLASSIC_I_CLAMP
            self.integral[0] = min(c, max(-c, -ax / g.ki_pos))
            self.integral[1] = min(c, max(-c, -ay / g.ki_pos))
        thrust = m * math.sqrt(ax * ax + ay * ay + (GRAVITY - az) ** 2)
        self._thrust_model = thrust
        self._a_model = (-ax, -ay)

    def compute(
        self,
        setpoint: tuple[float, float, float, float],
        dt: float,
        pos: tuple[float, ...],
        quat: tuple[float, ...],
        vel: tuple[float, ...],
        omega: tuple[float, ...],
    ) -> list[float]:
        """Rotor speed commands (rad/s) for ``setpoint = (vx, vy, vz, yaw_rate)`` (m/s, rad/s).

        Written with scalar maths: it runs at the physics rate and numpy's per-call overhead on
        3-vectors would dominate the simulation's cost.
        """
        g = self.gains
        m = self.quad.params.mass
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = p.getMatrixFromQuaternion(quat)
        yaw = math.atan2(r10, r00)
        cy, sy = math.cos(yaw), math.sin(yaw)
        sp_x, sp_y, sp_z, sp_r = setpoint
        vc0, vc1, vc2 = cy * sp_x - sy * sp_y, sy * sp_x + cy * sp_y, sp_z
        pr = self.p_ref
        pr[0] += vc0 * dt
        pr[1] += vc1 * dt
        pr[2] += vc2 * dt
        e0, e1, e2 = pr[0] - pos[0], pr[1] - pos[1], pr[2] - pos[2]
        n = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        leash = g.leash
        if n > leash:
            k = leash / n
            e0, e1, e2 = e0 * k, e1 * k, e2 * k
            pr[0], pr[1], pr[2] = pos[0] + e0, pos[1] + e1, pos[2] + e2
        integ = self.integral
        kp, kd, ki = g.kp_pos, g.kd_vel, g.ki_pos
        if not g.wind_hold:  # the classic loop (DeckHover-v0, DeckLanding-v1), unchanged
            i0 = integ[0] = min(CLASSIC_I_CLAMP, max(-CLASSIC_I_CLAMP, integ[0] + e0 * dt))
            i1 = integ[1] = min(CLASSIC_I_CLAMP, max(-CLASSIC_I_CLAMP, integ[1] + e1 * dt))
            i2 = integ[2] = min(CLASSIC_I_CLAMP, max(-CLASSIC_I_CLAMP, integ[2] + e2 * dt))
            fx = kp * e0 + kd * (vc0 - vel[0]) + ki * i0
            fy = kp * e1 + kd * (vc1 - vel[1]) + ki * i1
        else:
            lim_i = g.i_limit
            # horizontal integral: conditional integration (frozen while the tilt limit clips the
            # command and the error points further into the clipped direction), norm-limited
            if ki > 0.0:
                if not self._saturated or e0 * self._f_cmd[0] + e1 * self._f_cmd[1] <= 0.0:
                    i0, i1 = integ[0] + e0 * dt, integ[1] + e1 * dt
                    cap = lim_i / ki
                    ni = math.hypot(i0, i1)
                    if ni > cap:
                        i0, i1 = i0 * cap / ni, i1 * cap / ni
                    integ[0], integ[1] = i0, i1
            else:
                integ[0] = integ[1] = 0.0
            i0, i1 = integ[0], integ[1]
            if g.ki_z > 0.0:
                cap_z = g.i_limit_z / g.ki_z
                i2 = integ[2] = min(cap_z, max(-cap_z, integ[2] + e2 * dt))
            else:
                i2 = integ[2] = 0.0
            # disturbance observer: measured minus commanded horizontal acceleration, low-passed
            d0, d1 = self.disturbance
            if g.dob_tau > 0.0:
                vp = self._v_prev
                if vp is not None:
                    k = dt / (g.dob_tau + dt)
                    d0 += k * ((vel[0] - vp[0]) / dt - self._a_model[0] - d0)
                    d1 += k * ((vel[1] - vp[1]) / dt - self._a_model[1] - d1)
                    nd = math.hypot(d0, d1)
                    if nd > lim_i:
                        d0, d1 = d0 * lim_i / nd, d1 * lim_i / nd
                    self.disturbance = [d0, d1]
                self._v_prev = (vel[0], vel[1])
            fx = kp * e0 + kd * (vc0 - vel[0]) + ki * i0 - d0
            fy = kp * e1 + kd * (vc1 - vel[1]) + ki * i1 - d1
        acc_z = g.kp_z * e2 + g.kd_z * (vc2 - vel[2]) + g.ki_z * i2
        # thrust vector with tilt limit
        fz = max(acc_z + GRAVITY, 0.2 * GRAVITY)
        lim = fz * math.tan(g.max_tilt)
        nxy = math.hypot(fx, fy)
        self._saturated = nxy > lim and g.wind_hold
        if nxy > lim:
            fx, fy = fx * lim / nxy, fy * lim / nxy
        self._f_cmd = (fx, fy)
        F0, F1, F2 = m * fx, m * fy, m * fz
        self.yaw_ref = math.remainder(self.yaw_ref + sp_r * dt, 2 * math.pi)
        nF = math.sqrt(F0 * F0 + F1 * F1 + F2 * F2)
        z0, z1, z2 = F0 / nF, F1 / nF, F2 / nF  # desired body z
        xc0, xc1 = math.cos(self.yaw_ref), math.sin(self.yaw_ref)
        y0, y1, y2 = -z2 * xc1, z2 * xc0, z0 * xc1 - z1 * xc0
        ny = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
        y0, y1, y2 = y0 / ny, y1 / ny, y2 / ny  # desired body y
        x0, x1, x2 = y1 * z2 - y2 * z1, y2 * z0 - y0 * z2, y0 * z1 - y1 * z0  # desired body x
        thrust = F0 * r02 + F1 * r12 + F2 * r22

        # Geometric SO(3) attitude control: e_R = vee(Rd^T R - R^T Rd) / 2, with M = Rd^T R,
        # M[i][j] = (row i of Rd^T) . (column j of R); only the off-diagonal terms are needed.
        # Columns of R (body axes in world): c0 = (r00, r10, r20), c1 = (r01, r11, r21), c2 = (r02, r12, r22).
        e_R0 = 0.5 * ((z0 * r01 + z1 * r11 + z2 * r21) - (y0 * r02 + y1 * r12 + y2 * r22))
        e_R1 = 0.5 * ((x0 * r02 + x1 * r12 + x2 * r22) - (z0 * r00 + z1 * r10 + z2 * r20))
        e_R2 = 0.5 * ((y0 * r00 + y1 * r10 + y2 * r20) - (x0 * r01 + x1 * r11 + x2 * r21))
        w0, w1, w2 = omega
        wb0 = r00 * w0 + r10 * w1 + r20 * w2  # body rates
        wb1 = r01 * w0 + r11 * w1 + r21 * w2
        wb2 = r02 * w0 + r12 * w1 + r22 * w2
        J0, J1, J2 = self.quad.params.inertia
        Jw0, Jw1, Jw2 = J0 * wb0, J1 * wb1, J2 * wb2
        ka0, ka1, ka2 = g.k_att
        kr0, kr1, kr2 = g.k_rate
        # the feed-forward sp_r * (r20, r21, r22) is the world yaw rate in body axes
        torque = (
            -ka0 * e_R0 - kr0 * (wb0 - sp_r * r20) + (wb1 * Jw2 - wb2 * Jw1),
            -ka1 * e_R1 - kr1 * (wb1 - sp_r * r21) + (wb2 * Jw0 - wb0 * Jw2),
            -ka2 * e_R2 - kr2 * (wb2 - sp_r * r22) + (wb0 * Jw1 - wb1 * Jw0),
        )
        speeds = self.quad.wrench_to_speeds(thrust, torque)
        if g.wind_hold and g.dob_tau > 0.0:
            # the horizontal acceleration this command gives: the collective thrust of the rotor
            # speed commands through the motor lag, along the body z axis now
            if dt != self._lag_dt:
                tau = self._motor_tau
                self._lag_dt, self._lag = dt, (min(1.0, dt / tau) if tau > 0 else 1.0)
            w0, w1, w2, w3 = speeds
            t_cmd = self.quad.params.kf * (w0 * w0 + w1 * w1 + w2 * w2 + w3 * w3)
            # the lag acts on rotor speed (thrust ~ w^2): lag the square root of the thrust
            s_model = math.sqrt(self._thrust_model)
            s_model += self._lag * (math.sqrt(t_cmd) - s_model)
            self._thrust_model = s_model * s_model
            self._a_model = (self._thrust_model * r02 / m, self._thrust_model * r12 / m)
        return speeds


__all__ = [
    "CLASSIC_I_CLAMP",
    "Quadrotor",
    "VelocityController",
]
