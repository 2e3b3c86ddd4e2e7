"""Ground effect: the extra thrust of a rotor close to the surface below it.

Per rotor, the in-ground-effect to out-of-ground-effect thrust ratio at equal rotor speed is
Cheeseman & Bennett's image-method result ("The effect of the ground on a helicopter rotor in
forward flight", ARC R&M 3021, 1957), in hover::

    T_IGE / T_OGE = 1 / (1 - (R / (4 z))^2)

with ``R`` the rotor radius and ``z`` the rotor's height above the surface. Sanchez-Cuevas, Heredia
& Ollero ("Characterization of the aerodynamic ground effect and its influence in multirotor
control", Int. J. Aerospace Eng. 2017, 1823056) measured it on single rotors and multirotors: the
single-rotor formula holds for ``z / R`` above about 0.5 and a multirotor gains somewhat more (the
neighbouring rotors' and the body's images), which is not modelled here.

The height is taken *per rotor above the surface under it*, not from the world ground: a rotor
whose vertical projection falls on the deck's top face feels the deck (``z`` = its distance to the
deck plane along the deck normal: the image of the method of images is mirrored across that plane,
so a tilted deck is handled), one outside it feels the ground plane. Near the deck's edge the two
are blended by the fraction of the rotor disc over the deck, approximated from the distance of the
rotor centre to the edge (linear over one rotor radius either side), so the thrust never jumps.
Below ``min_height_ratio * R`` the height is held at that value (the formula diverges at
``z = R / 4``; see :func:`cheeseman_bennett`). The rotor's own tilt relative to the surface and the
Stewart platform's base are ignored.
"""

from __future__ import annotations

from collections.abc import Sequence

import pybullet as p

from ihrcf_env.core.checks import check_positive, check_real

#: Default lower bound of the height (in rotor radii) at which the formula is evaluated.
MIN_HEIGHT_RATIO = 0.5


def cheeseman_bennett(height: float, radius: float, min_height_ratio: float = MIN_HEIGHT_RATIO) -> float:
    """``T_IGE / T_OGE = 1 / (1 - (R / (4 z))^2)`` for a rotor of radius ``radius`` (m) at
    ``height`` (m) above a surface; the height is first raised to ``min_height_ratio * radius``
    (default 0.5 R: the model's range of validity, ratio 4/3 there), so any height (even negative,
    a rotor below the surface's plane) gives a finite ratio >= 1."""
    z = max(height, min_height_ratio * radius)
    q = radius / (4.0 * z)
    return 1.0 / (1.0 - q * q)


class GroundEffect:
    """Per-rotor ground-effect thrust ratios over a square deck and the ground plane.

    ``rotor_radius`` (m); ``ground_height`` (m), the world height of the ground plane;
    ``min_height_ratio`` see :func:`cheeseman_bennett` (at least 0.3: the formula's pole is at 0.25).
    """

    def __init__(
        self, rotor_radius: float, ground_height: float = 0.0, min_height_ratio: float = MIN_HEIGHT_RATIO
    ) -> None:
        self.rotor_radius = check_positive("rotor_radius", rotor_radius, "m", high=5.0)
        self.ground_height = check_real("ground_height", ground_height, "m", low=-1e4, high=1e4)
        self.min_height_ratio = check_real("min_height_ratio", min_height_ratio, "", low=0.3, high=100.0)

    def ratio(self, height: float) -> float:
        """:func:`cheeseman_bennett` with this model's radius and height floor."""
        return cheeseman_bennett(height, self.rotor_radius, self.min_height_ratio)

    def thrust_scale(
        self,
        rotors: Sequence[Sequence[float]],
        deck_position: Sequence[float],
        deck_rotation: Sequence[Sequence[float]] | Sequence[float],
        deck_half_extent: float,
    ) -> list[float]:
        """Thrust ratio of each rotor (a list, one per rotor).

        Args:
            rotors: rotor hub positions (world, m), e.g. from :func:`rotor_positions`.
            deck_position: a point of the deck's top face (world, m), the deck frame origin.
            deck_rotation: the deck frame's rotation (world from deck; column 2 the normal of the
                top face), as 3 rows of 3 or as 9 numbers row-major (as
                ``pybullet.getMatrixFromQuaternion`` gives it).
            deck_half_extent: half the side of the deck's square top face (m).

        Scalar maths: this runs at the physics rate.
        """
        cx, cy, cz = deck_position
        if len(deck_rotation) == 3:
            (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = deck_rotation  # type: ignore[misc]
        else:
            a00, a01, a02, a10, a11, a12, a20, a21, a22 = deck_rotation
        r, half, ground = self.rotor_radius, float(deck_half_extent), self.ground_height
        q4, z_min = 0.25 * r, self.min_height_ratio * r
        inv_2r = 0.5 / r
        out = []
        for px, py, pz in rotors:
            q = q4 / max(pz - ground, z_min)
            ground_ratio = 1.0 / (1.0 - q * q)
            # distance to the deck plane along its normal (column 2)
            dx, dy, dz = px - cx, py - cy, pz - cz
            h = dx * a02 + dy * a12 + dz * a22
            if h <= 0.0 or a22 <= 0.0:  # below the deck's top plane: the deck is not under it
                out.append(ground_ratio)
                continue
            # the point vertically below the rotor on the deck plane, in deck coordinates
            qz = dz - h / a22
            u = dx * a00 + dy * a10 + qz * a20
            v = dx * a01 + dy * a11 + qz * a21
            cover = 0.5 + (half - max(abs(u), abs(v))) * inv_2r  # fraction of the disc over the deck
            if cover <= 0.0:
                out.append(ground_ratio)
                continue
            q = q4 / max(h, z_min)
            deck_ratio = 1.0 / (1.0 - q * q)
            out.append(deck_ratio if cover >= 1.0 else cover * deck_ratio + (1.0 - cover) * ground_ratio)
        return out


def deck_surface(
    body_position: Sequence[float], body_quaternion: Sequence[float], half_thickness: float
) -> tuple[tuple[float, float, float], tuple[float, ...]]:
    """The deck's top face from its plate body's PyBullet pose: ``(point, rotation)``, the centre of
    the top face (world, m) and the rotation as 9 numbers row-major, for
    :meth:`GroundEffect.thrust_scale` (scalar maths, unlike ``Deck.pose``)."""
    rot = p.getMatrixFromQuaternion(body_quaternion)
    bx, by, bz = body_position
    t = half_thickness
    return (bx + rot[2] * t, by + rot[5] * t, bz + rot[8] * t), rot


def rotor_positions(
    position: Sequence[float], rotation: Sequence[float], motor_xy: Sequence[Sequence[float]]
) -> list[tuple[float, float, float]]:
    """World positions (m) of the rotor hubs at body ``(x, y, 0)`` for each ``motor_xy`` row (m),
    for the body at ``position`` (m) with ``rotation`` given row-major as 9 numbers (world from
    body, as ``pybullet.getMatrixFromQuaternion`` returns it)."""
    r00, r01, _, r10, r11, _, r20, r21, _ = rotation
    px, py, pz = position
    return [(px + r00 * x + r01 * y, py + r10 * x + r11 * y, pz + r20 * x + r21 * y) for x, y in motor_xy]


__all__ = [
    "MIN_HEIGHT_RATIO",
    "GroundEffect",
    "cheeseman_bennett",
    "deck_surface",
    "rotor_positions",
]
