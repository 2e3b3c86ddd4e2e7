"""Deck motion profiles: the deck pose relative to its neutral (home) pose as a function of time.

A profile maps times ``t`` (s, array of shape (N,)) to ``(offset (N, 3) m, rpy (N, 3) rad)``: the
deck frame's translation from the home position (world axes) and its roll/pitch/yaw (ZYX,
see ``ihrcf_env.core.frames``). Built-in profiles are vectorised; a user callable ``t -> pose`` for one
scalar time is wrapped by :class:`CallableProfile`.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize
from scipy.spatial.transform import Rotation

from ihrcf_env.core.checks import check_int, check_real, check_reals, describe
from ihrcf_env.core.frames import matrices_from_euler
from ihrcf_env.core.stewart import StewartGeometry

PoseArrays = tuple[NDArray[np.float64], NDArray[np.float64]]

#: Names of the six degrees of freedom, in the order of amplitudes and components.
DOFS: tuple[str, ...] = ("surge", "sway", "heave", "roll", "pitch", "yaw")


#: Bounds of a deck motion: amplitude of a translation (m) or rotation (rad) per sinusoid, a
#: frequency (Hz, below the physics rate's Nyquist frequency), a phase (rad), a period (s).
MAX_TRANSLATION = 10.0
MAX_ROTATION = math.pi
MAX_FREQUENCY = 50.0
MAX_PHASE = 1e3
PERIOD_BOUNDS = (0.1, 1e4)
#: Bound (s) of a profile's start time (:class:`ShiftedProfile`).
MAX_START_TIME = 1e6


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

    def __post_init__(self) -> None:
        comps = self.components
        if not isinstance(comps, tuple | list) or len(comps) > len(DOFS):
            raise TypeError(
                f"SumOfSines.components must be a tuple of at most {len(DOFS)} tuples (one per DOF "
                f"{DOFS}) of (amplitude, frequency_hz, phase_rad), got {describe(comps)}"
            )
        out = []
        for k, dof_comps in enumerate(comps):
            if not isinstance(dof_comps, tuple | list):
                raise TypeError(
                    f"SumOfSines.components[{k}] ({DOFS[k]}) must be a tuple of (amplitude, "
                    f"frequency_hz, phase_rad), got {describe(dof_comps)}"
                )
            amp_max, unit = (MAX_TRANSLATION, "m") if k < 3 else (MAX_ROTATION, "rad")
            checked = []
            for j, c in enumerate(dof_comps):
                name = f"SumOfSines.components[{k}][{j}] ({DOFS[k]})"
                if not isinstance(c, tuple | list) or len(c) != 3:
                    raise TypeError(f"{name} must be (amplitude, frequency_hz, phase_rad), got {describe(c)}")
                checked.append(
                    (
                        check_real(f"{name} amplitude", c[0], unit, low=-amp_max, high=amp_max),
                        check_real(f"{name} frequency", c[1], "Hz", low=0.0, high=MAX_FREQUENCY),
                        check_real(f"{name} phase", c[2], "rad", low=-MAX_PHASE, high=MAX_PHASE),
                    )
                )
            out.append(tuple(checked))
        self.components = tuple(out)

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


def sea_state_amplitudes(amplitudes: Mapping[str, float] | None = None) -> dict[str, float]:
    """The full per-DOF amplitudes of a sea state: :data:`SEA_STATE_AMPLITUDES` updated by
    ``amplitudes``. Raises TypeError (not a mapping of names to real numbers) or ValueError
    (unknown degree of freedom, negative or non-finite amplitude), naming ``sea_state_amplitudes``."""
    amps = dict(SEA_STATE_AMPLITUDES)
    if amplitudes is None:
        return amps
    if not isinstance(amplitudes, Mapping):
        raise TypeError(
            f"sea_state_amplitudes must be a mapping {{dof: amplitude}} with dof in {DOFS}, "
            f"got {type(amplitudes).__name__}"
        )
    unknown = set(amplitudes) - set(DOFS)
    if unknown:
        raise ValueError(
            f"sea_state_amplitudes has unknown degrees of freedom {sorted(map(str, unknown))}; use {DOFS}"
        )
    for k, v in amplitudes.items():
        high, unit = (MAX_TRANSLATION, "m") if DOFS.index(k) < 3 else (MAX_ROTATION, "rad")
        amps[k] = check_real(f"sea_state_amplitudes[{k!r}]", v, unit, low=0.0, high=high)
    return amps


def sea_state_profile(
    rng: np.random.Generator,
    amplitudes: Mapping[str, float] | None = None,
    n_components: int = 4,
    period_range: tuple[float, float] = (4.0, 14.0),
) -> SumOfSines:
    """Seeded sea-state-like motion: per DOF, ``n_components`` sinusoids with random periods in
    ``period_range`` (s) and random phases; their amplitudes are random weights normalised so the
    peak of the sum never exceeds the DOF's amplitude in ``amplitudes`` (defaults
    :data:`SEA_STATE_AMPLITUDES`; see :func:`sea_state_amplitudes` for the errors). Whether the
    legs can follow it for every seed is :func:`check_sea_state_amplitudes`' job."""
    amps = sea_state_amplitudes(amplitudes)
    lo, hi = check_reals("period_range", period_range, 2, "s", low=PERIOD_BOUNDS[0], high=PERIOD_BOUNDS[1])
    if not lo <= hi:
        raise ValueError(f"period_range must satisfy lo <= hi, got {period_range}")
    n_components = check_int("n_components", n_components, low=1, high=64)
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


#: Grid points per degree of freedom (including both ends) of the sea-state stroke check.
SEA_STATE_CHECK_POINTS = 5


def _leg_lengths_of_poses(geometry: StewartGeometry, poses: NDArray[np.float64]) -> NDArray[np.float64]:
    """Leg lengths (N, 6) of deck poses (N, 6) = (surge, sway, heave, roll, pitch, yaw) from home."""
    R = Rotation.from_euler("ZYX", poses[:, 5:2:-1]).as_matrix()
    return geometry.leg_lengths(geometry.home_position + poses[:, :3], R)


@functools.lru_cache(maxsize=64)
def _sea_state_leg_extremes(
    amps: tuple[float, ...], geometry: StewartGeometry
) -> tuple[float, NDArray[np.float64], int, float, NDArray[np.float64], int]:
    """(min length, its pose, its leg, max length, its pose, its leg) over the box +-amps."""
    a = np.asarray(amps)
    axes = [np.linspace(-x, x, SEA_STATE_CHECK_POINTS) if x > 0 else np.zeros(1) for x in a]
    corners = np.array(list(itertools.product(*[(-x, x) for x in a])))  # 64 (with repeats if x = 0)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 6)
    poses = np.concatenate([corners, grid])
    legs = _leg_lengths_of_poses(geometry, poses)
    bounds = [(-x, x) for x in a]
    lo = (np.inf, poses[0], 0)
    hi = (-np.inf, poses[0], 0)
    for leg in range(6):
        for sign in (1.0, -1.0):  # +1: minimise the length, -1: maximise it
            x0 = poses[int(np.argmin(sign * legs[:, leg]))]

            def f(x: NDArray[np.float64], leg: int = leg, sign: float = sign) -> float:
                return float(sign * _leg_lengths_of_poses(geometry, x[None, :])[0, leg])

            res = minimize(f, x0, method="L-BFGS-B", bounds=bounds)
            x = np.clip(res.x if res.fun < f(x0) else x0, -a, a)
            length = float(_leg_lengths_of_poses(geometry, x[None, :])[0, leg])
            if sign > 0 and length < lo[0]:
                lo = (length, x, leg)
            if sign < 0 and length > hi[0]:
                hi = (length, x, leg)
    return lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]


def check_sea_state_amplitudes(
    amplitudes: Mapping[str, float] | None, geometry: StewartGeometry | None = None
) -> None:
    """Raise ValueError naming ``sea_state_amplitudes`` unless the legs of ``geometry`` can follow
    every sea state with these amplitudes, for every seed and for all time.

    A sea state keeps each DOF within +-its amplitude, and its sinusoids' random periods can line
    up any combination of values in that box. So the whole box (offset from the home pose, roll/
    pitch/yaw) is checked against the stroke: its 64 corners, a grid of
    :data:`SEA_STATE_CHECK_POINTS` points per DOF, and a local (bounded L-BFGS-B) refinement of
    each leg's shortest and longest grid pose (leg length is not convex in the pose, so the corners
    alone do not suffice in general).
    """
    amps = sea_state_amplitudes(amplitudes)
    g = geometry if geometry is not None else StewartGeometry()
    lo, lo_pose, lo_leg, hi, hi_pose, hi_leg = _sea_state_leg_extremes(tuple(amps[d] for d in DOFS), g)
    for length, pose, leg in ((lo, lo_pose, lo_leg), (hi, hi_pose, hi_leg)):
        if not (g.min_leg <= length <= g.max_leg):
            where = ", ".join(
                f"{d} {v:+.3f} {'m' if k < 3 else 'rad'}"
                for k, (d, v) in enumerate(zip(DOFS, pose, strict=True))
            )
            given = dict(amplitudes) if amplitudes is not None else {}
            raise ValueError(
                f"sea_state_amplitudes {given} can drive the deck out of the Stewart legs' stroke: "
                f"a sea state may reach any pose with every degree of freedom within +-its amplitude "
                f"({', '.join(f'{d} {amps[d]:.3f}' for d in DOFS)}), and at ({where}) leg {leg + 1} "
                f"would be {length:.4f} m, allowed [{g.min_leg:.4f}, {g.max_leg:.4f}] m; reduce the "
                f"amplitudes (the defaults, SEA_STATE_AMPLITUDES, fit)"
            )


class UnusablePoseError(ValueError):
    """A profile gave no usable pose at ``time`` (s): the callable raised, or returned the wrong
    shape or a non-finite value. ``offset`` and ``rpy`` hold the poses sampled before it (the first
    ``index`` times asked for)."""

    def __init__(
        self, message: str, time: float, index: int, offset: NDArray[np.float64], rpy: NDArray[np.float64]
    ) -> None:
        super().__init__(message)
        self.time = time
        self.index = index
        self.offset = offset
        self.rpy = rpy


class CallableProfile(MotionProfile):
    """Wraps a user function ``t -> pose`` where pose is ``(offset (3,), rpy (3,))`` or a (6,) array.

    :meth:`sample` raises :class:`UnusablePoseError` (a ValueError naming the time) at the first
    time whose pose is unusable: the function raised, or returned the wrong shape or a non-finite
    value.
    """

    name = "callable"

    def __init__(self, fn: Callable[[float], object]) -> None:
        if not callable(fn):
            raise ValueError(f"deck profile must be a name or a callable, got {type(fn).__name__}")
        self.fn = fn

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        t = np.asarray(t, dtype=np.float64)
        out = np.empty((t.shape[0], 6))
        for i, ti in enumerate(t):
            problem = ""
            try:
                v = self.fn(float(ti))
                arr = (
                    np.concatenate([np.ravel(np.asarray(x, dtype=np.float64)) for x in v])
                    if isinstance(v, tuple)
                    else np.ravel(np.asarray(v, dtype=np.float64))
                )
            except Exception as e:  # the user's function failed, or its value is not numbers
                problem = (
                    f"deck profile callable gave no usable pose at t = {ti:.3f} s: {type(e).__name__}: {e}"
                )
                cause: Exception | None = e
            else:
                cause = None
                if arr.shape != (6,) or not np.isfinite(arr).all():
                    problem = (
                        f"deck profile callable must return (offset (3,), rpy (3,)) or a finite (6,) "
                        f"array; got {arr.shape} / non-finite at t = {ti:.3f} s"
                    )
            if problem:
                raise UnusablePoseError(
                    problem, float(ti), i, out[:i, :3].copy(), out[:i, 3:].copy()
                ) from cause
            out[i] = arr
        return out[:, :3], out[:, 3:]


def profile_leg_lengths(
    profile: MotionProfile, geometry: StewartGeometry, t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(n, 6) leg lengths (m) of ``geometry`` following ``profile`` at the times ``t`` (n,) (s):
    what the stroke checks compare with the legs' limits (the rotations in closed form,
    :func:`~ihrcf_env.core.frames.matrices_from_euler`)."""
    offset, rpy = profile.sample(t)
    return geometry.leg_lengths(geometry.home_position + offset, matrices_from_euler(rpy))


def sample_until_unusable(profile: MotionProfile, t: NDArray[np.float64]) -> PoseArrays:
    """``profile.sample(t)``, but from the first unusable pose on (see :class:`UnusablePoseError`)
    the rows are NaN instead of an exception: for sampling beyond a checked horizon, where the
    deck then stops (a non-finite pose counts as leaving the legs' stroke)."""
    try:
        return profile.sample(t)
    except UnusablePoseError as e:
        n = np.asarray(t).shape[0]
        offset = np.full((n, 3), np.nan)
        rpy = np.full((n, 3), np.nan)
        offset[: e.index] = e.offset
        rpy[: e.index] = e.rpy
        return offset, rpy


class ShiftedProfile(MotionProfile):
    """``base`` started ``t0`` seconds into its motion: pose(t) = base(t + t0)."""

    def __init__(self, base: MotionProfile, t0: float) -> None:
        self.base = base
        self.t0 = check_real("deck start time", t0, "s", low=-MAX_START_TIME, high=MAX_START_TIME)
        self.name = base.name

    def sample(self, t: NDArray[np.float64]) -> PoseArrays:
        return self.base.sample(np.asarray(t, dtype=np.float64) + self.t0)


#: Duration (s) of the "paper" run; random deck start times are drawn in [0, PAPER_DURATION).
PAPER_DURATION = 130.0

PROFILE_NAMES: tuple[str, ...] = ("paper", "sea_state", "static", "ship")


def make_profile(
    spec: str | Callable[[float], object] | MotionProfile,
    rng: np.random.Generator,
    amplitudes: Mapping[str, float] | None = None,
    ship: object = None,
) -> MotionProfile:
    """Build a profile from a name in :data:`PROFILE_NAMES`, a callable or a profile instance.
    ``"ship"``: a ship's deck (:func:`ihrcf_env.core.ship.ship_profile`) with the options
    ``ship`` (a :class:`~ihrcf_env.core.ship.ShipOptions`, a dict of its fields, or None for the
    defaults)."""
    if isinstance(spec, MotionProfile):
        return spec
    if isinstance(spec, str):
        if spec == "paper":
            return paper_profile()
        if spec == "sea_state":
            return sea_state_profile(rng, amplitudes)
        if spec == "static":
            return StaticProfile()
        if spec == "ship":
            from ihrcf_env.core.ship import ship_profile  # the ship module builds on this one

            return ship_profile(rng, ship)  # type: ignore[arg-type]
        raise ValueError(f"deck_profile must be one of {PROFILE_NAMES} or a callable, got {spec!r}")
    return CallableProfile(spec)


__all__ = [
    "DOFS",
    "MAX_FREQUENCY",
    "MAX_PHASE",
    "MAX_ROTATION",
    "MAX_START_TIME",
    "MAX_TRANSLATION",
    "PAPER_DURATION",
    "PERIOD_BOUNDS",
    "PROFILE_NAMES",
    "SEA_STATE_AMPLITUDES",
    "SEA_STATE_CHECK_POINTS",
    "CallableProfile",
    "MotionProfile",
    "PoseArrays",
    "ShiftedProfile",
    "StaticProfile",
    "SumOfSines",
    "UnusablePoseError",
    "check_sea_state_amplitudes",
    "make_profile",
    "paper_profile",
    "profile_leg_lengths",
    "sample_until_unusable",
    "sea_state_amplitudes",
    "sea_state_profile",
]
