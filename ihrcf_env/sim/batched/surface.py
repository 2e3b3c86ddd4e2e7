"""Ground effect over N drones: :meth:`GroundEffect.thrust_scale` on stacks of rotors.

The same model and the same floating-point operations as the scalar
:meth:`~ihrcf_env.sim.ground_effect.GroundEffect.thrust_scale` (per rotor, the deck under it or
the ground, blended near the deck's edge), evaluated element-wise on arrays so a row never depends
on the other rows.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.ground_effect import GroundEffect


def rotor_positions_batch(
    position: NDArray[np.float64], rotation: NDArray[np.float64], motor_xy: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N, 4, 3) world rotor hub positions (m) at body ``(x, y, 0)`` for each ``motor_xy`` row (m)
    of drones at ``position`` (N, 3) with ``rotation`` (N, 3, 3), world from body."""
    x = motor_xy[None, :, 0]
    y = motor_xy[None, :, 1]
    return np.stack(
        [
            position[:, None, 0] + rotation[:, None, 0, 0] * x + rotation[:, None, 0, 1] * y,
            position[:, None, 1] + rotation[:, None, 1, 0] * x + rotation[:, None, 1, 1] * y,
            position[:, None, 2] + rotation[:, None, 2, 0] * x + rotation[:, None, 2, 1] * y,
        ],
        axis=-1,
    )


def thrust_scale_batch(
    model: GroundEffect,
    rotors: NDArray[np.float64],
    deck_position: NDArray[np.float64],
    deck_rotation: NDArray[np.float64],
    deck_half_extent: float,
) -> NDArray[np.float64]:
    """(N, R) thrust ratios of ``rotors`` (N, R, 3) (world, m) over decks whose top-face centres are
    ``deck_position`` (N, 3) with ``deck_rotation`` (N, 3, 3) (world from deck), and the ground."""
    r, half, ground = model.rotor_radius, float(deck_half_extent), model.ground_height
    q4, z_min = 0.25 * r, model.min_height_ratio * r
    inv_2r = 0.5 / r
    px, py, pz = rotors[..., 0], rotors[..., 1], rotors[..., 2]
    q = q4 / np.maximum(pz - ground, z_min)
    ground_ratio = 1.0 / (1.0 - q * q)
    a = deck_rotation[:, None]  # (N, 1, 3, 3)
    dx = px - deck_position[:, None, 0]
    dy = py - deck_position[:, None, 1]
    dz = pz - deck_position[:, None, 2]
    h = dx * a[..., 0, 2] + dy * a[..., 1, 2] + dz * a[..., 2, 2]
    a22 = a[..., 2, 2]
    over = (h > 0.0) & (a22 > 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        qz = dz - h / a22
    u = dx * a[..., 0, 0] + dy * a[..., 1, 0] + qz * a[..., 2, 0]
    v = dx * a[..., 0, 1] + dy * a[..., 1, 1] + qz * a[..., 2, 1]
    cover = 0.5 + (half - np.maximum(np.abs(u), np.abs(v))) * inv_2r
    q = q4 / np.maximum(h, z_min)
    deck_ratio = 1.0 / (1.0 - q * q)
    blend = cover * deck_ratio + (1.0 - cover) * ground_ratio
    out = np.where(cover >= 1.0, deck_ratio, blend)
    return np.where(over & (cover > 0.0), out, ground_ratio)


__all__ = [
    "rotor_positions_batch",
    "thrust_scale_batch",
]
