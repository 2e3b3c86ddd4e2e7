"""First contact of one drone with its scene (touchdown geometry), in closed form: the contact
PyBullet's collision detection finds in a :class:`~ihrcf_env.sim.world.World` (tested against it
in ``tests/fast/test_contact.py``).

The drone's collision shape is a set of boxes fixed in the body frame (``centres``, ``halves``
(B, 3), m; :func:`ihrcf_env.core.collision.drone_boxes`, from the drone's URDF). It touches the
deck when one of its boxes intersects the deck plate (the separating-axis test of two oriented
boxes, 15 axes), the ground when a box corner lies on or below world z = 0, the Stewart base when a
corner lies inside its cylinder. Contact codes: 0 none, 1 deck, 2 ground, 3 base (deck first when
simultaneous, then ground).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jax import Array

__all__ = ["BASE", "DECK", "GROUND", "NO_CONTACT", "box_corners", "boxes_overlap_deck", "first_contact"]

NO_CONTACT, DECK, GROUND, BASE = 0, 1, 2, 3


def box_corners(centres: np.ndarray, halves: np.ndarray) -> np.ndarray:
    """(8 B, 3) corners (body frame, m) of the boxes (host-side, in the simulator's order)."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    return (np.asarray(centres)[:, None, :] + signs[None] * np.asarray(halves)[:, None, :]).reshape(-1, 3)


def boxes_overlap_deck(
    position: Array,
    rotation: Array,
    deck_centre: Array,
    deck_rotation: Array,
    deck_half: Array,
    centres: Array,
    halves: Array,
) -> Array:
    """Whether any of the drone's boxes intersects the deck plate (centre ``deck_centre``, axes
    ``deck_rotation`` (3, 3), half extents ``deck_half`` (3,))."""
    Rm = rotation.T @ deck_rotation  # body from deck
    A = jnp.abs(Rm) + 1e-12
    d = deck_centre - position
    t = (rotation.T @ d)[None, :] - centres  # (B, 3)
    b, a, R = deck_half, halves, Rm
    separated = jnp.zeros(centres.shape[0], dtype=bool)
    for i in range(3):
        rb = b[0] * A[i, 0] + b[1] * A[i, 1] + b[2] * A[i, 2]
        separated |= jnp.abs(t[:, i]) > a[:, i] + rb
    for j in range(3):
        ra = a[:, 0] * A[0, j] + a[:, 1] * A[1, j] + a[:, 2] * A[2, j]
        tj = t[:, 0] * R[0, j] + t[:, 1] * R[1, j] + t[:, 2] * R[2, j]
        separated |= jnp.abs(tj) > ra + b[j]
    for i in range(3):
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in range(3):
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            ra = a[:, i1] * A[i2, j] + a[:, i2] * A[i1, j]
            rb = b[j1] * A[i, j2] + b[j2] * A[i, j1]
            tl = t[:, i2] * R[i1, j] - t[:, i1] * R[i2, j]
            separated |= jnp.abs(tl) > ra + rb
    return ~jnp.all(separated)


def first_contact(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    deck_half_extent: Array | float,
    deck_thickness: Array | float,
    base_radius: Array | float,
    base_height: Array | float,
    centres: Array,
    halves: Array,
    corners: Array,
) -> Array:
    """The contact code of the drone at ``position`` with ``rotation`` (world from body), the deck
    frame (top-face centre) at ``deck_position`` with ``deck_rotation``; ``deck_half_extent`` half
    the deck's side and ``deck_thickness`` the plate's, ``base_radius`` and ``base_height`` the base
    cylinder's (m); the drone's boxes ``centres``, ``halves`` and their ``corners``
    (:func:`box_corners`)."""
    c = corners
    pts = position + c[:, 0:1] * rotation[:, 0] + c[:, 1:2] * rotation[:, 1] + c[:, 2:3] * rotation[:, 2]
    half_t = 0.5 * deck_thickness
    deck_centre = deck_position - deck_rotation[:, 2] * half_t
    deck_half = jnp.stack([jnp.asarray(deck_half_extent), jnp.asarray(deck_half_extent), jnp.asarray(half_t)])
    in_deck = boxes_overlap_deck(position, rotation, deck_centre, deck_rotation, deck_half, centres, halves)
    z = pts[:, 2]
    on_ground = jnp.any(z <= 0.0)
    in_base = jnp.any((z <= base_height) & (pts[:, 0] ** 2 + pts[:, 1] ** 2 <= base_radius**2))
    out = jnp.where(in_base, BASE, NO_CONTACT)
    out = jnp.where(on_ground, GROUND, out)
    return jnp.where(in_deck, DECK, out).astype(jnp.int8)
