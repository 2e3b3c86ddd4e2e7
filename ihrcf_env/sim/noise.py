"""Pluggable measurement-noise models ("corruptors" in dm_control's words).

A noise model turns a true measurement vector into a measured one, drawing all its randomness
from the generator it is given (the env's ``np_random``), so a seeded episode is reproducible.
Models keep state where the physics of the error needs it (a bias that random-walks), which
:meth:`NoiseModel.reset` re-draws at the start of every episode. Pure numpy: no simulator import.

A sensor holds one model per measured quantity; :class:`Chain` applies several in order. The
validity mask travels with the values, so a model can also invalidate readings (dropouts).

Models (``dt`` is the time since the previous sample, ``n ~ N(0, 1)`` a fresh draw):

* :class:`NoNoise`: ``y = x`` (draws nothing);
* :class:`GaussianNoise`: ``y = x + sigma n`` (a fixed per-sample sigma);
* :class:`WhiteNoise`: ``y = x + density / sqrt(dt) n`` (a noise density, discretised at the rate);
* :class:`ConstantBias`: ``y = x + b``, ``b ~ N(0, sigma^2)`` drawn at reset (turn-on bias);
* :class:`BiasRandomWalk`: ``b += sigma sqrt(dt) n``, ``y = x + b``;
* :class:`GaussMarkov`: ``b = phi b + sigma sqrt(1 - phi^2) n``, ``phi = exp(-dt / tau)``,
  ``y = x + b`` (bias instability; stationary std ``sigma``);
* :class:`Dropout`: the reading is invalid with probability ``p``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int, check_non_negative, check_real, check_reals, describe


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


#: Upper bound of a generic noise standard deviation or density (units of the value): far above any
#: sensor's, far below where squares overflow.
MAX_SIGMA = 1e6
#: Bounds (s) of a correlation time.
TAU_BOUNDS = (1e-3, 1e4)


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
        self.sigma = check_non_negative("sigma", self.sigma, high=MAX_SIGMA)

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
        self.probability = check_real("probability", self.probability, low=0.0, high=1.0)

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


# -- stateful models of inertial sensors and estimators ----------------------------------------------
def _check_size(size: int) -> int:
    return check_int("size", size, low=1, high=10**6)


def _per_element(name: str, value: float | Sequence[float], size: int) -> NDArray[np.float64]:
    """``value`` (one number, or one per element) as a (size,) array of numbers in [0, MAX_SIGMA]."""
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str):
        if len(value) != size:
            raise ValueError(f"{name} must be one number or {size} numbers, got {describe(value)}")
        return np.array(check_reals(name, value, size, low=0.0, high=MAX_SIGMA))
    return np.full(size, check_non_negative(name, value, high=MAX_SIGMA))


@dataclass
class WhiteNoise:
    """Additive white noise given by its (one-sided) noise density ``density`` (units/sqrt(Hz), e.g.
    rad/s/sqrt(Hz) for a gyro), sampled every ``dt`` seconds: each sample is independent with
    ``sigma_d = density / sqrt(dt) = density * sqrt(rate)`` (the usual discretisation, e.g. Kalibr's
    IMU noise model). ``density`` is one number or one per element (``size``)."""

    density: float | Sequence[float]
    size: int = 3

    def __post_init__(self) -> None:
        self.size = _check_size(self.size)
        self._density = _per_element("density", self.density, self.size)

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def sigma(self, dt: float) -> NDArray[np.float64]:
        """Standard deviation of one sample taken ``dt`` s after the previous one."""
        return self._density / math.sqrt(dt)

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if not self._density.any():
            return value, valid
        return value + rng.standard_normal(self.size) * self.sigma(dt), valid


@dataclass
class ConstantBias:
    """A bias drawn once per episode (at :meth:`reset`), ``N(0, sigma^2)`` per element, then constant:
    a sensor's turn-on (run-to-run) offset."""

    sigma: float | Sequence[float]
    size: int = 3

    def __post_init__(self) -> None:
        self.size = _check_size(self.size)
        self._sigma = _per_element("sigma", self.sigma, self.size)
        self.bias = np.zeros(self.size)

    def reset(self, rng: np.random.Generator) -> None:
        self.bias = rng.standard_normal(self.size) * self._sigma if self._sigma.any() else np.zeros(self.size)

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return value + self.bias, valid


@dataclass
class BiasRandomWalk:
    """A bias that random-walks: ``b_k = b_{k-1} + sigma * sqrt(dt) * n_k`` (``sigma`` in units/sqrt(s),
    the "rate random walk" of an Allan plot), ``n_k ~ N(0, 1)``; ``b_0 ~ N(0, initial_sigma^2)``
    at :meth:`reset`. The bias moves before it is added to each sample."""

    sigma: float | Sequence[float]
    initial_sigma: float | Sequence[float] = 0.0
    size: int = 3

    def __post_init__(self) -> None:
        self.size = _check_size(self.size)
        self._sigma = _per_element("sigma", self.sigma, self.size)
        self._sigma0 = _per_element("initial_sigma", self.initial_sigma, self.size)
        self.bias = np.zeros(self.size)

    def reset(self, rng: np.random.Generator) -> None:
        self.bias = (
            rng.standard_normal(self.size) * self._sigma0 if self._sigma0.any() else np.zeros(self.size)
        )

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        if self._sigma.any():
            self.bias = self.bias + rng.standard_normal(self.size) * self._sigma * math.sqrt(dt)
        return value + self.bias, valid


@dataclass
class GaussMarkov:
    """A first-order Gauss-Markov bias (a bias instability): ``db = -b / tau dt + q dW`` with stationary
    standard deviation ``sigma`` and correlation time ``tau`` (s), discretised exactly:
    ``b_k = phi b_{k-1} + sigma sqrt(1 - phi^2) n_k`` with ``phi = exp(-dt / tau)``, so
    ``E[b_k b_{k+m}] = sigma^2 exp(-m dt / tau)``. :meth:`reset` draws ``b_0`` from the stationary
    distribution ``N(0, sigma^2)``. The bias moves before it is added to each sample."""

    sigma: float | Sequence[float]
    tau: float
    size: int = 3

    def __post_init__(self) -> None:
        self.size = _check_size(self.size)
        self._sigma = _per_element("sigma", self.sigma, self.size)
        self.tau = check_real("tau", self.tau, "s", low=TAU_BOUNDS[0], high=TAU_BOUNDS[1])
        self.bias = np.zeros(self.size)

    def reset(self, rng: np.random.Generator) -> None:
        self.bias = rng.standard_normal(self.size) * self._sigma if self._sigma.any() else np.zeros(self.size)

    def step(self, dt: float, rng: np.random.Generator) -> NDArray[np.float64]:
        """Advance the bias by ``dt`` seconds and return it."""
        if self._sigma.any():
            phi = math.exp(-dt / self.tau)
            self.bias = phi * self.bias + rng.standard_normal(self.size) * (
                self._sigma * math.sqrt(1.0 - phi * phi)
            )
        return self.bias

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        return value + self.step(dt, rng), valid


__all__ = [
    "MAX_SIGMA",
    "TAU_BOUNDS",
    "BiasRandomWalk",
    "Chain",
    "ConstantBias",
    "Dropout",
    "GaussMarkov",
    "GaussianNoise",
    "NoNoise",
    "NoiseModel",
    "WhiteNoise",
]
