"""Pluggable measurement-noise models ("corruptors" in dm_control's words).

A noise model turns a true measurement vector into a measured one, drawing all its randomness
from the generator it is given (the env's ``np_random``), so a seeded episode is reproducible.
Models keep state where the physics of the error needs it (a bias that random-walks), which
:meth:`NoiseModel.reset` re-draws at the start of every episode. Pure numpy: no simulator import.

A sensor holds one model per measured quantity; :class:`Chain` applies several in order. The
validity mask travels with the values, so a model can also invalidate readings (dropouts).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


@runtime_checkable
class NoiseModel(Protocol):
    """Corrupts a measurement vector; may mark readings invalid."""

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: re-draw any persistent state (biases) from ``rng``."""

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Measured (value, valid) from the true ones; ``dt`` (s) is the time since the last sample."""
        ...


def _check_nonneg(name: str, value: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


@dataclass
class NoNoise:
    """The ideal sensor: values pass unchanged, nothing is drawn from the generator."""

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return value, valid


@dataclass
class GaussianNoise:
    """Additive white Gaussian noise of standard deviation ``sigma`` (units of the value)."""

    sigma: float

    def __post_init__(self) -> None:
        self.sigma = _check_nonneg("sigma", self.sigma)

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if self.sigma == 0.0:
            return value, valid
        return value + rng.normal(0.0, self.sigma, value.shape), valid


@dataclass
class Dropout:
    """Each reading is lost (invalid) independently with probability ``probability``."""

    probability: float

    def __post_init__(self) -> None:
        self.probability = _check_nonneg("probability", self.probability)
        if self.probability > 1.0:
            raise ValueError(f"probability must be in [0, 1], got {self.probability!r}")

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if self.probability == 0.0:
            return value, valid
        return value, valid & ~(rng.random(value.shape) < self.probability)


@dataclass
class Chain:
    """Several models applied in order."""

    models: Sequence[NoiseModel] = field(default_factory=tuple)

    def reset(self, rng: np.random.Generator) -> None:
        for m in self.models:
            m.reset(rng)

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        for m in self.models:
            value, valid = m.apply(value, valid, dt, rng)
        return value, valid
