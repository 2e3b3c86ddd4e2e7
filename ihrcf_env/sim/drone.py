"""Quadrotor dynamics (motor model, forces) and its flight controllers.

Motors (X configuration, body frame FLU): motor i at ``(±l/√2, ±l/√2, 0)`` in the order
front-left, front-right, rear-right, rear-left; spin directions (+1 = counter-clockwise seen from
above) ``(+1, -1, +1, -1)``; a counter-clockwise rotor pushes the body with a clockwise (-z) torque.
Thrust ``kf w^2`` along body +z, reaction torque ``-dir * km w^2`` about body z, rotor speeds
``w`` follow the commanded speeds through a first-order lag ``motor_tau``.

The controllers run at the physics rate (a flight controller's inner loop) on the true state,
like a well-estimated autopilot; only the landing task's *relative* sensing (camera, ToF) is the
subject of this simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.sim.assets import asset_path

GRAVITY = 9.81


@dataclass(frozen=True)
class QuadParams:
    """Physical constants of the quadrotor (SI units). Mass/inertia must match the URDF."""

    mass: float = 1.2
    inertia: tuple[float, float, float] = (0.0123, 0.0123, 0.0224)
    arm: float = 0.15
    kf: float = 5.886e-6  # N / (rad/s)^2
    km: float = 9.4e-8  # N m / (rad/s)^2  (km / kf = 0.016 m)
    max_rotor_speed: float = 1000.0  # rad/s -> 4 kf w_max^2 = 23.5 N, thrust-to-weight 2.0
    motor_tau: float = 0.015  # s, rotor speed time constant
    drag: float = 0.08  # N s/m, linear aerodynamic drag

    @property
    def max_thrust(self) -> float:
        """Per motor (N)."""
        return self.kf * self.max_rotor_speed**2

    @property
    def thrust_to_weight(self) -> float:
        return 4 * self.max_thrust / (self.mass * GRAVITY)

    @property
    def motor_xy(self) -> NDArray[np.float64]:
        d = self.arm / math.sqrt(2)
        return np.array([[d, d], [d, -d], [-d, -d], [-d, d]])

    @property
    def spin(self) -> NDArray[np.float64]:
        """+1 for rotors turning counter-clockwise seen from above."""
        return np.array([1.0, -1.0, 1.0, -1.0])

    @property
    def mixer(self) -> NDArray[np.float64]:
        """(4, 4) map from motor thrusts (N) to (collective thrust N, torque x, y, z N m)."""
        xy = self.motor_xy
        ratio = self.km / self.kf
        return np.vstack([np.ones(4), xy[:, 1], -xy[:, 0], -self.spin * ratio])


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
        self.rotor_speed = np.zeros(4)
        self._kf = params.kf
        self._km = params.km
        self._xy = params.motor_xy
        self._spin = params.spin

    def reset(self, position: NDArray[np.float64], yaw: float, hover: bool = True) -> None:
        """Place the drone level at ``position`` (world, m) with heading ``yaw`` (rad), at rest;
        rotors spinning at hover speed when ``hover``."""
        q = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        p.resetBasePositionAndOrientation(
            self.body, list(map(float, position)), q, physicsClientId=self.client
        )
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)
        w_hover = math.sqrt(self.params.mass * GRAVITY / 4 / self.params.kf)
        self.rotor_speed = np.full(4, w_hover if hover else 0.0)

    def state(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """World position, quaternion (x, y, z, w), linear velocity, angular velocity."""
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        v, w = p.getBaseVelocity(self.body, physicsClientId=self.client)
        return pos, quat, v, w

    def thrusts_to_speeds(self, thrusts: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor speeds (rad/s) for per-motor thrusts (N), clipped to the motor limits."""
        f = np.clip(thrusts, 0.0, self.params.max_thrust)
        return np.sqrt(f / self._kf)

    def wrench_to_speeds(self, thrust: float, torque: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rotor speeds realising a collective thrust (N) and body torque (N m) as well as the limits allow.

        When saturated, roll/pitch are kept and yaw is sacrificed first, then the thrust is shifted.
        """
        f = self._mixer_inv @ np.array([thrust, torque[0], torque[1], torque[2]])
        fmax = self.params.max_thrust
        if f.min() < 0.0 or f.max() > fmax:
            f = self._mixer_inv @ np.array([thrust, torque[0], torque[1], 0.0])
            if f.max() - f.min() > fmax:
                f = f * (fmax / (f.max() - f.min()))
            if f.min() < 0.0:
                f = f - f.min()
            if f.max() > fmax:
                f = f - (f.max() - fmax)
        return self.thrusts_to_speeds(f)

    def apply(
        self, speed_cmd: NDArray[np.float64], dt: float, quat: tuple[float, ...], vel: tuple[float, ...]
    ) -> None:
        """Advance the rotor lag by ``dt`` and apply this physics step's rotor forces and drag."""
        a = min(1.0, dt / self.params.motor_tau) if self.params.motor_tau > 0 else 1.0
        self.rotor_speed += a * (speed_cmd - self.rotor_speed)
        w2 = self.rotor_speed * self.rotor_speed
        f = self._kf * w2
        thrust = float(f.sum())
        tx = float(f @ self._xy[:, 1])
        ty = float(-(f @ self._xy[:, 0]))
        tz = float(-(self._km * w2) @ self._spin)
        R = p.getMatrixFromQuaternion(quat)
        # body z axis and torque in world coordinates
        force = (
            R[2] * thrust - self.params.drag * vel[0],
            R[5] * thrust - self.params.drag * vel[1],
            R[8] * thrust - self.params.drag * vel[2],
        )
        torque = (
            R[0] * tx + R[1] * ty + R[2] * tz,
            R[3] * tx + R[4] * ty + R[5] * tz,
            R[6] * tx + R[7] * ty + R[8] * tz,
        )
        pos, _ = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        p.applyExternalForce(self.body, -1, force, pos, p.WORLD_FRAME, physicsClientId=self.client)
        p.applyExternalTorque(self.body, -1, torque, p.WORLD_FRAME, physicsClientId=self.client)


@dataclass(frozen=True)
class VelocityGains:
    """Cascaded controller gains: position/velocity (outer) and attitude/rate (inner)."""

    kp_pos: float = 3.0  # 1/s^2
    kd_vel: float = 3.5  # 1/s
    ki_pos: float = 0.6  # 1/s^3
    kp_z: float = 4.0
    kd_z: float = 4.0
    ki_z: float = 1.0
    max_tilt: float = math.radians(30.0)
    k_att: tuple[float, float, float] = (4.5, 4.5, 1.6)  # N m / rad
    k_rate: tuple[float, float, float] = (0.38, 0.38, 0.3)  # N m s / rad
    leash: float = 0.5  # m, max position error before the set-point is dragged along
    i_limit: float = 2.0  # m/s^2, integrator clamp


class VelocityController:
    """Velocity set-points (heading frame) -> rotor speeds, at the physics rate.

    ``vx, vy`` are horizontal velocities in the heading frame (x forward along the current yaw,
    y left), ``vz`` is the world vertical velocity, ``yaw_rate`` about world z. A position
    set-point integrates the commanded velocity, so a zero command holds position (as an
    autopilot's position-hold mode does); the error to it is limited to ``leash``.
    """

    def __init__(self, quad: Quadrotor, gains: VelocityGains | None = None) -> None:
        self.quad = quad
        self.gains = gains if gains is not None else VelocityGains()
        self.reset(np.zeros(3), 0.0)

    def reset(self, position: NDArray[np.float64], yaw: float) -> None:
        self.p_ref = np.array(position, dtype=np.float64)
        self.yaw_ref = float(yaw)
        self.integral = np.zeros(3)

    def compute(
        self,
        setpoint: NDArray[np.float64],
        dt: float,
        pos: tuple[float, ...],
        quat: tuple[float, ...],
        vel: tuple[float, ...],
        omega: tuple[float, ...],
    ) -> NDArray[np.float64]:
        """Rotor speed commands (rad/s) for ``setpoint = (vx, vy, vz, yaw_rate)`` (m/s, rad/s)."""
        g = self.gains
        m = self.quad.params.mass
        R = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        yaw = math.atan2(R[1, 0], R[0, 0])
        cy, sy = math.cos(yaw), math.sin(yaw)
        v_cmd = np.array(
            [cy * setpoint[0] - sy * setpoint[1], sy * setpoint[0] + cy * setpoint[1], setpoint[2]]
        )
        self.p_ref += v_cmd * dt
        pos_a = np.asarray(pos)
        err = self.p_ref - pos_a
        n = float(np.linalg.norm(err))
        if n > g.leash:
            err *= g.leash / n
            self.p_ref = pos_a + err
        self.integral = np.clip(self.integral + err * dt, -g.i_limit, g.i_limit)
        kp = np.array([g.kp_pos, g.kp_pos, g.kp_z])
        kd = np.array([g.kd_vel, g.kd_vel, g.kd_z])
        ki = np.array([g.ki_pos, g.ki_pos, g.ki_z])
        acc = kp * err + kd * (v_cmd - np.asarray(vel)) + ki * self.integral
        # thrust vector with tilt limit
        fz = max(acc[2] + GRAVITY, 0.2 * GRAVITY)
        fxy = acc[:2]
        lim = fz * math.tan(g.max_tilt)
        nxy = float(np.linalg.norm(fxy))
        if nxy > lim:
            fxy = fxy * (lim / nxy)
        F = m * np.array([fxy[0], fxy[1], fz])
        self.yaw_ref = math.remainder(self.yaw_ref + setpoint[3] * dt, 2 * math.pi)
        z_d = F / np.linalg.norm(F)
        x_c = np.array([math.cos(self.yaw_ref), math.sin(self.yaw_ref), 0.0])
        y_d = np.cross(z_d, x_c)
        y_d /= np.linalg.norm(y_d)
        x_d = np.cross(y_d, z_d)
        R_d = np.column_stack([x_d, y_d, z_d])
        thrust = float(F @ R[:, 2])
        return self._attitude(R, R_d, np.array([0.0, 0.0, setpoint[3]]), thrust, omega)

    def _attitude(
        self,
        R: NDArray[np.float64],
        R_d: NDArray[np.float64],
        rate_ff_world: NDArray[np.float64],
        thrust: float,
        omega: tuple[float, ...],
    ) -> NDArray[np.float64]:
        """Geometric (SO(3)) attitude controller -> rotor speeds."""
        g = self.gains
        E = R_d.T @ R - R.T @ R_d
        e_R = 0.5 * np.array([E[2, 1], E[0, 2], E[1, 0]])
        w_body = R.T @ np.asarray(omega)
        e_w = w_body - R.T @ rate_ff_world
        J = np.asarray(self.quad.params.inertia)
        torque = -np.asarray(g.k_att) * e_R - np.asarray(g.k_rate) * e_w + np.cross(w_body, J * w_body)
        return self.quad.wrench_to_speeds(thrust, torque)
