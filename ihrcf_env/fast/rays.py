"""Range beams against the collision scene in closed form, for one environment: the port of
:func:`ihrcf_env.sim.sensors.rays.cast_rays` and
:meth:`ihrcf_env.sim.sensors.ranging.ClosedFormToF.true_ranges`.

The scene: the ground plane (world z = 0, hit from either side, a ray starting on it does not hit
it), the Stewart base (a z-axis cylinder of ``base_radius`` and ``base_height`` on the ground at the
world origin) and the deck plate (a box of ``half_extents`` whose top face is the deck frame's z = 0
plane). A ray runs from ``start`` to ``start + length * direction`` and reports the first surface it
enters (PyBullet's ``rayTestBatch`` conventions); a miss has fraction 1 and a zero normal. Units: m.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.fast.linalg3 import matvec, tmatvec

__all__ = ["RayHits", "Scene", "body_hits", "cast_rays", "own_fraction", "true_ranges"]


class Scene(NamedTuple):
    """The static collision scene: deck plate ``half_extents`` (3,), base cylinder ``base_radius``
    and ``base_height`` (m), as :class:`ihrcf_env.sim.sensors.rays.RayScene`."""

    half_extents: Array
    base_radius: Array
    base_height: Array


class RayHits(NamedTuple):
    """First hits: ``fraction`` (R,) of the ray's length (1 for a miss), ``hit`` (R,), ``normal``
    (R, 3) unit surface normal facing the ray (world; zeros for a miss)."""

    fraction: Array
    hit: Array
    normal: Array


def _slab(s: Array, d: Array, half: Array) -> tuple[Array, Array, Array]:
    """Entry and exit fractions of ``s + f d`` (R, k) through the box ``|x| <= half`` (k,), and the
    axis of entry (R,); empty when entry > exit."""
    parallel = d == 0.0
    dd = jnp.where(parallel, 1.0, d)
    t1 = (-half - s) / dd
    t2 = (half - s) / dd
    inside = jnp.abs(s) <= half
    lo = jnp.where(parallel, jnp.where(inside, -jnp.inf, jnp.inf), jnp.minimum(t1, t2))
    hi = jnp.where(parallel, jnp.where(inside, jnp.inf, -jnp.inf), jnp.maximum(t1, t2))
    axis = jnp.argmax(lo, axis=-1)
    t_in = jnp.take_along_axis(lo, axis[..., None], axis=-1)[..., 0]
    return t_in, jnp.min(hi, axis=-1), axis


def _box_entry(s: Array, d: Array, half: Array) -> tuple[Array, Array]:
    """(fraction (R,), box-frame normal (R, 3)) of the segments' entry into the box (``inf``: none)."""
    t_in, t_out, axis = _slab(s, d, half)
    ok = (t_in <= t_out) & (t_in >= 0.0) & (t_in <= 1.0)
    d_axis = jnp.take_along_axis(d, axis[..., None], axis=-1)[..., 0]
    onehot = axis[..., None] == jnp.arange(3)
    normal = jnp.where(onehot, -jnp.sign(d_axis)[..., None], 0.0)
    return jnp.where(ok, t_in, jnp.inf), normal


def _cylinder_entry(s: Array, d: Array, radius: Array, height: Array) -> tuple[Array, Array]:
    """(fraction, normal) of the segments' entry into ``x^2 + y^2 <= radius^2``, ``0 <= z <= height``."""
    a = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    b = s[:, 0] * d[:, 0] + s[:, 1] * d[:, 1]
    c = s[:, 0] * s[:, 0] + s[:, 1] * s[:, 1] - radius * radius
    disc = b * b - a * c
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    vertical = a == 0.0
    aa = jnp.where(vertical, 1.0, a)
    side_in = jnp.where(vertical, jnp.where(c <= 0.0, -jnp.inf, jnp.inf), (-b - root) / aa)
    side_out = jnp.where(vertical, jnp.where(c <= 0.0, jnp.inf, -jnp.inf), (-b + root) / aa)
    side_in = jnp.where(disc < 0.0, jnp.inf, side_in)
    side_out = jnp.where(disc < 0.0, -jnp.inf, side_out)
    z = s[:, 2:3] - height / 2
    cap_in, cap_out, _ = _slab(z, d[:, 2:3], jnp.reshape(height / 2, (1,)))
    t_in = jnp.maximum(side_in, cap_in)
    t_out = jnp.minimum(side_out, cap_out)
    ok = (t_in <= t_out) & (t_in >= 0.0) & (t_in <= 1.0)
    on_side = side_in >= cap_in
    t_hit = jnp.where(ok, t_in, 0.0)
    px = s[:, 0] + t_hit * d[:, 0]
    py = s[:, 1] + t_hit * d[:, 1]
    rho = jnp.sqrt(px * px + py * py)
    rr = jnp.where(rho > 0.0, rho, 1.0)
    side_n = jnp.stack([px / rr, py / rr, jnp.zeros_like(px)], axis=-1)
    side_n = jnp.where((rho > 0.0)[:, None], side_n, 0.0)
    zero = jnp.zeros_like(px)
    cap_n = jnp.stack([zero, zero, -jnp.sign(d[:, 2])], axis=-1)
    normal = jnp.where((on_side & ok)[:, None], side_n, cap_n)
    return jnp.where(ok, t_in, jnp.inf), normal


def _ground_entry(s: Array, d: Array) -> tuple[Array, Array]:
    """(fraction, normal) of the segments' strict crossing of the plane z = 0."""
    za, zb = s[:, 2], s[:, 2] + d[:, 2]
    cross = za * zb < 0.0
    f = za / jnp.where(cross, za - zb, 1.0)
    zero = jnp.zeros_like(za)
    normal = jnp.stack([zero, zero, jnp.where(za > 0.0, 1.0, -1.0)], axis=-1)
    return jnp.where(cross, f, jnp.inf), normal


def _nearest(fractions: Array, normals: Array) -> RayHits:
    """The first of K candidate hits: ``fractions`` (R, K; ``inf`` for none), ``normals`` (R, K, 3)."""
    k = jnp.argmin(fractions, axis=-1)
    f = jnp.take_along_axis(fractions, k[:, None], axis=-1)[:, 0]
    n = jnp.take_along_axis(normals, k[:, None, None], axis=-2)[:, 0, :]
    hit = jnp.isfinite(f)
    return RayHits(jnp.where(hit, f, 1.0), hit, jnp.where(hit[:, None], n, 0.0))


def cast_rays(
    starts: Array,
    directions: Array,
    length: Array | float,
    deck_position: Array,
    deck_rotation: Array,
    scene: Scene,
) -> RayHits:
    """First hits of the rays ``starts`` (R, 3) + ``f length directions`` (R, 3; world, unit), f in
    [0, 1], against the ground, the base and the deck plate at ``deck_position`` (3,) with
    ``deck_rotation`` (3, 3; world from deck). The drone's own boxes are not included."""
    d = directions * length
    f_g, n_g = _ground_entry(starts, d)
    f_c, n_c = _cylinder_entry(starts, d, scene.base_radius, scene.base_height)
    half = scene.half_extents
    s_loc = tmatvec(deck_rotation, starts - deck_position)
    s_loc = s_loc.at[:, 2].add(half[2])
    f_b, n_b = _box_entry(s_loc, tmatvec(deck_rotation, d), half)
    n_b = matvec(deck_rotation, n_b)
    return _nearest(jnp.stack([f_g, f_c, f_b], axis=-1), jnp.stack([n_g, n_c, n_b], axis=-2))


def body_hits(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    starts_body: Array,
    directions_body: Array,
    max_range: Array | float,
    scene: Scene,
    self_fraction: Array | None = None,
    self_normal: Array | None = None,
) -> tuple[RayHits, Array]:
    """Hits of rays fixed in the body frame (``starts_body``, ``directions_body`` (R, 3)) of the
    drone at ``position`` with ``rotation`` (world from body), up to ``max_range``, and the rays'
    world directions (R, 3). ``self_fraction`` (R,) (``inf``: none) and ``self_normal`` (R, 3,
    body frame) are the rays' hits on the drone's own boxes (a constant of the mounting)."""
    starts = matvec(rotation, starts_body) + position
    dirs = matvec(rotation, directions_body)
    h = cast_rays(starts, dirs, max_range, deck_position, deck_rotation, scene)
    if self_fraction is not None:
        own_n = jnp.zeros_like(dirs) if self_normal is None else matvec(rotation, self_normal)
        fr = jnp.stack([jnp.where(h.hit, h.fraction, jnp.inf), self_fraction], axis=-1)
        h = _nearest(fr, jnp.stack([h.normal, own_n], axis=-2))
    return h, dirs


def true_ranges(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    starts_body: Array,
    directions_body: Array,
    max_range: Array | float,
    scene: Scene,
    self_fraction: Array | None = None,
    self_normal: Array | None = None,
) -> tuple[Array, Array]:
    """(ranges (R,) m, hit flags (R,)) of beams fixed in the body frame (``starts_body``,
    ``directions_body`` (R, 3)) of the drone at ``position`` with ``rotation`` (world from body);
    a miss reads ``max_range``. ``self_fraction`` (R,) (``inf``: none) and ``self_normal`` (R, 3,
    body frame) are the beams' hits on the drone's own boxes (a constant of the mounting)."""
    h, _ = body_hits(
        position,
        rotation,
        deck_position,
        deck_rotation,
        starts_body,
        directions_body,
        max_range,
        scene,
        self_fraction,
        self_normal,
    )
    return jnp.where(h.hit, h.fraction * max_range, max_range), h.hit


def own_fraction(starts_body: Array, segments_body: Array, centres: np.ndarray, halves: np.ndarray) -> Array:
    """(R,) fraction at which each segment ``starts_body + f segments_body`` (R, 3; body frame)
    enters the drone's own collision boxes (``centres``, ``halves`` (B, 3), body frame; host-side
    constants), ``inf`` where it enters none."""
    f = jnp.full(starts_body.shape[:1], jnp.inf, dtype=starts_body.dtype)
    for c, h in zip(np.asarray(centres), np.asarray(halves), strict=True):
        fb, _ = _box_entry(starts_body - jnp.asarray(c), segments_body, jnp.asarray(h))
        f = jnp.minimum(f, fb)
    return f
