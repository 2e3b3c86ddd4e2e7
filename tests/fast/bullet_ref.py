"""The PyBullet reference of the JAX flight goldens: the simulator's own drone
(:class:`~ihrcf_env.sim.drone.Quadrotor`) stepped by PyBullet's rigid-body solver in a DIRECT
client of its own (gravity and the physics tick as a world sets them, no other body), one drone
state at a time, float64. A tick is what ``World.step`` does in one physics step: the rotor
forces and drag (``Quadrotor.apply`` on the pose PyBullet reports), an external force, then
``stepSimulation``. :func:`controller_state` gives the state of the simulator's autopilot
(:class:`~ihrcf_env.sim.drone.VelocityController`) as the JAX autopilot holds it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pybullet as p

from ihrcf_env.config.vehicle import QuadParams
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.fast.autopilot import ControllerState
from ihrcf_env.sim.drone import Quadrotor, VelocityController

#: The physics tick (s) of the goldens (the worlds' default 240 Hz).
DT = 1.0 / 240.0


class BulletDrone:
    """One :class:`Quadrotor` in its own PyBullet client; :meth:`close` disconnects it."""

    def __init__(self, params: QuadParams | None = None, dt: float = DT) -> None:
        self.client = p.connect(p.DIRECT)
        p.setGravity(0, 0, -GRAVITY, physicsClientId=self.client)
        p.setTimeStep(dt, physicsClientId=self.client)
        self.dt = dt
        self.quad = Quadrotor(self.client, params if params is not None else QuadParams())

    def close(self) -> None:
        p.disconnect(physicsClientId=self.client)

    def place(
        self,
        position: Sequence[float],
        quaternion: Sequence[float],
        velocity: Sequence[float],
        angular_velocity: Sequence[float],
        rotor_speed: Sequence[float],
    ) -> None:
        """Put the drone in a state (world; quaternion x, y, z, w; rotor speeds rad/s)."""
        body, cid = self.quad.body, self.client
        p.resetBasePositionAndOrientation(
            body, list(map(float, position)), list(map(float, quaternion)), physicsClientId=cid
        )
        p.resetBaseVelocity(
            body, list(map(float, velocity)), list(map(float, angular_velocity)), physicsClientId=cid
        )
        self.quad.rotor_speed = [float(w) for w in rotor_speed]

    def tick(
        self,
        speed_cmd: Sequence[float],
        scale: Sequence[float] | None = None,
        force: Sequence[float] | None = None,
    ) -> None:
        """One physics tick on rotor speed commands (rad/s), per-rotor thrust factors and an
        external world force (N)."""
        quad, cid = self.quad, self.client
        pos, quat, vel, _ = quad.state()
        quad.apply([float(c) for c in speed_cmd], self.dt, pos, quat, vel, thrust_scale=scale)
        if force is not None:
            f = [float(v) for v in force]
            p.applyExternalForce(quad.body, -1, f, pos, p.WORLD_FRAME, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)

    def state(self) -> dict[str, np.ndarray]:
        """The drone's state as PyBullet reports it: ``position``, ``quaternion`` (x, y, z, w),
        ``rotation`` (3, 3, world from body), ``velocity``, ``angular_velocity``, ``rotor_speed``."""
        pos, quat, vel, omega = self.quad.state()
        rot = np.asarray(p.getMatrixFromQuaternion(quat), dtype=np.float64).reshape(3, 3)
        return {
            "position": np.asarray(pos, dtype=np.float64),
            "quaternion": np.asarray(quat, dtype=np.float64),
            "rotation": rot,
            "velocity": np.asarray(vel, dtype=np.float64),
            "angular_velocity": np.asarray(omega, dtype=np.float64),
            "rotor_speed": np.asarray(self.quad.rotor_speed, dtype=np.float64),
        }


def stack(rows: Sequence[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The rows' states stacked by key ((N, ...) arrays)."""
    return {k: np.stack([r[k] for r in rows]) for k in rows[0]}


def controller_state(c: VelocityController) -> ControllerState:
    """The JAX :class:`~ihrcf_env.fast.autopilot.ControllerState` of the simulator's scalar
    controller ``c`` (host arrays, float64)."""
    return ControllerState(
        np.asarray(c.p_ref, dtype=np.float64),
        np.float64(c.yaw_ref),
        np.asarray(c.integral, dtype=np.float64),
        np.asarray(c.disturbance, dtype=np.float64),
        np.asarray(c._v_prev if c._v_prev is not None else (0.0, 0.0), dtype=np.float64),
        np.bool_(c._v_prev is not None),
        np.float64(c._thrust_model),
        np.asarray(c._a_model, dtype=np.float64),
        np.bool_(c._saturated),
        np.asarray(c._f_cmd, dtype=np.float64),
    )
