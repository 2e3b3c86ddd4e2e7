"""One physics step of N free rigid bodies, as Bullet integrates a single-link ``loadURDF`` body.

PyBullet loads a URDF as a ``btMultiBody`` (Featherstone) and steps it in
``btMultiBodyDynamicsWorld``: first the velocities from the forces accumulated during the step
(``btMultiBody::computeAccelerationsArticulatedBodyAlgorithmMultiDof``), then the pose from the
*new* velocities (``btMultiBody::stepPositionsMultiDof``): semi-implicit (symplectic) Euler. For a
body without links, with its inertial frame at the link origin, Bullet computes, in the body frame
(``Rt``: world to body, the matrix of the stored world-to-base quaternion, i.e. ``R^T``):

* ``omega_b = Rt omega``, ``v_b = Rt v``;
* angular: ``alpha_b = -((-Rt tau + omega_b x (I omega_b)) / I)`` (the gyroscopic term explicit,
  ``m_useGyroTerm`` on by default), ``omega += dt (R alpha_b)``;
* linear: ``a_b = -((-Rt F + m omega_b x v_b) * (1 / m))``, ``v += dt R (a_b + omega_b x v_b)``
  (the body-frame Coriolis term added and removed again: the world acceleration is ``F / m``);
* every velocity component (world frame) clamped to ``[-v_max, v_max]`` (``m_maxCoordinateVelocity``,
  100 by default: 100 m/s and 100 rad/s per axis);
* ``p += dt v``; the orientation by the exponential map of ``omega dt`` (left-multiplied in the
  world frame), the rotation angle capped at pi/4 per step (``ANGULAR_MOTION_THRESHOLD``), a Taylor
  series of ``sin`` below 0.001 rad/s, then renormalised.

``linearDamping`` and ``angularDamping`` are 0 (set by :class:`~ihrcf_env.sim.drone.Quadrotor`), so
Bullet's damping terms vanish and are not modelled. The operations below follow Bullet's order so
the rounding is the same (PyBullet is built in double precision).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.batched.floatmath import matrices_from_quaternions

Array = NDArray[np.float64]

#: Bullet's default ``btMultiBody::m_maxCoordinateVelocity`` (m/s and rad/s, per world axis).
BULLET_MAX_COORDINATE_VELOCITY = 100.0
#: Bullet's ``ANGULAR_MOTION_THRESHOLD`` (rad): the largest rotation of one step.
ANGULAR_MOTION_THRESHOLD = 0.25 * math.pi


def _mat_vec(m: Array, x: Array, y: Array, z: Array) -> tuple[Array, Array, Array]:
    """``m @ (x, y, z)`` row by row, each a left-to-right dot product (btMatrix3x3 * btVector3)."""
    return (
        m[:, 0, 0] * x + m[:, 0, 1] * y + m[:, 0, 2] * z,
        m[:, 1, 0] * x + m[:, 1, 1] * y + m[:, 1, 2] * z,
        m[:, 2, 0] * x + m[:, 2, 1] * y + m[:, 2, 2] * z,
    )


def _mat_t_vec(m: Array, x: Array, y: Array, z: Array) -> tuple[Array, Array, Array]:
    """``m^T @ (x, y, z)`` (btMatrix3x3::transpose() * btVector3)."""
    return (
        m[:, 0, 0] * x + m[:, 1, 0] * y + m[:, 2, 0] * z,
        m[:, 0, 1] * x + m[:, 1, 1] * y + m[:, 2, 1] * z,
        m[:, 0, 2] * x + m[:, 1, 2] * y + m[:, 2, 2] * z,
    )


def bullet_step(
    position: Array,
    quaternion: Array,
    velocity: Array,
    angular_velocity: Array,
    force: Array,
    torque: Array,
    mass: float,
    inertia: tuple[float, float, float],
    dt: float,
    max_velocity: float = BULLET_MAX_COORDINATE_VELOCITY,
) -> None:
    """Advance N bodies by ``dt`` (s) in place, under the total world force ``force`` (N, 3) (N,
    gravity included) and world torque ``torque`` (N, 3) (N m) about the centre of mass.

    ``position`` (N, 3) m and ``quaternion`` (N, 4) (x, y, z, w, body to world) are the pose,
    ``velocity`` (N, 3) m/s and ``angular_velocity`` (N, 3) rad/s the world-frame velocities."""
    # Rt = matrix of the world-to-base quaternion conj(q): exactly the transpose of R(q)
    r = matrices_from_quaternions(quaternion)
    w0, w1, w2 = angular_velocity[:, 0], angular_velocity[:, 1], angular_velocity[:, 2]
    v0, v1, v2 = velocity[:, 0], velocity[:, 1], velocity[:, 2]
    ob0, ob1, ob2 = _mat_t_vec(r, w0, w1, w2)
    vb0, vb1, vb2 = _mat_t_vec(r, v0, v1, v2)
    tb0, tb1, tb2 = _mat_t_vec(r, torque[:, 0], torque[:, 1], torque[:, 2])
    fb0, fb1, fb2 = _mat_t_vec(r, force[:, 0], force[:, 1], force[:, 2])
    j0, j1, j2 = inertia
    h0, h1, h2 = j0 * ob0, j1 * ob1, j2 * ob2
    # zero-acceleration spatial force: -external + gyroscopic / Coriolis (damping terms are zero)
    za0 = -tb0 + (ob1 * h2 - ob2 * h1)
    za1 = -tb1 + (ob2 * h0 - ob0 * h2)
    za2 = -tb2 + (ob0 * h1 - ob1 * h0)
    c0, c1, c2 = ob1 * vb2 - ob2 * vb1, ob2 * vb0 - ob0 * vb2, ob0 * vb1 - ob1 * vb0
    zl0, zl1, zl2 = -fb0 + mass * c0, -fb1 + mass * c1, -fb2 + mass * c2
    inv_m = 1.0 / mass
    al0, al1, al2 = -(za0 / j0), -(za1 / j1), -(za2 / j2)
    ll0, ll1, ll2 = -(zl0 * inv_m) + c0, -(zl1 * inv_m) + c1, -(zl2 * inv_m) + c2
    dw = _mat_vec(r, al0, al1, al2)
    dv = _mat_vec(r, ll0, ll1, ll2)
    vmax = max_velocity
    for k in range(3):
        angular_velocity[:, k] = np.clip(angular_velocity[:, k] + dw[k] * dt, -vmax, vmax)
        velocity[:, k] = np.clip(velocity[:, k] + dv[k] * dt, -vmax, vmax)
    position += dt * velocity
    integrate_quaternions(quaternion, angular_velocity, dt)


def integrate_quaternions(quaternion: Array, angular_velocity: Array, dt: float) -> None:
    """Rotate ``quaternion`` (N, 4) in place by the world angular velocity (N, 3) over ``dt``:
    Bullet's exponential-map update of a multibody base, rounding included."""
    w0, w1, w2 = angular_velocity[:, 0], angular_velocity[:, 1], angular_velocity[:, 2]
    ang = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    ang = np.where(ang * dt > ANGULAR_MOTION_THRESHOLD, 0.5 * (0.5 * math.pi) / dt, ang)
    small = ang < 0.001
    with np.errstate(invalid="ignore", divide="ignore"):
        sinc = np.where(
            small,
            0.5 * dt - (dt * dt * dt) * 0.020833333333 * ang * ang,
            np.sin(0.5 * ang * dt) / ang,
        )
    a0, a1, a2 = w0 * sinc, w1 * sinc, w2 * sinc
    ac = np.cos(ang * dt * 0.5)
    # Bullet stores conj(q) (world to base) and right-multiplies it by conj(a) = (-a, cos)
    px, py, pz, pw = -quaternion[:, 0], -quaternion[:, 1], -quaternion[:, 2], quaternion[:, 3]
    qx, qy, qz, qw = -a0, -a1, -a2, ac
    nx = pw * qx + px * qw + py * qz - pz * qy
    ny = pw * qy + py * qw + pz * qx - px * qz
    nz = pw * qz + pz * qw + px * qy - py * qx
    nw = pw * qw - px * qx - py * qy - pz * qz
    inv = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    quaternion[:, 0] = -(nx * inv)
    quaternion[:, 1] = -(ny * inv)
    quaternion[:, 2] = -(nz * inv)
    quaternion[:, 3] = nw * inv


__all__ = [
    "ANGULAR_MOTION_THRESHOLD",
    "BULLET_MAX_COORDINATE_VELOCITY",
    "Array",
    "bullet_step",
    "integrate_quaternions",
]
