"""One control period of one drone's flight (``lax.scan`` over the physics ticks): the velocity
autopilot, the ground effect over the deck and the ground, the wind's drag force, the rigid-body
tick, the touchdown test against the deck plate, the ground and the Stewart base, and, once down,
the drone resting where it touched (moving with the deck on it). The counterpart of one
:meth:`World.step <ihrcf_env.sim.world.World.step>` on velocity setpoints, with the navigation
errors given (no user disturbances); the touchdown is the closed-form test of
:mod:`ihrcf_env.fast.contact` where the world has PyBullet's contacts (after which its drone
follows PyBullet's contact response, this one rests).

The deck's poses at the period's ticks and the air's velocity at each tick are inputs (from
:mod:`ihrcf_env.fast.deck_motion` and :mod:`ihrcf_env.fast.wind`, or the simulator's). Frames:
world z up; quaternions (x, y, z, w); m, s, rad.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax

from ihrcf_env.fast import contact
from ihrcf_env.fast.autopilot import ControllerState, Gains, velocity_control
from ihrcf_env.fast.dynamics import (
    DroneParams,
    DroneState,
    GroundEffectParams,
    matrix_from_quaternion,
    quaternion_from_matrix,
    rotor_positions,
    thrust_scale,
    tick,
)
from ihrcf_env.fast.navigation import NavConstants, NavState, nav_estimate
from ihrcf_env.fast.wind import DragConstants, wind_force

__all__ = ["AdvanceConsts", "Flight", "advance", "angular_velocity_between", "quat_multiply"]


class AdvanceConsts(NamedTuple):
    """Host-side constants: the drone, the autopilot's gains, the ground effect (None: off), the
    physics tick ``dt`` (s) and ``substeps`` per control period, the deck plate's top half extent
    and thickness (m), the Stewart base's cylinder (radius, height; m), the drone's bounding
    ``reach`` (m), its collision boxes (centres, halves (B, 3); body) and the wind's drag."""

    drone: DroneParams
    gains: Gains
    ground_effect: GroundEffectParams | None
    dt: float
    substeps: int
    deck_half: float
    deck_thickness: float
    base_radius: float
    base_height: float
    reach: float
    box_centres: np.ndarray
    box_halves: np.ndarray
    drag: DragConstants | None


class Flight(NamedTuple):
    """The drone, its autopilot, and its touchdown: ``latched`` (it has touched), ``on_deck``,
    its pose in the frame of what it rests on (``rel_pos``, ``rel_quat``), the contact ``code``
    (:data:`~ihrcf_env.fast.contact.DECK`, ...; 0 none yet), the ``tick`` of the contact within its
    period, the velocity the tick before it (``touch_velocity``, m/s) and the last tick's
    acceleration (``acceleration``, m/s^2, world)."""

    drone: DroneState
    control: ControllerState
    latched: Array
    on_deck: Array
    rel_pos: Array
    rel_quat: Array
    code: Array
    tick: Array
    touch_velocity: Array
    acceleration: Array


def quat_multiply(a: Array, b: Array) -> Array:
    """Hamilton product ``a b`` of quaternions (x, y, z, w) (the simulator's operation order)."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return jnp.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def angular_velocity_between(q_from: Array, q_to: Array, dt: float) -> Array:
    """World-frame angular velocity (rad/s) that rotates ``q_from`` into ``q_to`` in ``dt`` s."""
    ax, ay, az, aw = q_to[0], q_to[1], q_to[2], q_to[3]
    bx, by, bz, bw = -q_from[0], -q_from[1], -q_from[2], q_from[3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    sg = jnp.where(w < 0, -1.0, 1.0)
    x, y, z, w = x * sg, y * sg, z * sg, w * sg
    s = jnp.sqrt(x * x + y * y + z * z)
    small = s < 1e-12
    k = jnp.where(small, 2.0 / dt, 2.0 * jnp.arctan2(s, w) / (jnp.where(small, 1.0, s) * dt))
    return jnp.stack([x * k, y * k, z * k])


def _relative(pos: Array, quat: Array, frame_pos: Array, frame_quat: Array) -> tuple[Array, Array]:
    R = matrix_from_quaternion(frame_quat)
    inv = jnp.stack([-frame_quat[0], -frame_quat[1], -frame_quat[2], frame_quat[3]])
    return R.T @ (pos - frame_pos), quat_multiply(inv, quat)


def _compose(frame_pos: Array, frame_quat: Array, rel_pos: Array, rel_quat: Array) -> tuple[Array, Array]:
    return frame_pos + matrix_from_quaternion(frame_quat) @ rel_pos, quat_multiply(frame_quat, rel_quat)


def _rest(f: Flight, top0: Array, q0: Array, top1: Array, q1: Array, dt: float) -> DroneState:
    pos0, quat0 = _compose(top0, q0, f.rel_pos, f.rel_quat)
    pos, quat = _compose(top1, q1, f.rel_pos, f.rel_quat)
    deck = f.drone._replace(
        position=pos,
        quaternion=quat,
        velocity=(pos - pos0) / dt,
        angular_velocity=angular_velocity_between(quat0, quat, dt),
    )
    z3 = jnp.zeros(3, dtype=pos.dtype)
    ground = f.drone._replace(position=f.rel_pos, quaternion=f.rel_quat, velocity=z3, angular_velocity=z3)
    return _sel(f.on_deck, deck, ground)


def _sel(m: Array, a: DroneState, b: DroneState) -> DroneState:
    return DroneState(*(jnp.where(m, x, y) for x, y in zip(a, b, strict=True)))


def advance(
    c: AdvanceConsts,
    flight: Flight,
    setpoint: Array,
    deck_top: Array,
    deck_quat: Array,
    air: Array | None = None,
    nav: tuple[NavState, NavConstants] | None = None,
) -> Flight:
    """The flight after one control period under the velocity ``setpoint`` (4,): ``deck_top``
    (S + 1, 3) and ``deck_quat`` (S + 1, 4) the deck frame (its top face's centre) at the period's
    S + 1 ticks (first: now), ``air`` (S, 3) the air's velocity at the first S ticks (None: still
    air), ``nav`` the navigation errors at the S ticks (a :class:`~ihrcf_env.fast.navigation.NavState`
    of (S, 3) arrays) and their constants: the autopilot's position and velocity loops close on
    the estimate (None: on the truth). The first contact of the period (if any, and none before)
    is in ``code`` / ``tick``."""
    dt = c.dt
    deck_rot = jax.vmap(matrix_from_quaternion)(deck_quat)  # (S + 1, 3, 3)
    boxes = (
        jnp.asarray(c.box_centres),
        jnp.asarray(c.box_halves),
        jnp.asarray(contact.box_corners(c.box_centres, c.box_halves)),
    )
    code0 = flight.code

    def body(f: Flight, j: Array) -> tuple[Flight, None]:
        st = f.drone
        q_rep = quaternion_from_matrix(matrix_from_quaternion(st.quaternion))
        rot = matrix_from_quaternion(q_rep)
        pos_fb, vel_fb = st.position, st.velocity
        if nav is not None:
            errors = NavState(nav[0].ep[j], nav[0].ev[j], nav[0].white[j])
            pos_fb, vel_fb = nav_estimate(errors, st.position, st.velocity, nav[1])
        ctrl, cmd = velocity_control(
            f.control,
            setpoint,
            dt,
            pos_fb,
            q_rep,
            vel_fb,
            st.angular_velocity,
            c.drone,
            c.gains,
            rot,
        )
        scale = None
        if c.ground_effect is not None:
            scale = thrust_scale(
                rotor_positions(st.position, rot, c.drone), deck_top[j], deck_rot[j], c.ground_effect
            )
        force = None
        if air is not None and c.drag is not None:
            force = wind_force(st.velocity, air[j], c.drag)
        prev_vel = st.velocity
        new = tick(st, cmd, c.drone, dt, scale, force)
        rested = _rest(f, deck_top[j], deck_quat[j], deck_top[j + 1], deck_quat[j + 1], dt)
        new = _sel(f.latched, rested, new)
        # touchdown: the first contact of a drone not yet down
        top, R_top = deck_top[j + 1], deck_rot[j + 1]
        R_new = matrix_from_quaternion(new.quaternion)
        h = jnp.abs(jnp.sum((new.position - top) * R_top[:, 2]))
        near = ~f.latched & ((new.position[2] < c.reach + c.base_height) | (h < c.reach + c.deck_thickness))
        hit = contact.first_contact(
            new.position,
            R_new,
            top,
            R_top,
            c.deck_half,
            c.deck_thickness,
            c.base_radius,
            c.base_height,
            *boxes,
        )
        hit = jnp.where(near, hit, contact.NO_CONTACT)
        touch = hit != contact.NO_CONTACT
        on_deck = hit == contact.DECK
        rel_d = _relative(new.position, new.quaternion, top, deck_quat[j + 1])
        rel_pos = jnp.where(on_deck, rel_d[0], new.position)
        rel_quat = jnp.where(on_deck, rel_d[1], new.quaternion)
        g = Flight(
            new,
            ctrl,
            f.latched | touch,
            jnp.where(touch, on_deck, f.on_deck),
            jnp.where(touch, rel_pos, f.rel_pos),
            jnp.where(touch, rel_quat, f.rel_quat),
            jnp.where(touch, hit, f.code),
            jnp.where(touch, j + 1, f.tick),
            jnp.where(touch, prev_vel, f.touch_velocity),
            f.acceleration,
        )
        # a drone that touched at this tick rests there already (as the simulator's latch)
        now = _sel(touch, _rest(g, deck_top[j], deck_quat[j], top, deck_quat[j + 1], dt), g.drone)
        return g._replace(drone=now, acceleration=(now.velocity - prev_vel) / dt), None

    out, _ = lax.scan(
        body, flight._replace(tick=jnp.where(code0 != 0, flight.tick, 0)), jnp.arange(c.substeps)
    )
    return out
