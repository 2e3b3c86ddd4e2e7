"""The velocity controller (velocity set-points in the heading frame -> rotor speeds, at the physics
rate) for one drone: the port of :class:`ihrcf_env.sim.drone.VelocityController`.
The position set-point integrates the command with its leash; the horizontal PID is the classic
loop (per-axis integrator clamp) or the wind-holding loop (conditional, norm-limited integral and
the disturbance observer); then the vertical PID, the tilt limit, the yaw reference, the geometric
SO(3) attitude loop and the saturating mixer.

The gains are configuration (:class:`Gains`, Python numbers: they choose the loop's form at trace
time); the controller's state is a :class:`ControllerState` per drone. World frame, SI units.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
from jax import Array

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.fast.dynamics import DroneParams, matrix_from_quaternion, mixer_speeds

__all__ = ["CLASSIC_I_CLAMP", "ControllerState", "Gains", "controller_reset", "gains_of", "velocity_control"]

#: Integral state clamp (m s) of the classic loop (the simulator's ``CLASSIC_I_CLAMP``).
CLASSIC_I_CLAMP = 2.0
_TWO_PI = 2 * math.pi


class Gains(NamedTuple):
    """The controller's gains (Python numbers; see the simulator's ``VelocityGains``)."""

    kp_pos: float
    kd_vel: float
    ki_pos: float
    kp_z: float
    kd_z: float
    ki_z: float
    max_tilt: float
    k_att: tuple[float, float, float]
    k_rate: tuple[float, float, float]
    leash: float
    i_limit: float
    i_limit_z: float
    dob_tau: float
    wind_hold: bool


def gains_of(g: Any) -> Gains:
    """The :class:`Gains` of an object with the same fields (the simulator's ``VelocityGains``)."""
    return Gains(
        float(g.kp_pos),
        float(g.kd_vel),
        float(g.ki_pos),
        float(g.kp_z),
        float(g.kd_z),
        float(g.ki_z),
        float(g.max_tilt),
        tuple(float(v) for v in g.k_att),  # type: ignore[arg-type]
        tuple(float(v) for v in g.k_rate),  # type: ignore[arg-type]
        float(g.leash),
        float(g.i_limit),
        float(g.i_limit_z),
        float(g.dob_tau),
        bool(g.wind_hold),
    )


class ControllerState(NamedTuple):
    """One controller's state: ``p_ref`` (3,) m, ``yaw_ref`` rad, ``integral`` (3,) m s,
    ``disturbance`` (2,) m/s^2 (world x, y), the observer's previous velocity ``v_prev`` (2,) and
    ``has_v_prev``, the thrust model ``thrust_model`` N and ``a_model`` (2,) m/s^2, the last
    ``saturated`` flag and horizontal command ``f_cmd`` (2,) m/s^2."""

    p_ref: Array
    yaw_ref: Array
    integral: Array
    disturbance: Array
    v_prev: Array
    has_v_prev: Array
    thrust_model: Array
    a_model: Array
    saturated: Array
    f_cmd: Array


def controller_reset(params: DroneParams, position: Array, yaw: Array) -> ControllerState:
    """A controller holding ``position`` (3,) and heading ``yaw`` (rad), integrals at zero."""
    position = jnp.asarray(position)
    z2 = jnp.zeros(2, dtype=position.dtype)
    return ControllerState(
        position,
        jnp.asarray(yaw, dtype=position.dtype),
        jnp.zeros(3, dtype=position.dtype),
        z2,
        z2,
        jnp.asarray(False),
        params.mass * GRAVITY,
        z2,
        jnp.asarray(False),
        z2,
    )


def _remainder(x: Array, y: float) -> Array:
    """``math.remainder(x, y)`` for a positive ``y``, computed exactly (the simulator's)."""
    r2 = jnp.fmod(x, 2.0 * y)
    a = jnp.abs(r2)
    half = 0.5 * y
    b = a - y
    r = jnp.where(a <= half, a, jnp.where(a < y, b, jnp.where(b < half, b, b - y)))
    return jnp.where(jnp.signbit(r2), -r, r)


def _hypot_over(x: Array, y: Array, limit: Array | float) -> tuple[Array, Array]:
    h = jnp.hypot(x, y)
    return h > limit, h


def velocity_control(
    state: ControllerState,
    setpoint: Array,
    dt: float,
    pos: Array,
    quat: Array,
    vel: Array,
    omega: Array,
    params: DroneParams,
    gains: Gains,
    rotation: Array | None = None,
) -> tuple[ControllerState, Array]:
    """The new controller state and rotor speed commands (4,) rad/s for ``setpoint`` (4,) =
    (vx, vy, vz, yaw_rate) (m/s, rad/s; heading frame) of the drone at ``pos`` (3,) with ``quat``
    (4,; x, y, z, w), velocity ``vel`` (3,) and angular velocity ``omega`` (3,) (world);
    ``rotation``: the matrix of ``quat`` when already computed."""
    g = gains
    m = params.mass
    r = matrix_from_quaternion(quat) if rotation is None else rotation
    r00, r01, r02 = r[0, 0], r[0, 1], r[0, 2]
    r10, r11, r12 = r[1, 0], r[1, 1], r[1, 2]
    r20, r21, r22 = r[2, 0], r[2, 1], r[2, 2]
    yaw = jnp.arctan2(r10, r00)
    cy, sy = jnp.cos(yaw), jnp.sin(yaw)
    sp_x, sp_y, sp_z, sp_r = setpoint[0], setpoint[1], setpoint[2], setpoint[3]
    vc0, vc1, vc2 = cy * sp_x - sy * sp_y, sy * sp_x + cy * sp_y, sp_z
    pr = state.p_ref + jnp.stack([vc0 * dt, vc1 * dt, vc2 * dt])
    e = pr - pos
    e0, e1, e2 = e[0], e[1], e[2]
    n = jnp.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    far = n > g.leash
    k = g.leash / jnp.where(far, n, 1.0)
    e0, e1, e2 = (jnp.where(far, c * k, c) for c in (e0, e1, e2))
    pr = jnp.where(far, pos + jnp.stack([e0, e1, e2]), pr)
    kp, kd, ki = g.kp_pos, g.kd_vel, g.ki_pos
    v0, v1, v2 = vel[0], vel[1], vel[2]
    integ = state.integral
    dist, v_prev, has_v_prev = state.disturbance, state.v_prev, state.has_v_prev
    if not g.wind_hold:
        c = CLASSIC_I_CLAMP
        integ = jnp.minimum(c, jnp.maximum(-c, integ + jnp.stack([e0, e1, e2]) * dt))
        i2 = integ[2]
        fx = kp * e0 + kd * (vc0 - v0) + ki * integ[0]
        fy = kp * e1 + kd * (vc1 - v1) + ki * integ[1]
    else:
        lim_i = g.i_limit
        if ki > 0.0:
            free = ~state.saturated | (e0 * state.f_cmd[0] + e1 * state.f_cmd[1] <= 0.0)
            i0, i1 = integ[0] + e0 * dt, integ[1] + e1 * dt
            cap = lim_i / ki
            over, ni = _hypot_over(i0, i1, cap)
            den = jnp.where(over, ni, 1.0)
            i0 = jnp.where(over, i0 * cap / den, i0)
            i1 = jnp.where(over, i1 * cap / den, i1)
            i0, i1 = jnp.where(free, i0, integ[0]), jnp.where(free, i1, integ[1])
        else:
            i0 = i1 = jnp.zeros_like(e0)
        if g.ki_z > 0.0:
            cap_z = g.i_limit_z / g.ki_z
            i2 = jnp.minimum(cap_z, jnp.maximum(-cap_z, integ[2] + e2 * dt))
        else:
            i2 = jnp.zeros_like(e2)
        integ = jnp.stack([i0, i1, i2])
        if g.dob_tau > 0.0:
            kk = dt / (g.dob_tau + dt)
            d0 = dist[0] + kk * ((v0 - v_prev[0]) / dt - state.a_model[0] - dist[0])
            d1 = dist[1] + kk * ((v1 - v_prev[1]) / dt - state.a_model[1] - dist[1])
            over, nd = _hypot_over(d0, d1, lim_i)
            den = jnp.where(over, nd, 1.0)
            d0 = jnp.where(over, d0 * lim_i / den, d0)
            d1 = jnp.where(over, d1 * lim_i / den, d1)
            dist = jnp.where(has_v_prev, jnp.stack([d0, d1]), dist)
            v_prev = jnp.stack([v0, v1])
            has_v_prev = jnp.asarray(True)
        fx = kp * e0 + kd * (vc0 - v0) + ki * i0 - dist[0]
        fy = kp * e1 + kd * (vc1 - v1) + ki * i1 - dist[1]
    acc_z = g.kp_z * e2 + g.kd_z * (vc2 - v2) + g.ki_z * i2
    fz = jnp.maximum(acc_z + GRAVITY, 0.2 * GRAVITY)
    lim = fz * math.tan(g.max_tilt)
    clip, nxy = _hypot_over(fx, fy, lim)
    saturated = clip & g.wind_hold
    den = jnp.where(clip, nxy, 1.0)
    fx = jnp.where(clip, fx * lim / den, fx)
    fy = jnp.where(clip, fy * lim / den, fy)
    F0, F1, F2 = m * fx, m * fy, m * fz
    yaw_ref = _remainder(state.yaw_ref + sp_r * dt, _TWO_PI)
    nF = jnp.sqrt(F0 * F0 + F1 * F1 + F2 * F2)
    z0, z1, z2 = F0 / nF, F1 / nF, F2 / nF
    xc0, xc1 = jnp.cos(yaw_ref), jnp.sin(yaw_ref)
    y0, y1, y2 = -z2 * xc1, z2 * xc0, z0 * xc1 - z1 * xc0
    ny = jnp.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    y0, y1, y2 = y0 / ny, y1 / ny, y2 / ny
    x0, x1, x2 = y1 * z2 - y2 * z1, y2 * z0 - y0 * z2, y0 * z1 - y1 * z0
    thrust = F0 * r02 + F1 * r12 + F2 * r22
    e_R0 = 0.5 * ((z0 * r01 + z1 * r11 + z2 * r21) - (y0 * r02 + y1 * r12 + y2 * r22))
    e_R1 = 0.5 * ((x0 * r02 + x1 * r12 + x2 * r22) - (z0 * r00 + z1 * r10 + z2 * r20))
    e_R2 = 0.5 * ((y0 * r00 + y1 * r10 + y2 * r20) - (x0 * r01 + x1 * r11 + x2 * r21))
    w0, w1, w2 = omega[0], omega[1], omega[2]
    wb0 = r00 * w0 + r10 * w1 + r20 * w2
    wb1 = r01 * w0 + r11 * w1 + r21 * w2
    wb2 = r02 * w0 + r12 * w1 + r22 * w2
    J0, J1, J2 = params.inertia[0], params.inertia[1], params.inertia[2]
    Jw0, Jw1, Jw2 = J0 * wb0, J1 * wb1, J2 * wb2
    ka0, ka1, ka2 = g.k_att
    kr0, kr1, kr2 = g.k_rate
    tx = -ka0 * e_R0 - kr0 * (wb0 - sp_r * r20) + (wb1 * Jw2 - wb2 * Jw1)
    ty = -ka1 * e_R1 - kr1 * (wb1 - sp_r * r21) + (wb2 * Jw0 - wb0 * Jw2)
    tz = -ka2 * e_R2 - kr2 * (wb2 - sp_r * r22) + (wb0 * Jw1 - wb1 * Jw0)
    speeds = mixer_speeds(params, thrust, tx, ty, tz)
    thrust_model, a_model = state.thrust_model, state.a_model
    if g.wind_hold and g.dob_tau > 0.0:
        lag = jnp.where(params.motor_tau > 0, jnp.minimum(1.0, dt / params.motor_tau), 1.0)
        s0, s1, s2, s3 = speeds[0], speeds[1], speeds[2], speeds[3]
        t_cmd = params.kf * (s0 * s0 + s1 * s1 + s2 * s2 + s3 * s3)
        s_model = jnp.sqrt(thrust_model)
        s_model = s_model + lag * (jnp.sqrt(t_cmd) - s_model)
        thrust_model = s_model * s_model
        a_model = jnp.stack([thrust_model * r02 / m, thrust_model * r12 / m])
    new = ControllerState(
        pr, yaw_ref, integ, dist, v_prev, has_v_prev, thrust_model, a_model, saturated, jnp.stack([fx, fy])
    )
    return new, speeds
