"""N quadrotors in free flight, batched in numpy: the motor model and forces of
:class:`~ihrcf_env.sim.drone.Quadrotor` on the rigid-body step of
:func:`~ihrcf_env.sim.batched.integrator.bullet_step`.

One :meth:`BatchedQuadrotor.step` is one physics step of the PyBullet world for every drone: the
rotor speeds follow the commands through the first-order lag ``motor_tau``; rotor thrusts
``kf w^2`` (times optional per-rotor factors, e.g. ground effect) along body z, their roll/pitch
torques and the rotors' reaction (yaw) torques ``km w^2`` (never scaled), linear drag
``-drag v``, an optional external world force (wind, side loads) and gravity; then the body is
advanced as Bullet advances it. Contacts are not modelled (an episode ends at the first touchdown).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.batched.floatmath import (
    matrices_from_quaternions,
    quaternions_from_matrices,
    yaw_quaternions,
)
from ihrcf_env.sim.batched.integrator import BULLET_MAX_COORDINATE_VELOCITY, bullet_step

if TYPE_CHECKING:
    from ihrcf_env.config.vehicle import QuadParams

Array = NDArray[np.float64]


def motor_lag(dt: float, tau: float) -> float:
    """The rotor speed's first-order lag factor over ``dt`` (s): ``min(1, dt / tau)``, 1 when
    ``tau`` is 0 (as :meth:`~ihrcf_env.sim.drone.Quadrotor.apply`)."""
    return min(1.0, dt / tau) if tau > 0 else 1.0


class BatchedQuadrotor:
    """The state of N quadrotors (world frame, SI units), rows independent of each other.

    ``position`` (N, 3) m, ``quaternion`` (N, 4) (x, y, z, w, body to world), ``velocity`` (N, 3)
    m/s, ``angular_velocity`` (N, 3) rad/s (world), ``rotor_speed`` (N, 4) rad/s in the motor order
    of :class:`~ihrcf_env.config.vehicle.QuadParams`. ``max_velocity``: Bullet's per-axis velocity clamp.
    """

    def __init__(
        self,
        params: QuadParams,
        n: int,
        gravity: float = GRAVITY,
        max_velocity: float = BULLET_MAX_COORDINATE_VELOCITY,
    ) -> None:
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n must be a positive integer, got {n!r}")
        self.params = params
        self.n = int(n)
        self.gravity = float(gravity)
        self.max_velocity = float(max_velocity)
        self.position = np.zeros((self.n, 3))
        self.quaternion = np.zeros((self.n, 4))
        self.quaternion[:, 3] = 1.0
        self.velocity = np.zeros((self.n, 3))
        self.angular_velocity = np.zeros((self.n, 3))
        self.rotor_speed = np.zeros((self.n, 4))
        xy = params.motor_xy
        self._x = [float(v) for v in xy[:, 0]]
        self._y = [float(v) for v in xy[:, 1]]
        self._spin = [float(v) for v in params.spin]
        self._lag_dt = float("nan")
        self._lag = 1.0
        self.force = np.zeros((self.n, 3))  # scratch: the total world force of the last step
        self.torque = np.zeros((self.n, 3))  # scratch: the world torque of the last step
        self._reported: tuple[Array, Array] | None = None  # reported_quaternion() of the current state

    def reset(
        self,
        position: ArrayLike,
        yaw: ArrayLike,
        hover: bool = True,
        rows: ArrayLike | None = None,
    ) -> None:
        """Place drones level at ``position`` ((3,) or (k, 3), world m) with heading ``yaw`` (rad),
        at rest, rotors at hover speed when ``hover`` (else stopped); ``rows``: which drones (all
        by default), as :meth:`~ihrcf_env.sim.drone.Quadrotor.reset` does for one."""
        idx = np.arange(self.n) if rows is None else np.asarray(rows, dtype=np.intp).reshape(-1)
        k = idx.size
        pos = np.broadcast_to(np.asarray(position, dtype=np.float64), (k, 3))
        yaws = np.broadcast_to(np.asarray(yaw, dtype=np.float64), (k,))
        self.position[idx] = pos
        self.quaternion[idx] = yaw_quaternions(yaws)
        self.velocity[idx] = 0.0
        self.angular_velocity[idx] = 0.0
        p = self.params
        w_hover = float(np.sqrt(p.mass * GRAVITY / 4 / p.kf))
        self.rotor_speed[idx] = w_hover if hover else 0.0
        self._reported = None

    def rotation(self) -> Array:
        """Body-to-world rotation matrices (N, 3, 3)."""
        return matrices_from_quaternions(self.quaternion)

    def reported_quaternion(self) -> Array:
        """The orientation (N, 4) as PyBullet's ``getBasePositionAndOrientation`` reports it: the
        stored quaternion through a rotation matrix and back (the same rotation; the sign and the
        last bit may differ from :attr:`quaternion`, which is the integrator's state). Computed once
        per state: call :meth:`invalidate` after writing the state arrays directly."""
        if self._reported is None:
            q = quaternions_from_matrices(matrices_from_quaternions(self.quaternion))
            self._reported = (q, matrices_from_quaternions(q))
        return self._reported[0]

    def reported_rotation(self) -> Array:
        """The rotation matrices (N, 3, 3) of :meth:`reported_quaternion` (what PyBullet's
        ``getMatrixFromQuaternion`` gives for the reported orientation)."""
        self.reported_quaternion()
        assert self._reported is not None
        return self._reported[1]

    def invalidate(self) -> None:
        """Forget the cached :meth:`reported_quaternion` (after editing :attr:`quaternion`)."""
        self._reported = None

    def step(
        self,
        speed_cmd: Array,
        dt: float,
        thrust_scale: Array | None = None,
        force: Array | None = None,
    ) -> None:
        """Advance every drone by one physics step ``dt`` (s) under rotor speed commands
        ``speed_cmd`` (N, 4) rad/s, optional per-rotor thrust factors ``thrust_scale`` (N, 4) and an
        optional external world force ``force`` (N, 3) N applied at the centre of mass."""
        p = self.params
        if dt != self._lag_dt:
            self._lag_dt, self._lag = dt, motor_lag(dt, p.motor_tau)
        a = self._lag
        w = self.rotor_speed
        w += a * (speed_cmd - w)
        kf, km = p.kf, p.km
        f = kf * w * w
        s0, s1, s2, s3 = self._spin
        tz = -(km / kf) * (s0 * f[:, 0] + s1 * f[:, 1] + s2 * f[:, 2] + s3 * f[:, 3])
        if thrust_scale is not None:
            f = f * thrust_scale
        f0, f1, f2, f3 = f[:, 0], f[:, 1], f[:, 2], f[:, 3]
        x, y = self._x, self._y
        thrust = f0 + f1 + f2 + f3
        tx = f0 * y[0] + f1 * y[1] + f2 * y[2] + f3 * y[3]
        ty = -(f0 * x[0] + f1 * x[1] + f2 * x[2] + f3 * x[3])
        r = self.reported_rotation()
        vel = self.velocity
        drag = p.drag
        F, T = self.force, self.torque
        for i in range(3):
            F[:, i] = r[:, i, 2] * thrust - drag * vel[:, i]
            T[:, i] = r[:, i, 0] * tx + r[:, i, 1] * ty + r[:, i, 2] * tz
        if force is not None:
            F += force
        F[:, 2] += -self.gravity * p.mass
        bullet_step(
            self.position,
            self.quaternion,
            self.velocity,
            self.angular_velocity,
            F,
            T,
            p.mass,
            p.inertia,
            dt,
            self.max_velocity,
        )
        self._reported = None


__all__ = [
    "Array",
    "BatchedQuadrotor",
    "motor_lag",
]
