"""Ray casting against a world's collision scene in closed form, for N worlds at once.

The collision bodies a range sensor's ray can meet in a :class:`~ihrcf_env.sim.world.World` are the
ground plane (world z = 0), the deck plate (a box whose top face is the deck frame's z = 0 plane,
:class:`RayScene` ``deck_half_extents``), the Stewart platform's base (a cylinder of radius
``base_radius`` and height ``base_height`` standing on the ground, centred on the world origin)
and the drone's own collision boxes (:func:`~ihrcf_env.core.collision.drone_boxes`). The tag
and the legs are visual only.

The conventions are PyBullet's ``rayTestBatch``: a ray runs from ``start`` to ``start + length *
direction``; it reports the first surface it *enters* (a ray starting inside a box or the base
reports nothing of that body, one starting on a surface and pointing inwards hits it at fraction
0), the ground is hit from either side (a ray starting on it does not hit it); the normal faces
the ray; a miss has fraction 1 and a zero normal.

All functions work element-wise over the leading axes (a row's result never depends on the
other rows).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.collision import drone_boxes


@dataclass(frozen=True)
class RayScene:
    """The static geometry of a world's collision scene (m): the deck plate's half extents (x, y,
    z; the plate's centre lies ``deck_half_extents[2]`` below the deck frame's origin, along its z
    axis) and the base cylinder's radius and height."""

    deck_half_extents: tuple[float, float, float]
    base_radius: float
    base_height: float

    @classmethod
    def of(cls, deck_size: float, deck_thickness: float, base_radius: float, base_height: float) -> RayScene:
        """The scene of a deck plate ``deck_size`` x ``deck_size`` x ``deck_thickness`` and a Stewart
        base of joint radius ``base_radius`` (the base cylinder is 0.06 m wider) and ``base_height``
        (m), as :class:`~ihrcf_env.sim.deck.Deck` builds them."""
        half = deck_size / 2
        return cls((half, half, deck_thickness / 2), base_radius + 0.06, base_height)


class RayHits(NamedTuple):
    """First hits of a stack of rays: ``fraction`` (...,) of the ray's length (1 for a miss),
    ``hit`` (...,) flags and ``normal`` (..., 3) unit surface normals facing the ray (world, zeros
    for a miss)."""

    fraction: NDArray[np.float64]
    hit: NDArray[np.bool_]
    normal: NDArray[np.float64]


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row-wise dot product over the last axis (3), element-wise arithmetic."""
    out: NDArray[np.float64] = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return out


def _slab(
    s: NDArray[np.float64], d: NDArray[np.float64], half: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Entry and exit fractions of the segments ``s + f d`` (box frame) through the axis-aligned box
    of half extents ``half`` centred on the origin, and the axis of entry. Empty: entry > exit."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - s) / d
        t2 = (half - s) / d
    parallel = d == 0.0
    inside = np.abs(s) <= half
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    axis = np.argmax(lo, axis=-1)
    t_in = np.take_along_axis(lo, axis[..., None], axis=-1)[..., 0]
    t_out = np.min(hi, axis=-1)
    return t_in, t_out, axis


def _box_entry(
    s: NDArray[np.float64], d: NDArray[np.float64], half: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(fraction, normal in the box frame) of the segments' entry into the box; fraction ``inf``
    when a segment does not enter it within [0, 1]."""
    t_in, t_out, axis = _slab(s, d, half)
    ok = (t_in <= t_out) & (t_in >= 0.0) & (t_in <= 1.0)
    normal = np.zeros(s.shape)
    sign = -np.sign(np.take_along_axis(d, axis[..., None], axis=-1)[..., 0])
    np.put_along_axis(normal, axis[..., None], sign[..., None], axis=-1)
    return np.where(ok, t_in, np.inf), normal


def _cylinder_entry(
    s: NDArray[np.float64], d: NDArray[np.float64], radius: float, height: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(fraction, normal) of the segments' entry into the z-axis cylinder ``x^2 + y^2 <= radius^2``,
    ``0 <= z <= height``; fraction ``inf`` when a segment does not enter it within [0, 1]."""
    a = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]
    b = s[..., 0] * d[..., 0] + s[..., 1] * d[..., 1]
    c = s[..., 0] * s[..., 0] + s[..., 1] * s[..., 1] - radius * radius
    disc = b * b - a * c
    root = np.sqrt(np.maximum(disc, 0.0))
    vertical = a == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        side_in = np.where(vertical, np.where(c <= 0.0, -np.inf, np.inf), (-b - root) / a)
        side_out = np.where(vertical, np.where(c <= 0.0, np.inf, -np.inf), (-b + root) / a)
    side_in = np.where(disc < 0.0, np.inf, side_in)
    side_out = np.where(disc < 0.0, -np.inf, side_out)
    half_h = np.full(1, height / 2)
    z = s[..., 2:3] - height / 2
    cap_in, cap_out, _ = _slab(z, d[..., 2:3], half_h)
    t_in = np.maximum(side_in, cap_in)
    t_out = np.minimum(side_out, cap_out)
    ok = (t_in <= t_out) & (t_in >= 0.0) & (t_in <= 1.0)
    on_side = side_in >= cap_in
    t_hit = np.where(ok, t_in, 0.0)
    px = s[..., 0] + t_hit * d[..., 0]
    py = s[..., 1] + t_hit * d[..., 1]
    rho = np.sqrt(px * px + py * py)
    with np.errstate(divide="ignore", invalid="ignore"):
        side_n = np.stack([px / rho, py / rho, np.zeros_like(px)], axis=-1)
    side_n = np.where((rho > 0.0)[..., None], side_n, 0.0)
    cap_n = np.zeros(s.shape)
    cap_n[..., 2] = -np.sign(d[..., 2])
    normal = np.where((on_side & ok)[..., None], side_n, cap_n)
    return np.where(ok, t_in, np.inf), normal


def _ground_entry(
    s: NDArray[np.float64], d: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(fraction, normal) of the segments' crossing of the plane z = 0 (from either side, strictly)."""
    za, zb = s[..., 2], s[..., 2] + d[..., 2]
    cross = za * zb < 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        f = za / (za - zb)
    normal = np.zeros(s.shape)
    normal[..., 2] = np.where(za > 0.0, 1.0, -1.0)
    return np.where(cross, f, np.inf), normal


def to_local(v: NDArray[np.float64], rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    """``rotation^T v`` over the last axis: ``v`` (N, R, 3) world vectors, ``rotation`` (N, 3, 3)."""
    R = rotation[:, None]
    return np.stack([_dot(v, R[..., :, j]) for j in range(3)], axis=-1)


def to_world(v: NDArray[np.float64], rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    """``rotation v`` over the last axis: ``v`` (N, R, 3) local vectors, ``rotation`` (N, 3, 3)."""
    R = rotation[:, None]
    return np.stack([_dot(v, R[..., i, :]) for i in range(3)], axis=-1)


def cast_rays(
    starts: NDArray[np.float64],
    directions: NDArray[np.float64],
    length: float,
    deck_position: NDArray[np.float64],
    deck_rotation: NDArray[np.float64],
    scene: RayScene,
) -> RayHits:
    """First hits of the rays ``starts`` (N, R, 3) + ``f length directions`` (N, R, 3; world, unit
    vectors), f in [0, 1], against the ground, the base and the deck plate of world n at
    ``deck_position`` (N, 3; deck frame origin, world) with ``deck_rotation`` (N, 3, 3; world from
    deck). The drone's own boxes are not included (see :func:`self_hits`)."""
    d = directions * length
    fracs, normals = [], []
    f, n = _ground_entry(starts, d)
    fracs.append(f)
    normals.append(n)
    f, n = _cylinder_entry(starts, d, scene.base_radius, scene.base_height)
    fracs.append(f)
    normals.append(n)
    half = np.asarray(scene.deck_half_extents, dtype=np.float64)
    s_loc = to_local(starts - deck_position[:, None, :], deck_rotation)
    s_loc[..., 2] += half[2]
    f, n = _box_entry(s_loc, to_local(d, deck_rotation), half)
    fracs.append(f)
    normals.append(to_world(n, deck_rotation))
    return nearest(np.stack(fracs, axis=-1), np.stack(normals, axis=-2))


def nearest(fractions: NDArray[np.float64], normals: NDArray[np.float64]) -> RayHits:
    """The first of several candidate hits: ``fractions`` (..., K; ``inf`` for none) and their
    ``normals`` (..., K, 3)."""
    k = np.argmin(fractions, axis=-1)
    f = np.take_along_axis(fractions, k[..., None], axis=-1)[..., 0]
    n = np.take_along_axis(normals, k[..., None, None], axis=-2)[..., 0, :]
    hit = np.isfinite(f)
    return RayHits(np.where(hit, f, 1.0), hit, np.where(hit[..., None], n, 0.0))


def self_hits(
    starts_body: NDArray[np.float64], directions_body: NDArray[np.float64], length: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(fraction (R,), normal (R, 3), body frame) of rays fixed in the drone's body frame against its
    own collision boxes (``inf`` where a ray meets none): a constant of the sensor's mounting."""
    centres, halves = drone_boxes()
    s = starts_body[:, None, :] - centres[None]  # (R, B, 3)
    d = np.broadcast_to((directions_body * length)[:, None, :], s.shape)
    f, n = _box_entry(s, d, np.broadcast_to(halves[None], s.shape))
    k = np.argmin(f, axis=1)
    return f[np.arange(len(f)), k], n[np.arange(len(f)), k]


__all__ = [
    "RayHits",
    "RayScene",
    "cast_rays",
    "nearest",
    "self_hits",
    "to_local",
    "to_world",
]
