"""Deck motion profiles: the deck pose relative to its neutral (home) pose as a function of time.

A profile maps times ``t`` (s, array of shape (N,)) to ``(offset (N, 3) m, rpy (N, 3) rad)``: the
deck frame's translation from the home position (world axes) and its roll/pitch/yaw (ZYX,
see ``ihrcf_env.core.frames``). Built-in profiles are vectorised; a user callable ``t -> pose`` for one
scalar time is wrapped by :class:`CallableProfile`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

PoseArrays = tuple[NDArray[np.float64], NDArray[np.float64]]

#: Names of the six degrees of freedom, in the order of amplitudes and components.
DOFS: tuple[str, ...] = ("surge", "sway", "heave", "roll", "pitch", "yaw")


class MotionProfile:
    """Base class: subclasses implement :meth:`sample`."""

    name: str = "profile"

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        raise NotImplementedError

    def __call__(self, t: float) -> PoseArrays:
        """Pose at one time: ``(offset (3,), rpy (3,))``."""
        off, rpy = self.sample(np.array([float(t)]))
        return off[0], rpy[0]


@dataclass
class SumOfSines(MotionProfile):
    """Sum of sinusoids per degree of freedom.

    ``components[k]`` lists ``(amplitude, frequency_hz, phase_rad)`` for DOF ``DOFS[k]``
    (metres for surge/sway/heave, radians for roll/pitch/yaw).
    """

    components: tuple[tuple[tuple[float, float, float], ...], ...]
    name: str = "sum_of_sines"

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        t = np.asarray(t, dtype=np.float64)
        out = np.zeros((t.shape[0], 6))
        for k, comps in enumerate(self.components):
            for amp, freq, phase in comps:
                out[:, k] += amp * np.sin(2 * math.pi * freq * t + phase)
        return out[:, :3], out[:, 3:]


class StaticProfile(MotionProfile):
    """The deck stays at its home pose."""

    name = "static"

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        n = np.asarray(t).shape[0]
        return np.zeros((n, 3)), np.zeros((n, 3))


def paper_profile() -> SumOfSines:
    """Slow 6-DOF multi-sine like the paper's Stewart test (~130 s).

    Centimetres of translation (surge/sway 3 cm, heave 5 cm), roll and pitch up to ~13 degrees,
    yaw ~8 degrees, with periods of 20-130 s, starting from the home pose at t = 0 (every
    component starts at zero phase, so the motion ramps up smoothly).
    """
    d = math.radians
    comps = (
        ((0.020, 1 / 65, 0.0), (0.010, 1 / 26, 0.0)),
        ((0.020, 1 / 43, 0.0), (0.010, 1 / 130, 0.0)),
        ((0.035, 1 / 32.5, 0.0), (0.015, 1 / 21.7, 0.0)),
        ((d(9.0), 1 / 43.3, 0.0), (d(4.0), 1 / 18.6, 0.0)),
        ((d(8.0), 1 / 32.5, 0.0), (d(5.0), 1 / 65, 0.0)),
        ((d(6.0), 1 / 52, 0.0), (d(2.0), 1 / 26, 0.0)),
    )
    return SumOfSines(components=comps, name="paper")


#: Default sea-state amplitudes per DOF (m for surge/sway/heave, rad for roll/pitch/yaw).
SEA_STATE_AMPLITUDES: dict[str, float] = {
    "surge": 0.03,
    "sway": 0.03,
    "heave": 0.08,
    "roll": math.radians(8.0),
    "pitch": math.radians(5.0),
    "yaw": math.radians(3.0),
}


def sea_state_profile(
    rng: np.random.Generator,
    amplitudes: Mapping[str, float] | None = None,
    n_components: int = 4,
    period_range: tuple[float, float] = (4.0, 14.0),
) -> SumOfSines:
    """Seeded sea-state-like motion: per DOF, ``n_components`` sinusoids with random periods in
    ``period_range`` (s) and random phases; their amplitudes are random weights normalised so the
    peak of the sum never exceeds the DOF's amplitude in ``amplitudes`` (defaults
    :data:`SEA_STATE_AMPLITUDES`; unknown keys raise ValueError)."""
    amps = dict(SEA_STATE_AMPLITUDES)
    if amplitudes is not None:
        unknown = set(amplitudes) - set(DOFS)
        if unknown:
            raise ValueError(
                f"sea_state amplitudes has unknown degrees of freedom {sorted(unknown)}; use {DOFS}"
            )
        for k, v in amplitudes.items():
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"sea_state amplitude {k!r} must be finite and >= 0, got {v!r}")
            amps[k] = float(v)
    lo, hi = period_range
    if not (0 < lo <= hi):
        raise ValueError(f"period_range must satisfy 0 < lo <= hi, got {period_range}")
    if n_components < 1:
        raise ValueError(f"n_components must be >= 1, got {n_components}")
    comps = []
    for dof in DOFS:
        w = rng.uniform(0.3, 1.0, n_components)
        w = w / w.sum() * amps[dof]
        periods = rng.uniform(lo, hi, n_components)
        phases = rng.uniform(0.0, 2 * math.pi, n_components)
        comps.append(
            tuple((float(a), float(1 / p), float(ph)) for a, p, ph in zip(w, periods, phases, strict=True))
        )
    return SumOfSines(components=tuple(comps), name="sea_state")


class CallableProfile(MotionProfile):
    """Wraps a user function ``t -> pose`` where pose is ``(offset (3,), rpy (3,))`` or a (6,) array."""

    name = "callable"

    def __init__(self, fn: Callable[[float], object]) -> None:
        if not callable(fn):
            raise ValueError(f"deck profile must be a name or a callable, got {type(fn).__name__}")
        self.fn = fn

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        t = np.asarray(t, dtype=np.float64)
        out = np.empty((t.shape[0], 6))
        for i, ti in enumerate(t):
            v = self.fn(float(ti))
            try:
                arr = (
                    np.concatenate([np.ravel(np.asarray(x, dtype=np.float64)) for x in v])
                    if isinstance(v, tuple)
                    else np.ravel(np.asarray(v, dtype=np.float64))
                )
            except (TypeError, ValueError) as e:
                raise ValueError(
                    f"deck profile callable returned an unusable pose at t = {ti:.3f} s: {e}"
                ) from e
            if arr.shape != (6,) or not np.all(np.isfinite(arr)):
                raise ValueError(
                    f"deck profile callable must return (offset (3,), rpy (3,)) or a finite (6,) array; "
                    f"got {arr.shape} / non-finite at t = {ti:.3f} s"
                )
            out[i] = arr
        return out[:, :3], out[:, 3:]


class ShiftedProfile(MotionProfile):
    """``base`` started ``t0`` seconds into its motion: pose(t) = base(t + t0)."""

    def __init__(self, base: MotionProfile, t0: float) -> None:
        if not math.isfinite(t0):
            raise ValueError(f"deck start time must be finite (s), got {t0!r}")
        self.base = base
        self.t0 = float(t0)
        self.name = base.name

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        return self.base.sample(np.asarray(t, dtype=np.float64) + self.t0)


#: Duration (s) of the "paper" run; random deck start times are drawn in [0, PAPER_DURATION).
PAPER_DURATION = 130.0

PROFILE_NAMES: tuple[str, ...] = ("paper", "sea_state", "static")


def make_profile(
    spec: str | Callable[[float], object] | MotionProfile,
    rng: np.random.Generator,
    amplitudes: Mapping[str, float] | None = None,
) -> MotionProfile:
    """Build a profile from a name in :data:`PROFILE_NAMES`, a callable or a profile instance."""
    if isinstance(spec, MotionProfile):
        return spec
    if isinstance(spec, str):
        if spec == "paper":
            return paper_profile()
        if spec == "sea_state":
            return sea_state_profile(rng, amplitudes)
        if spec == "static":
            return StaticProfile()
        raise ValueError(f"deck_profile must be one of {PROFILE_NAMES} or a callable, got {spec!r}")
    return CallableProfile(spec)
