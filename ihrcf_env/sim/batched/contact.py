"""First contact of N drones with their scene, in closed form (the numpy physics backend).

The scene of a :class:`~ihrcf_env.sim.world.World` has three collision bodies: the ground plane
(world z = 0), the Stewart platform's base (a static cylinder on the ground, centred on the world
origin) and the deck plate (a box whose top face is the deck frame's z = 0 plane). The drone's
collision shape is the boxes of ``quadrotor.urdf`` (body, four landing legs). A drone touches a
body when one of its boxes intersects the deck plate (the separating-axis test of two oriented
boxes), or when a corner of one of its boxes lies on or below the ground or inside the base
cylinder; :func:`drone_boxes` gives the boxes in the body frame (FLU, m).

All functions work on stacks over N drones, row by row (a row's result never depends on the
other rows).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.collision import drone_boxes

#: Contact codes of :func:`first_contact`, in the order a simultaneous contact reports them.
NO_CONTACT, DECK, GROUND, BASE = 0, 1, 2, 3
#: Names of the codes (index = code) as :class:`~ihrcf_env.sim.world.Touchdown` gives them.
CONTACT_NAMES = ("", "deck", "ground", "base")


@functools.lru_cache(maxsize=1)
def drone_corners() -> NDArray[np.float64]:
    """(8 B, 3) corners (body frame, m) of :func:`drone_boxes` (read-only)."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    c, h = drone_boxes()
    out = (c[:, None, :] + signs[None] * h[:, None, :]).reshape(-1, 3)
    out.flags.writeable = False
    return out


def boxes_overlap_deck(
    position: NDArray[np.float64],
    rotation: NDArray[np.float64],
    deck_centre: NDArray[np.float64],
    deck_rotation: NDArray[np.float64],
    deck_half: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """(N,) whether any of the drone's boxes intersects the deck plate (a box with centre
    ``deck_centre`` (N, 3), axes ``deck_rotation`` (N, 3, 3) and half extents ``deck_half`` (3,)):
    the separating-axis test of two oriented boxes (15 axes)."""
    c, a = drone_boxes()  # (B, 3) in the body frame; the boxes' axes are the body's
    Rm = np.matmul(np.swapaxes(rotation, 1, 2), deck_rotation)  # (N, 3, 3): body from deck
    absR = np.abs(Rm) + 1e-12
    # the deck centre relative to each box centre, in body axes
    d = deck_centre - position  # (N, 3) world
    t = np.matmul(np.swapaxes(rotation, 1, 2), d[:, :, None])[:, None, :, 0] - c[None]  # (N, B, 3)
    b = np.asarray(deck_half, dtype=np.float64)
    A = absR[:, None]  # (N, 1, 3, 3)
    R = Rm[:, None]
    aa = a[None]  # (1, B, 3)
    separated = np.zeros(t.shape[:2], dtype=bool)
    for i in range(3):
        rb = b[0] * A[..., i, 0] + b[1] * A[..., i, 1] + b[2] * A[..., i, 2]
        separated |= np.abs(t[..., i]) > aa[..., i] + rb
    for j in range(3):
        ra = aa[..., 0] * A[..., 0, j] + aa[..., 1] * A[..., 1, j] + aa[..., 2] * A[..., 2, j]
        tj = t[..., 0] * R[..., 0, j] + t[..., 1] * R[..., 1, j] + t[..., 2] * R[..., 2, j]
        separated |= np.abs(tj) > ra + b[j]
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            ra = aa[..., i1] * A[..., i2, j] + aa[..., i2] * A[..., i1, j]
            rb = b[j1] * A[..., i, j2] + b[j2] * A[..., i, j1]
            tl = t[..., i2] * R[..., i1, j] - t[..., i1] * R[..., i2, j]
            separated |= np.abs(tl) > ra + rb
    out: NDArray[np.bool_] = np.logical_not(separated.all(axis=1))
    return out


@functools.lru_cache(maxsize=1)
def drone_radius() -> float:
    """Radius (m) of the sphere about the body origin that holds every collision box (a margin
    added): no contact is possible while it stays clear of a surface."""
    return float(np.linalg.norm(drone_corners(), axis=1).max()) + 0.01


def corners_world(position: NDArray[np.float64], rotation: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, K, 3) world positions (m) of the drones' collision corners, for drones at ``position``
    (N, 3) with ``rotation`` (N, 3, 3), world from body."""
    c = drone_corners()
    # element-wise sums (no BLAS): each row's rounding is independent of N
    return (
        position[:, None, :]
        + c[None, :, 0:1] * rotation[:, None, :, 0]
        + c[None, :, 1:2] * rotation[:, None, :, 1]
        + c[None, :, 2:3] * rotation[:, None, :, 2]
    )


def first_contact(
    position: NDArray[np.float64],
    rotation: NDArray[np.float64],
    deck_position: NDArray[np.float64],
    deck_rotation: NDArray[np.float64],
    deck_half_extent: float,
    deck_thickness: float,
    base_radius: float,
    base_height: float,
) -> NDArray[np.int8]:
    """Contact code (:data:`DECK`, :data:`GROUND`, :data:`BASE` or :data:`NO_CONTACT`) of each drone.

    Args:
        position, rotation: the drones' poses, (N, 3) m and (N, 3, 3) world from body.
        deck_position, deck_rotation: the deck frames (top face centre, world from deck), (N, 3) m
            and (N, 3, 3).
        deck_half_extent: half the side of the square deck (m); deck_thickness: the plate's (m).
        base_radius, base_height: the base cylinder's (m; its bottom on the ground).
    """
    pts = corners_world(position, rotation)  # (N, K, 3)
    half_t = 0.5 * float(deck_thickness)
    deck_centre = deck_position - deck_rotation[:, :, 2] * half_t
    deck_half = np.array([float(deck_half_extent), float(deck_half_extent), half_t])
    in_deck = boxes_overlap_deck(position, rotation, deck_centre, deck_rotation, deck_half)
    z = pts[..., 2]
    on_ground = z <= 0.0
    in_base = (z <= float(base_height)) & (pts[..., 0] ** 2 + pts[..., 1] ** 2 <= float(base_radius) ** 2)
    out = np.full(len(position), NO_CONTACT, dtype=np.int8)
    out[in_base.any(axis=1)] = BASE
    out[on_ground.any(axis=1)] = GROUND
    out[in_deck] = DECK
    return out


__all__ = [
    "CONTACT_NAMES",
    "boxes_overlap_deck",
    "corners_world",
    "drone_corners",
    "drone_radius",
    "first_contact",
]
