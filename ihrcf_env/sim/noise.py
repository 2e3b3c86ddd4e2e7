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


def check_param(name: str, value: object, *, positive: bool = False, upper: float | None = None) -> float:
    """A model parameter as a float: TypeError for non-numbers (bools included), ValueError naming
    ``name`` if it is not finite, negative (zero too with ``positive``) or above ``upper``."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeError(f"{name} must be a number, got {type(value).__name__} {value!r}")
    v = float(value)
    if not math.isfinite(v) or v < 0 or (positive and v == 0):
        raise ValueError(f"{name} must be a finite number {'> 0' if positive else '>= 0'}, got {value!r}")
    if upper is not None and v > upper:
        raise ValueError(f"{name} must be <= {upper:g}, got {value!r}")
    return v


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
        self.sigma = check_param("sigma", self.sigma)

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
        self.probability = check_param("probability", self.probability, upper=1.0)

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
    if isinstance(size, bool) or not isinstance(size, int | np.integer) or size < 1:
        raise ValueError(f"size must be an integer >= 1, got {size!r}")
    return int(size)


def _per_element(name: str, value: float | Sequence[float], size: int) -> NDArray[np.float64]:
    """``value`` (one number, or one per element) as a (size,) array of finite numbers >= 0."""
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str):
        items = list(value)
        if len(items) != size:
            raise ValueError(f"{name} must be one number or {size} numbers, got {value!r}")
        return np.array([check_param(f"{name}[{i}]", v) for i, v in enumerate(items)])
    return np.full(size, check_param(name, value))


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
        self.tau = check_param("tau", self.tau, positive=True)
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
