"""Points of the deck (the tag's corners, its quiet zone, its centre) through the downward camera:
the projection of :class:`ihrcf_env.sim.sensors.closed_form_camera.ClosedFormTagCamera` (and
:func:`ihrcf_env.core.detector_model.features.project_points`) for one environment.

Frames: world (z up), body (world from body ``R_wb``), deck (world from deck ``R_wd``, origin at the
tag centre on the top face), camera (OpenCV: x right, y down, z along the optical axis; body from
camera ``R_BODY_CAM``). Units: m, px.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
from jax import Array

from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.fast.linalg3 import dot, matmul, matvec

__all__ = ["TagView", "camera_points", "project", "tag_view"]


def camera_points(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    points_deck: Array,
    camera_offset: Array,
) -> tuple[Array, Array, Array]:
    """Camera-frame points (M, 3) of deck-frame ``points_deck`` (M, 3) for the drone at ``position``
    (3,) with ``rotation`` (3, 3; world from body) and the deck at ``deck_position`` with
    ``deck_rotation``; ``camera_offset`` (3,) is the camera's position on the body. Also returns the
    optical centre (3,) and ``R_wc`` (3, 3; world from camera), world frame."""
    eye = position + matvec(rotation, camera_offset)
    R_wc = matmul(rotation, jnp.asarray(R_BODY_CAM, dtype=rotation.dtype))
    pts_w = deck_position + jnp.stack([dot(points_deck, deck_rotation[i]) for i in range(3)], axis=-1)
    rel = pts_w - eye
    P = jnp.stack([dot(rel, R_wc[:, j]) for j in range(3)], axis=-1)
    return P, eye, R_wc


def project(P: Array, K: Array, distortion: Array) -> Array:
    """Pixels (M, 2) (OpenCV pixel centres) of camera-frame points ``P`` (M, 3) through ``K`` (3, 3)
    and radial distortion ``(k1, k2)``: ``x_d = x (1 + k1 r^2 + k2 r^4)``."""
    x = P[:, 0] / P[:, 2]
    y = P[:, 1] / P[:, 2]
    k1, k2 = distortion[0], distortion[1]
    r2 = x * x + y * y
    s = 1.0 + k1 * r2 + k2 * r2 * r2
    x, y = x * s, y * s
    return jnp.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], axis=-1)


class TagView(NamedTuple):
    """The tag as the camera sees it: ``pixels`` (4, 2) of its corners and ``quiet`` (4, 2) of its
    quiet zone's corners (px), ``points`` (9, 3) camera frame (corners, quiet corners, centre; m),
    ``in_range`` (all eight corners beyond the near plane, the tag's corners within the far one),
    ``cos_view`` (cosine between the deck normal and the line of sight to the centre), ``eye``
    (3,) the optical centre (world, m)."""

    pixels: Array
    quiet: Array
    points: Array
    in_range: Array
    cos_view: Array
    eye: Array


def tag_view(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    points_deck: Array,
    camera_offset: Array,
    K: Array,
    distortion: Array,
    near: float,
    far: float,
) -> TagView:
    """The tag's view (:class:`TagView`) for ``points_deck`` (9, 3): the four tag corners, the four
    quiet-zone corners and the tag centre in the deck frame (the order of the closed-form camera)."""
    P, eye, R_wc = camera_points(position, rotation, deck_position, deck_rotation, points_deck, camera_offset)
    z = P[:8, 2]
    in_range = ~((jnp.min(z) <= near) | (jnp.max(z[:4]) >= far))
    px = project(P[:8], K, distortion)
    centre = P[8]
    n_c = jnp.stack([dot(deck_rotation[:, 2], R_wc[:, j]) for j in range(3)])
    cos_view = jnp.abs(dot(n_c, centre)) / jnp.sqrt(dot(centre, centre))
    return TagView(px[:4], px[4:], P, in_range, cos_view, eye)
