"""Stewart-platform (6-UPS) geometry and inverse kinematics (pure numpy).

The base joints lie on a circle of radius ``base_radius`` in the base plane (world z =
``base_height``), grouped in three pairs centred at 0, 120 and 240 degrees and separated by
``base_pair_angle``. The top (platform) joints lie on a circle of radius ``top_radius`` in the
platform frame, ``joint_depth`` below the deck's top surface, in pairs centred at 60, 180 and
300 degrees. Leg i joins base joint i to the nearest top joint of the neighbouring pair, the
classic zig-zag layout. Leg length = distance between its two joints.

The platform pose is that of the **deck frame** (origin at the tag centre on the top surface, see
``ihrcf_env.core.frames``) in the world.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class StewartGeometry:
    """6-UPS geometry. Lengths in metres, angles in radians, world frame z up.

    ``home_height`` is the world height of the deck's top surface at the neutral pose
    (deck centred above the base, level, zero yaw). Leg stroke: lengths must stay within
    ``[min_leg, max_leg]``; by default the neutral length +- ``stroke / 2``.
    """

    base_radius: float = 0.55
    top_radius: float = 0.32
    base_pair_angle: float = math.radians(20.0)
    top_pair_angle: float = math.radians(20.0)
    base_height: float = 0.08
    home_height: float = 0.85
    joint_depth: float = 0.06
    stroke: float = 0.30

    def __post_init__(self) -> None:
        for name in ("base_radius", "top_radius", "home_height", "stroke"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"StewartGeometry.{name} must be positive, got {v!r}")
        if self.home_height - self.joint_depth <= self.base_height:
            raise ValueError("StewartGeometry.home_height puts the top joints below the base joints")

    @functools.cached_property
    def base_joints(self) -> NDArray[np.float64]:
        """(6, 3) base joint positions in the world frame (m; computed once, read-only)."""
        ang = []
        for c in (0.0, 120.0, 240.0):
            ang += [math.radians(c) - self.base_pair_angle / 2, math.radians(c) + self.base_pair_angle / 2]
        a = np.array(ang)
        out = np.column_stack(
            [self.base_radius * np.cos(a), self.base_radius * np.sin(a), np.full(6, self.base_height)]
        )
        out.setflags(write=False)
        return out

    @functools.cached_property
    def top_joints(self) -> NDArray[np.float64]:
        """(6, 3) top joint positions in the deck frame (m), ordered so leg i joins base joint i
        (computed once, read-only)."""
        h = self.top_pair_angle / 2
        ang = np.radians([-60.0, 60.0, 60.0, 180.0, 180.0, 300.0]) + np.array([h, -h, h, -h, h, -h])
        out = np.column_stack(
            [self.top_radius * np.cos(ang), self.top_radius * np.sin(ang), np.full(6, -self.joint_depth)]
        )
        out.setflags(write=False)
        return out

    @property
    def home_position(self) -> NDArray[np.float64]:
        """World position of the deck frame at the neutral pose (m)."""
        return np.array([0.0, 0.0, self.home_height])

    @property
    def neutral_lengths(self) -> NDArray[np.float64]:
        return self.leg_lengths(self.home_position, np.eye(3))

    @property
    def min_leg(self) -> float:
        return float(self.neutral_lengths.min() - self.stroke / 2)

    @property
    def max_leg(self) -> float:
        return float(self.neutral_lengths.max() + self.stroke / 2)

    def leg_lengths(self, position: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
        """Inverse kinematics: the six leg lengths (m) for a deck pose.

        ``position`` (..., 3) is the deck frame origin in the world, ``rotation`` (..., 3, 3) the
        deck orientation; leading dimensions broadcast, giving (..., 6).
        """
        p = np.asarray(position, dtype=np.float64)
        R = np.asarray(rotation, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"position must have shape (..., 3), got {p.shape}")
        if R.shape[-2:] != (3, 3):
            raise ValueError(f"rotation must have shape (..., 3, 3), got {R.shape}")
        T, B = self.top_joints, self.base_joints
        if R.ndim == 2 and p.ndim == 1:  # one pose: a matrix product costs less than the sums below
            leg = T @ R.T + (p - B)
            return np.sqrt(np.add.reduce(leg * leg, axis=1))
        d = [  # world coordinate i of each leg: (R @ top + p - base)_i, written out (no einsum)
            R[..., i, 0, None] * T[:, 0]
            + R[..., i, 1, None] * T[:, 1]
            + R[..., i, 2, None] * T[:, 2]
            + (p[..., i, None] - B[:, i])
            for i in range(3)
        ]
        return np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])

    def top_joints_world(self, position: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
        """(6, 3) top joint positions in the world for one deck pose."""
        R = np.asarray(rotation, dtype=np.float64)
        return self.top_joints @ R.T + np.asarray(position, dtype=np.float64)

    def check_stroke(self, times: ArrayLike, lengths: ArrayLike) -> None:
        """Raise ValueError naming the first time (s) and leg (1-6) whose length leaves the stroke."""
        L = np.asarray(lengths)
        bad = (L < self.min_leg) | (L > self.max_leg) | ~np.isfinite(L)
        if bad.any():
            k, leg = np.argwhere(bad)[0]
            t = float(np.asarray(times)[k])
            raise ValueError(
                f"deck motion exceeds the Stewart leg stroke at t = {t:.3f} s: leg {leg + 1} would be "
                f"{L[k, leg]:.4f} m, allowed [{self.min_leg:.4f}, {self.max_leg:.4f}] m"
            )


__all__ = [
    "StewartGeometry",
]
