"""The quadrotor's physics tick for one drone: rotor lag, thrust and drag, PyBullet's rigid-body
step, the saturating mixer and the ground effect relative to the deck. Ports of the simulator's
drone (:class:`ihrcf_env.sim.drone.Quadrotor`: rotor lag, forces, the mixer of
``wrench_to_speeds``), of PyBullet's double-precision rigid-body step of it (the same formulas in
the same order, the orientation reported through a rotation matrix as PyBullet reports it) and of
:class:`ihrcf_env.sim.ground_effect.GroundEffect`.

State (world frame, SI): position (3,) m, quaternion (4,) (x, y, z, w; body to world), velocity
(3,) m/s, angular velocity (3,) rad/s, rotor speeds (4,) rad/s in the motor order of the
quadrotor's parameters.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array, lax

from ihrcf_env.core.constants import GRAVITY

__all__ = [
    "BULLET_MAX_COORDINATE_VELOCITY",
    "DroneParams",
    "DroneState",
    "GroundEffectParams",
    "bullet_step",
    "drone_params",
    "hover_state",
    "matrix_from_quaternion",
    "mixer_speeds",
    "quaternion_from_matrix",
    "rotor_positions",
    "thrust_scale",
    "tick",
    "ticks",
]

#: Bullet's default ``m_maxCoordinateVelocity`` (m/s and rad/s, per world axis).
BULLET_MAX_COORDINATE_VELOCITY = 100.0
#: Bullet's ``ANGULAR_MOTION_THRESHOLD`` (rad): the largest rotation of one step.
ANGULAR_MOTION_THRESHOLD = 0.25 * math.pi


class DroneParams(NamedTuple):
    """The quadrotor's constants as arrays (see :func:`drone_params`)."""

    mass: Array
    inertia: Array  # (3,) kg m^2, body principal axes
    kf: Array
    km: Array
    motor_tau: Array  # s
    drag: Array  # N s/m
    motor_x: Array  # (4,) m
    motor_y: Array  # (4,) m
    spin: Array  # (4,) +1 counter-clockwise seen from above
    max_thrust: Array  # N per motor
    inv_mixer: Array  # (4, 4): (thrust, tx, ty, tz) -> motor thrusts
    gravity: Array
    max_velocity: Array


class DroneState(NamedTuple):
    """One drone's state (see the module docstring)."""

    position: Array
    quaternion: Array
    velocity: Array
    angular_velocity: Array
    rotor_speed: Array


def drone_params(
    params: Any, gravity: float = GRAVITY, max_velocity: float = BULLET_MAX_COORDINATE_VELOCITY
) -> DroneParams:
    """The :class:`DroneParams` of a quadrotor parameter set (an object with ``mass``, ``inertia``,
    ``kf``, ``km``, ``motor_tau``, ``drag``, ``motor_xy``, ``spin``, ``max_thrust`` and ``mixer``, as
    the simulator's ``QuadParams``); host-side, once per configuration."""
    xy = np.asarray(params.motor_xy, dtype=np.float64)
    f = jnp.asarray
    return DroneParams(
        f(float(params.mass)),
        f(np.asarray(params.inertia, dtype=np.float64)),
        f(float(params.kf)),
        f(float(params.km)),
        f(float(params.motor_tau)),
        f(float(params.drag)),
        f(xy[:, 0]),
        f(xy[:, 1]),
        f(np.asarray(params.spin, dtype=np.float64)),
        f(float(params.max_thrust)),
        f(np.linalg.inv(np.asarray(params.mixer, dtype=np.float64))),  # host-side, as the simulator
        f(float(gravity)),
        f(float(max_velocity)),
    )


def hover_state(params: DroneParams, position: Array, yaw: Array, hover: bool = True) -> DroneState:
    """A drone level at ``position`` (3,) with heading ``yaw`` (rad), at rest, rotors at hover speed
    (``hover``) or stopped."""
    q = jnp.stack([jnp.zeros_like(yaw), jnp.zeros_like(yaw), jnp.sin(0.5 * yaw), jnp.cos(0.5 * yaw)])
    w = jnp.sqrt(params.mass * GRAVITY / 4 / params.kf) if hover else jnp.zeros(())
    z3 = jnp.zeros(3, dtype=q.dtype)
    return DroneState(jnp.asarray(position, dtype=q.dtype), q, z3, z3, jnp.full(4, w, dtype=q.dtype))


def matrix_from_quaternion(q: Array) -> Array:
    """Rotation matrix (3, 3) of a quaternion (x, y, z, w) with Bullet's formula and rounding."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    return jnp.array(
        [
            [1.0 - (yy + zz), xy - wz, xz + wy],
            [xy + wz, 1.0 - (xx + zz), yz - wx],
            [xz - wy, yz + wx, 1.0 - (xx + yy)],
        ]
    )


def quaternion_from_matrix(m: Array) -> Array:
    """Quaternion (x, y, z, w) of a rotation matrix with Bullet's ``getRotation`` (Shepperd's
    method: the branch, hence the sign, from the trace and the largest diagonal element)."""
    d0, d1, d2 = m[0, 0], m[1, 1], m[2, 2]
    trace = d0 + d1 + d2
    s = jnp.sqrt(jnp.maximum(trace + 1.0, 1e-300))
    h = 0.5 / s
    main = jnp.stack([(m[2, 1] - m[1, 2]) * h, (m[0, 2] - m[2, 0]) * h, (m[1, 0] - m[0, 1]) * h, s * 0.5])
    alts = []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        si = jnp.sqrt(jnp.maximum(m[i, i] - m[j, j] - m[k, k] + 1.0, 1e-300))
        hi = 0.5 / si
        alt = [jnp.zeros_like(si)] * 4
        alt[i] = si * 0.5
        alt[3] = (m[k, j] - m[j, k]) * hi
        alt[j] = (m[j, i] + m[i, j]) * hi
        alt[k] = (m[k, i] + m[i, k]) * hi
        alts.append(jnp.stack(alt))
    i_big = jnp.where(d0 < d1, jnp.where(d1 < d2, 2, 1), jnp.where(d0 < d2, 2, 0))
    other = jnp.stack(alts)[i_big]
    return jnp.where(trace <= 0.0, other, main)


def _integrate_quaternion(q: Array, w: Array, dt: Array | float) -> Array:
    """``q`` rotated by the world angular velocity ``w`` over ``dt``: Bullet's exponential map."""
    w0, w1, w2 = w[0], w[1], w[2]
    ang = jnp.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    ang = jnp.where(ang * dt > ANGULAR_MOTION_THRESHOLD, 0.5 * (0.5 * math.pi) / dt, ang)
    small = ang < 0.001
    sinc = jnp.where(
        small,
        0.5 * dt - (dt * dt * dt) * 0.020833333333 * ang * ang,
        jnp.sin(0.5 * ang * dt) / jnp.where(small, 1.0, ang),
    )
    a0, a1, a2 = w0 * sinc, w1 * sinc, w2 * sinc
    ac = jnp.cos(ang * dt * 0.5)
    px, py, pz, pw = -q[0], -q[1], -q[2], q[3]
    qx, qy, qz, qw = -a0, -a1, -a2, ac
    nx = pw * qx + px * qw + py * qz - pz * qy
    ny = pw * qy + py * qw + pz * qx - px * qz
    nz = pw * qz + pz * qw + px * qy - py * qx
    nw = pw * qw - px * qx - py * qy - pz * qz
    inv = 1.0 / jnp.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    return jnp.stack([-(nx * inv), -(ny * inv), -(nz * inv), nw * inv])


def bullet_step(
    state: DroneState, force: Array, torque: Array, params: DroneParams, dt: Array | float
) -> DroneState:
    """One semi-implicit Euler step of the rigid body as PyBullet's multibody integrates it, under
    the total world ``force`` (3,) N (gravity included) and ``torque`` (3,) N m."""
    r = matrix_from_quaternion(state.quaternion)

    def t_vec(v: Array) -> Array:
        return jnp.stack([r[0, i] * v[0] + r[1, i] * v[1] + r[2, i] * v[2] for i in range(3)])

    def vec(v: Array) -> Array:
        return jnp.stack([r[i, 0] * v[0] + r[i, 1] * v[1] + r[i, 2] * v[2] for i in range(3)])

    ob, vb = t_vec(state.angular_velocity), t_vec(state.velocity)
    tb, fb = t_vec(torque), t_vec(force)
    j = params.inertia
    h = j * ob
    za = -tb + jnp.stack(
        [ob[1] * h[2] - ob[2] * h[1], ob[2] * h[0] - ob[0] * h[2], ob[0] * h[1] - ob[1] * h[0]]
    )
    c = jnp.stack(
        [ob[1] * vb[2] - ob[2] * vb[1], ob[2] * vb[0] - ob[0] * vb[2], ob[0] * vb[1] - ob[1] * vb[0]]
    )
    zl = -fb + params.mass * c
    inv_m = 1.0 / params.mass
    al = -(za / j)
    ll = -(zl * inv_m) + c
    vmax = params.max_velocity
    w = jnp.clip(state.angular_velocity + vec(al) * dt, -vmax, vmax)
    v = jnp.clip(state.velocity + vec(ll) * dt, -vmax, vmax)
    p = state.position + dt * v
    return DroneState(p, _integrate_quaternion(state.quaternion, w, dt), v, w, state.rotor_speed)


def tick(
    state: DroneState,
    speed_cmd: Array,
    params: DroneParams,
    dt: Array | float,
    scale: Array | None = None,
    force: Array | None = None,
) -> DroneState:
    """One physics tick: rotor speeds follow ``speed_cmd`` (4,) rad/s through the first-order lag,
    thrusts ``kf w^2`` (times the per-rotor ``scale``, e.g. ground effect; the yaw reaction torques
    unscaled), linear drag, an optional external world ``force`` (3,) N and gravity."""
    a = jnp.where(params.motor_tau > 0, jnp.minimum(1.0, dt / params.motor_tau), 1.0)
    w = state.rotor_speed
    w = w + a * (speed_cmd - w)
    kf, km = params.kf, params.km
    f = kf * w * w
    s = params.spin
    tz = -(km / kf) * (s[0] * f[0] + s[1] * f[1] + s[2] * f[2] + s[3] * f[3])
    if scale is not None:
        f = f * scale
    x, y = params.motor_x, params.motor_y
    thrust = f[0] + f[1] + f[2] + f[3]
    tx = f[0] * y[0] + f[1] * y[1] + f[2] * y[2] + f[3] * y[3]
    ty = -(f[0] * x[0] + f[1] * x[1] + f[2] * x[2] + f[3] * x[3])
    # the rotation PyBullet reports: the quaternion through a matrix and back
    r = matrix_from_quaternion(quaternion_from_matrix(matrix_from_quaternion(state.quaternion)))
    F = r[:, 2] * thrust - params.drag * state.velocity
    T = r[:, 0] * tx + r[:, 1] * ty + r[:, 2] * tz
    if force is not None:
        F = F + force
    F = F.at[2].add(-params.gravity * params.mass)
    return bullet_step(state._replace(rotor_speed=w), F, T, params, dt)


def ticks(state: DroneState, speed_cmd: Array, params: DroneParams, dt: float, n: int) -> DroneState:
    """``n`` ticks under one command (``lax.scan``), no ground effect or external force."""

    def body(s: DroneState, _: None) -> tuple[DroneState, None]:
        return tick(s, speed_cmd, params, dt), None

    out, _ = lax.scan(body, state, None, length=n)
    return out


def _motor_thrusts(params: DroneParams, thrust: Array, tx: Array, ty: Array, tz: Array | None) -> Array:
    rows = params.inv_mixer
    out = []
    for i in range(4):
        f = rows[i, 0] * thrust + rows[i, 1] * tx + rows[i, 2] * ty
        out.append(f if tz is None else f + rows[i, 3] * tz)
    return jnp.stack(out)


def mixer_speeds(params: DroneParams, thrust: Array, tx: Array, ty: Array, tz: Array) -> Array:
    """Rotor speeds (4,) rad/s of a collective ``thrust`` (N) and body torques (N m) within the motor
    limits: exact where every motor fits, else roll/pitch and thrust first, then as much yaw as
    every motor's margin allows (the PX4-style mixer of the simulator)."""
    fmax = params.max_thrust
    f = _motor_thrusts(params, thrust, tx, ty, tz)
    sat = (jnp.min(f) < 0.0) | (jnp.max(f) > fmax)
    g = _motor_thrusts(params, thrust, tx, ty, None)
    spread = jnp.max(g) - jnp.min(g)
    big = spread > fmax
    g = jnp.where(big, g * fmax / jnp.where(big, spread, 1.0), g)
    lo = jnp.min(g)
    g = jnp.where(lo < 0.0, g - lo, g)
    hi = jnp.max(g)
    g = jnp.where(hi > fmax, g - (hi - fmax), g)
    yaw = params.inv_mixer[:, 3] * tz
    safe = jnp.where(yaw == 0.0, 1.0, yaw)
    up = (fmax - g) / safe
    down = g / -safe
    scale = jnp.ones_like(thrust)
    for i in range(4):
        cand = jnp.where(yaw[i] > 0.0, up[i], jnp.where(yaw[i] < 0.0, down[i], jnp.inf))
        scale = jnp.where(cand < scale, cand, scale)
    scale = jnp.where(scale < 0.0, 0.0, scale)
    f = jnp.where(sat, g + scale * yaw, f)
    return jnp.sqrt(jnp.minimum(jnp.maximum(f, 0.0), fmax) / params.kf)


class GroundEffectParams(NamedTuple):
    """Ground effect constants: ``rotor_radius`` (m), ``ground_height`` (world z of the ground, m),
    ``min_height_ratio`` (the model's lowest height over the rotor radius), ``deck_half`` (half the
    deck plate's side, m)."""

    rotor_radius: Array
    ground_height: Array
    min_height_ratio: Array
    deck_half: Array


def rotor_positions(position: Array, rotation: Array, params: DroneParams) -> Array:
    """(4, 3) world rotor hub positions (body ``(x, y, 0)``) of the drone at ``position`` with
    ``rotation`` (world from body)."""
    x, y = params.motor_x, params.motor_y
    return jnp.stack([position[i] + rotation[i, 0] * x + rotation[i, 1] * y for i in range(3)], axis=-1)


def thrust_scale(rotors: Array, deck_position: Array, deck_rotation: Array, ge: GroundEffectParams) -> Array:
    """(R,) thrust ratios of ``rotors`` (R, 3) (world, m) over the deck (top-face centre
    ``deck_position``, world from deck ``deck_rotation``) and the ground: per rotor the deck under
    it or the ground, blended across the deck's edge (Cheeseman-Bennett)."""
    r, half, ground = ge.rotor_radius, ge.deck_half, ge.ground_height
    q4, z_min = 0.25 * r, ge.min_height_ratio * r
    inv_2r = 0.5 / r
    px, py, pz = rotors[:, 0], rotors[:, 1], rotors[:, 2]
    q = q4 / jnp.maximum(pz - ground, z_min)
    ground_ratio = 1.0 / (1.0 - q * q)
    a = deck_rotation
    dx, dy, dz = px - deck_position[0], py - deck_position[1], pz - deck_position[2]
    h = dx * a[0, 2] + dy * a[1, 2] + dz * a[2, 2]
    a22 = a[2, 2]
    over = (h > 0.0) & (a22 > 0.0)
    qz = dz - h / jnp.where(a22 == 0.0, 1.0, a22)
    u = dx * a[0, 0] + dy * a[1, 0] + qz * a[2, 0]
    v = dx * a[0, 1] + dy * a[1, 1] + qz * a[2, 1]
    cover = 0.5 + (half - jnp.maximum(jnp.abs(u), jnp.abs(v))) * inv_2r
    q = q4 / jnp.maximum(h, z_min)
    deck_ratio = 1.0 / (1.0 - q * q)
    blend = cover * deck_ratio + (1.0 - cover) * ground_ratio
    out = jnp.where(cover >= 1.0, deck_ratio, blend)
    return jnp.where(over & (cover > 0.0), out, ground_ratio)
