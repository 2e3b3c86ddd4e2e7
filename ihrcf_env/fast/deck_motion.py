"""Deck motion for one environment: the sum-of-sines profile, the "ship" profile (a JONSWAP sea's
components through the vessel's response, then the deck point's pose at a time) and the Stewart
platform's leg lengths. Ports of :class:`ihrcf_env.core.profiles.SumOfSines`,
:func:`ihrcf_env.core.ship.ship_profile` / :class:`~ihrcf_env.core.ship.ShipMotion` and
:meth:`ihrcf_env.core.stewart.StewartGeometry.leg_lengths`.

Poses are model scale: the deck offset (3,) m from its home position and its attitude (roll,
pitch, yaw) rad (intrinsic Z-Y-X); times in model seconds. The ship's random draws (the
frequencies' jitter and the phases, uniforms on [0, 1)) are inputs, so that a caller decides the
stream they come from.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.ship import BAND, ShipOptions
from ihrcf_env.fast.linalg3 import matrix_from_euler

__all__ = [
    "DeckTrack",
    "ShipConstants",
    "ShipMotion",
    "ShipPhasor",
    "deck_pose",
    "deck_track",
    "leg_lengths",
    "ship_constants",
    "ship_motion",
    "ship_phasor",
    "ship_phasor_advance",
    "ship_pose",
    "ship_pose_of_phasor",
    "sines_arrays",
    "sum_of_sines",
]


def sines_arrays(components: Any) -> tuple[Array, Array, Array]:
    """Amplitudes, frequencies (Hz) and phases (rad), each (6, K), of a sum-of-sines profile's
    ``components`` (per DOF a tuple of (amplitude, frequency_hz, phase_rad); padded with zero
    amplitudes); host-side."""
    comps = list(components) + [()] * (6 - len(components))
    k = max(1, max(len(c) for c in comps))
    out = np.zeros((3, 6, k))
    for d, dof in enumerate(comps):
        for j, c in enumerate(dof):
            out[:, d, j] = c
    return jnp.asarray(out[0]), jnp.asarray(out[1]), jnp.asarray(out[2])


def sum_of_sines(t: Array, amp: Array, freq: Array, phase: Array) -> tuple[Array, Array]:
    """(offset (3,) m, rpy (3,) rad) of the sum of sinusoids at time ``t`` (s)."""
    s = amp[:, 0] * jnp.sin(2 * math.pi * freq[:, 0] * t + phase[:, 0])
    for j in range(1, amp.shape[1]):
        s = s + amp[:, j] * jnp.sin(2 * math.pi * freq[:, j] * t + phase[:, j])
    return s[:3], s[3:]


class ShipConstants(NamedTuple):
    """A ship configuration's constants (host-side, :func:`ship_constants`): the sea's ``hs`` (m),
    ``tp`` (s), ``gamma``; the band's ``lo`` and step ``d_omega`` (rad/s); the vessel's ``length``,
    ``beam``, ``draught`` (m), periods (s) and dampings of heave, roll and pitch, its
    ``roll_slope_factor`` and ``deck`` point (3,) m; ``heading`` (rad), ``speed`` (m/s),
    ``length_scale``."""

    hs: float
    tp: float
    gamma: float
    lo: float
    d_omega: float
    length: float
    beam: float
    draught: float
    heave_period: float
    heave_damping: float
    roll_period: float
    roll_damping: float
    pitch_period: float
    pitch_damping: float
    roll_slope_factor: float
    deck: tuple[float, float, float]
    heading: float
    speed: float
    length_scale: float
    n_components: int


def ship_constants(options: ShipOptions) -> ShipConstants:
    """The :class:`ShipConstants` of a :class:`~ihrcf_env.core.ship.ShipOptions`."""
    sea, v, n = options.sea, options.ship, options.n_components
    lo, hi = BAND[0] * sea.omega_p, BAND[1] * sea.omega_p
    return ShipConstants(
        sea.hs,
        sea.tp,
        sea.gamma,
        lo,
        (hi - lo) / n,
        v.length,
        v.beam,
        v.draught,
        v.heave_period,
        v.heave_damping,
        v.roll_period,
        v.roll_damping,
        v.pitch_period,
        v.pitch_damping,
        v.roll_slope_factor,
        tuple(float(x) for x in v.deck_position),  # type: ignore[arg-type]
        float(options.wave_heading),
        float(options.speed),
        float(options.length_scale),
        int(n),
    )


class ShipMotion(NamedTuple):
    """One sea realisation: encounter frequencies ``omega_e`` (n,) rad/s (full scale) and the
    complex full-scale motion amplitudes of the centre of motion, ``re`` and ``im`` (6, n)."""

    omega_e: Array
    re: Array
    im: Array


def _jonswap(w: Array, hs: float, tp: float, gamma: float) -> Array:
    wp = 2.0 * math.pi / tp
    pos = w > 0
    ws = jnp.where(pos, w, 1.0)
    x = wp / ws
    s_pm = 5.0 / 16.0 * hs**2 * wp**4 * ws**-5 * jnp.exp(-1.25 * x**4)
    sigma = jnp.where(ws <= wp, 0.07, 0.09)
    peak = gamma ** jnp.exp(-0.5 * ((ws - wp) / (sigma * wp)) ** 2)
    return jnp.where(pos, (1.0 - 0.287 * math.log(gamma)) * s_pm * peak, 0.0)


def _g1(u: Array) -> Array:
    big = jnp.abs(u) > 1e-3
    ub = jnp.where(big, u, 1.0)
    return jnp.where(big, 3.0 * (jnp.sin(ub) - ub * jnp.cos(ub)) / ub**3, 1.0 - u**2 / 10.0)


def _sinc(x: Array) -> Array:
    """``sin(x) / x`` (1 at 0): numpy's ``sinc(x / pi)``."""
    small = x == 0.0
    xs = jnp.where(small, 1.0, x)
    return jnp.where(small, 1.0, jnp.sin(xs) / xs)


def _second_order(omega_e: Array, period: float, damping: float) -> Array:
    r = omega_e * period / (2.0 * math.pi)
    return 1.0 / (1.0 - r**2 + 2j * damping * r)


def ship_motion(u_omega: Array, u_phase: Array, c: ShipConstants) -> ShipMotion:
    """The realisation of the uniforms ``u_omega`` and ``u_phase`` (n,) on [0, 1) (the jitter of
    each component's frequency in its band slot and its phase, as :func:`ihrcf_env.core.ship.ship_profile`
    draws them)."""
    n = c.n_components
    omega = c.lo + c.d_omega * (jnp.arange(n) + u_omega)
    phase = 2 * math.pi * u_phase
    a = jnp.sqrt(2.0 * _jonswap(omega, c.hs, c.tp, c.gamma) * c.d_omega)
    k = omega**2 / GRAVITY
    ch, sh = math.cos(c.heading), math.sin(c.heading)
    kx, ky = k * ch, k * sh
    ux, uy = kx * c.length / 2, ky * c.beam / 2
    sx, sy = _sinc(ux), _sinc(uy)
    att = jnp.exp(-k * c.draught)
    att_half = jnp.exp(-k * c.draught / 2)
    omega_e = omega - k * c.speed * ch
    orbital = -1j * sx * sy * att_half
    roll_eq = -1j * ky * _g1(uy) * sx * att * c.roll_slope_factor
    pitch_eq = 1j * kx * _g1(ux) * sy * att
    L2, B2 = c.length**2, c.beam**2
    twist = (L2 * _g1(ux) * sy - B2 * _g1(uy) * sx) / (L2 + B2)
    T = jnp.stack(
        [
            ch * orbital,
            sh * orbital,
            sx * sy * att * _second_order(omega_e, c.heave_period, c.heave_damping),
            roll_eq * _second_order(omega_e, c.roll_period, c.roll_damping),
            pitch_eq * _second_order(omega_e, c.pitch_period, c.pitch_damping),
            (-k * sh * ch * twist * att_half).astype(orbital.dtype),
        ]
    )
    amps = T * (a * jnp.exp(1j * phase))
    return ShipMotion(omega_e, amps.real, amps.imag)


def ship_pose(t: Array, motion: ShipMotion, c: ShipConstants) -> tuple[Array, Array]:
    """(offset (3,) m, rpy (3,) rad) of the deck point at model time ``t`` (s)."""
    tf = t * math.sqrt(c.length_scale)
    wt = motion.omega_e * tf
    return _deck_point(jnp.sum(motion.re * jnp.cos(wt) - motion.im * jnp.sin(wt), axis=1), c)


class ShipPhasor(NamedTuple):
    """The components' phases at one time, ``cos`` and ``sin`` of ``omega_e t`` (n,) (full-scale
    time), and their rotation over one step, ``step_cos`` and ``step_sin`` (n,)."""

    cos: Array
    sin: Array
    step_cos: Array
    step_sin: Array


def ship_phasor(t: Array, dt: Array | float, motion: ShipMotion, c: ShipConstants) -> ShipPhasor:
    """The phasors at model time ``t`` (s) advancing by ``dt`` (s, model) per step: the deck pose
    at a fixed rate without a cosine and sine per component and step."""
    ts = math.sqrt(c.length_scale)
    wt = motion.omega_e * (t * ts)
    wd = motion.omega_e * (dt * ts)
    return ShipPhasor(jnp.cos(wt), jnp.sin(wt), jnp.cos(wd), jnp.sin(wd))


def ship_phasor_advance(ph: ShipPhasor) -> ShipPhasor:
    """The phasors one step later (a rotation: exact up to rounding, which grows by about one unit
    of the last place per step)."""
    c = ph.cos * ph.step_cos - ph.sin * ph.step_sin
    s = ph.sin * ph.step_cos + ph.cos * ph.step_sin
    return ph._replace(cos=c, sin=s)


def _deck_point(m: Array, c: ShipConstants) -> tuple[Array, Array]:
    rpy = m[3:]
    cr, sr = jnp.cos(rpy[0]), jnp.sin(rpy[0])
    cp, sp = jnp.cos(rpy[1]), jnp.sin(rpy[1])
    cy, sy = jnp.cos(rpy[2]), jnp.sin(rpy[2])
    x, y, z = c.deck
    y1, z1 = y * cr - z * sr, y * sr + z * cr
    x2, z2 = x * cp + z1 * sp, -x * sp + z1 * cp
    rot = jnp.stack([x2 * cy - y1 * sy, x2 * sy + y1 * cy, z2])
    return (m[:3] + rot - jnp.asarray(c.deck)) / c.length_scale, rpy


def ship_pose_of_phasor(ph: ShipPhasor, motion: ShipMotion, c: ShipConstants) -> tuple[Array, Array]:
    """(offset (3,) m, rpy (3,) rad) of the deck point at the phasors' time."""
    return _deck_point(motion.re @ ph.cos - motion.im @ ph.sin, c)


def deck_pose(offset: Array, rpy: Array, home_position: Array) -> tuple[Array, Array]:
    """The deck frame's world position (3,) and rotation (3, 3; world from deck) of a profile pose."""
    return home_position + offset, matrix_from_euler(rpy)


def leg_lengths(position: Array, rotation: Array, top_joints: Array, base_joints: Array) -> Array:
    """The six leg lengths (m) of the deck at ``position`` with ``rotation``: top joints (6, 3) in the
    deck frame, base joints (6, 3) in the world (:class:`ihrcf_env.core.stewart.StewartGeometry`)."""
    T, B = top_joints, base_joints
    d = [
        rotation[i, 0] * T[:, 0]
        + rotation[i, 1] * T[:, 1]
        + rotation[i, 2] * T[:, 2]
        + (position[i] - B[:, i])
        for i in range(3)
    ]
    return jnp.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


class DeckTrack(NamedTuple):
    """The deck at a physics tick: its frame's ``position`` (3,; world, the tag centre on the top
    face) and ``rotation`` (3, 3; world from deck), the plate's ``body`` centre (3,) and whether the
    deck has ``stalled`` (held at its last reachable pose)."""

    position: Array
    rotation: Array
    body: Array
    stalled: Array


def deck_track(
    prev: DeckTrack,
    offset: Array,
    rpy: Array,
    home_position: Array,
    top_joints: Array,
    base_joints: Array,
    min_leg: float,
    max_leg: float,
    half_thickness: float,
) -> DeckTrack:
    """The deck at the next tick for the profile's pose (``offset``, ``rpy``): that pose, or, once a
    pose leaves the legs' stroke or is not finite, the last reachable one for the rest of the
    episode (as :class:`ihrcf_env.sim.deck.DeckTrajectory` drives the platform)."""
    pos, R = deck_pose(offset, rpy, home_position)
    legs = leg_lengths(pos, R, top_joints, base_joints)
    bad = jnp.any(legs < min_leg) | jnp.any(legs > max_leg) | ~jnp.all(jnp.isfinite(legs))
    stalled = prev.stalled | bad
    new = DeckTrack(pos, R, pos - R[:, 2] * half_thickness, stalled)
    return DeckTrack(
        *(jnp.where(stalled, a, b) for a, b in zip(prev._replace(stalled=stalled), new, strict=True))
    )
