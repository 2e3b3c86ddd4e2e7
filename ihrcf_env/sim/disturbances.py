"""Disturbances acting on the drone: the force hook of :class:`~ihrcf_env.sim.world.World`.

A disturbance is called at every physics step with the simulated time and the drone's world
position and velocity and returns a world-frame force (N) applied at the centre of mass, like
PyFlyt's wind ``__call__(t, pos)``. Randomness (gust sequences) is drawn in :meth:`reset` from the
env's generator so that a seeded episode is reproducible. Wind models come with the landing task.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


@runtime_checkable
class Disturbance(Protocol):
    """World-frame force (N) on the drone's centre of mass as a function of time and state."""

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: draw this episode's random parameters from ``rng``."""

    def __call__(
        self, t: float, position: Sequence[float], velocity: Sequence[float]
    ) -> tuple[float, float, float]:
        """Force (N, world frame) at time ``t`` (s) for the drone at ``position`` (m) with
        ``velocity`` (m/s)."""
        ...


class ConstantForce:
    """A steady world-frame force (N), e.g. to test position hold or model a steady side load."""

    def __init__(self, force: Sequence[float] | NDArray[np.float64]) -> None:
        f = np.asarray(force, dtype=np.float64)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise ValueError(f"force must be 3 finite numbers (N), got {force!r}")
        self.force = (float(f[0]), float(f[1]), float(f[2]))

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(
        self, t: float, position: Sequence[float], velocity: Sequence[float]
    ) -> tuple[float, float, float]:
        return self.force
