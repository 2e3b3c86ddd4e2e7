"""Sensor faults: seeded failures applied to the sensors' readings (opt-in, one class per kind).

A fault (:class:`~ihrcf_env.sim.registry.Fault`) acts on the mapping one sensor reads, after its
noise models: ``reset(rng)`` draws the episode's fault (which sensors, when it starts),
``apply(reading, time, dt, rng)`` returns the faulty reading (a new dict; keys the fault does not
act on pass unchanged, a reading without its keys passes whole). ``time`` (s) is the reading's time
since the episode's start, ``dt`` (s) the time since the sensor's previous sample. All randomness
comes from the generator given (the world's stream ``"fault.<name>"``). Pure numpy: no simulator.

* :class:`ToFDead`: ToF sensors read invalid (``ranges_valid = 0``, the range ``tof_max_range``, as
  any invalid reading) from an onset time;
* :class:`ToFStuck`: ToF sensors repeat their last valid range from an onset, still flagged valid;
* :class:`CameraDropout`: bursts of lost camera frames (Gilbert-Elliott two-state Markov chain);
* :class:`TagOcclusion`: episodes of an occluder (spray, a deck crew member) over part of the tag;
  the detector loses the tag while the occluder covers one of its corners;
* :class:`ImuBiasStep`: a step in the gyro and/or accelerometer bias from an onset time.

An onset is a time (s) from the episode's start, or ``(low, high)``: drawn uniformly at reset.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int, check_non_negative, check_positive, check_real, describe
from ihrcf_env.sim.sensors.base import tag_status_code

#: ToF sensors ps1..ps4 (indices 0..3).
N_TOF = 4
#: Upper bound (s) of an onset time: far beyond any episode.
MAX_ONSET_S = 1e6
#: ``tag_reason`` of a frame the camera lost (no image reached the detector).
REASON_FRAME_LOST = "camera frame lost"
#: ``tag_reason`` of a tag the detector lost to an occluder.
REASON_OCCLUDED = "tag occluded"
#: Full scales of a MEMS IMU (BMI088: 2000 deg/s, 24 g): bounds of a bias step.
MAX_GYRO_STEP = math.radians(2000.0)
MAX_ACCEL_STEP = 24 * 9.80665


Reading = Mapping[str, NDArray]


def check_onset(name: str, value: Any) -> tuple[float, float]:
    """An onset (s): a number, or ``(low, high)`` with ``0 <= low <= high``."""
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str):
        if len(value) != 2:
            raise TypeError(f"{name} must be a time (s) or (low, high), got {describe(value)}")
        lo = check_non_negative(f"{name}[0]", value[0], "s", high=MAX_ONSET_S)
        hi = check_real(f"{name}[1]", value[1], "s", low=lo, high=MAX_ONSET_S)
        return lo, hi
    t = check_non_negative(name, value, "s", high=MAX_ONSET_S)
    return t, t


def _draw_onset(window: tuple[float, float], rng: np.random.Generator) -> float:
    lo, hi = window
    return lo if hi == lo else float(rng.uniform(lo, hi))


def check_tof_sensors(name: str, value: Any) -> tuple[int, ...] | None:
    """Indices of ToF sensors (0..3 for ps1..ps4), each once (one index alone or a sequence)."""
    if value is None:
        return None
    items = [value] if not isinstance(value, Sequence | np.ndarray) or isinstance(value, str) else list(value)
    if not items:
        raise ValueError(f"{name} must name at least one ToF sensor (0..3), got {describe(value)}")
    idx = tuple(check_int(f"{name}[{i}]", v, low=0, high=N_TOF - 1) for i, v in enumerate(items))
    if len(set(idx)) != len(idx):
        raise ValueError(f"{name}: a sensor is given twice in {list(idx)}")
    return idx


@dataclass
class _ToFFault:
    """Shared by the ToF faults: which sensors (``sensors``, or ``count`` drawn at reset) and when."""

    sensors: int | Sequence[int] | None = None
    count: int = 1
    onset: float | Sequence[float] = 0.0
    chosen: tuple[int, ...] = field(default=(), init=False)
    start: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        kind = type(self).__name__
        self._fixed = check_tof_sensors(f"{kind}.sensors", self.sensors)
        self.sensors = self._fixed
        self.count = check_int(f"{kind}.count", self.count, low=1, high=N_TOF)
        if self._fixed is not None and self.count not in (1, len(self._fixed)):
            raise ValueError(f"{kind}: give sensors or count, not both ({self._fixed}, count={self.count})")
        self._window = check_onset(f"{kind}.onset", self.onset)
        self.chosen = self._fixed if self._fixed is not None else ()

    def reset(self, rng: np.random.Generator) -> None:
        if self._fixed is None:
            self.chosen = tuple(sorted(int(i) for i in rng.choice(N_TOF, self.count, replace=False)))
        self.start = _draw_onset(self._window, rng)

    def fixed(self) -> frozenset[int]:
        """The sensors this fault hits in every episode (empty when they are drawn)."""
        return frozenset(self._fixed) if self._fixed is not None else frozenset()


@dataclass
class ToFDead(_ToFFault):
    """ToF sensors that stop ranging: from the onset they read invalid (``ranges_valid = 0``) and
    read ``tof_max_range`` (m), as every invalid reading does. ``sensors`` (indices 0..3 of
    ps1..ps4) or ``count`` sensors drawn per episode; at least one sensor keeps working."""

    tof_max_range: float = 4.0

    def __post_init__(self) -> None:
        super().__post_init__()
        n = len(self._fixed) if self._fixed is not None else self.count
        if n >= N_TOF:
            raise ValueError(
                "ToFDead: all four ToF sensors dead leaves no range at all (IHRCF needs three); "
                "at most three may be dead"
            )
        self.tof_max_range = check_positive("ToFDead.tof_max_range", self.tof_max_range, "m", high=100.0)

    def apply(self, reading: Reading, time: float, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        out = dict(reading)
        if "ranges" not in out or time < self.start:
            return out
        dead = np.zeros(N_TOF, bool)
        dead[list(self.chosen)] = True
        r = np.asarray(out["ranges"])
        out["ranges"] = np.where(dead, self.tof_max_range, r).astype(r.dtype)
        if "ranges_valid" in out:
            v = np.asarray(out["ranges_valid"])
            out["ranges_valid"] = np.where(dead, 0, v).astype(v.dtype)
        return out

    def check_with(self, faults: Mapping[str, object]) -> None:
        """A sensor both dead and stuck (given by index) is a contradiction."""
        for name, other in faults.items():
            if isinstance(other, ToFStuck) and self.fixed() & other.fixed():
                raise ValueError(
                    f"faults: ToF sensors {sorted(self.fixed() & other.fixed())} are both dead "
                    f"(tof_dead) and stuck ({name})"
                )


@dataclass
class ToFStuck(_ToFFault):
    """ToF sensors whose output freezes: from the onset each repeats its last valid range, still
    flagged valid (``ranges_valid = 1``), whatever the true distance (a firmware hang, a cracked
    cover glass reflecting a fixed echo). Before its first valid reading a sensor reads normally."""

    latched: NDArray[np.float64] = field(default_factory=lambda: np.full(N_TOF, np.nan), init=False)

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.latched = np.full(N_TOF, np.nan)

    def apply(self, reading: Reading, time: float, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        out = dict(reading)
        if "ranges" not in out:
            return out
        r = np.asarray(out["ranges"])
        valid = (
            np.asarray(out["ranges_valid"]).astype(bool) if "ranges_valid" in out else np.ones(N_TOF, bool)
        )
        stuck = np.zeros(N_TOF, bool)
        stuck[list(self.chosen)] = True
        frozen = stuck & np.isfinite(self.latched) & (time >= self.start)
        # Until the onset (and until a first valid reading) the sensor tracks its valid readings.
        update = stuck & ~frozen & valid
        self.latched[update] = r[update]
        if not frozen.any():
            return out
        out["ranges"] = np.where(frozen, self.latched, r).astype(r.dtype)
        if "ranges_valid" in out:
            v = np.asarray(out["ranges_valid"])
            out["ranges_valid"] = np.where(frozen, 1, v).astype(v.dtype)
        return out


def lost_tag(reading: Reading, reason: str) -> dict[str, NDArray]:
    """``reading`` with the tag not detected for ``reason`` (corners zero, as every miss)."""
    out = dict(reading)
    if "tag_corners" in out:
        out["tag_corners"] = np.zeros_like(np.asarray(out["tag_corners"]))
        out["tag_detected"] = np.array(False)
        out["tag_reason"] = np.array(reason)
        out["tag_status"] = np.array(max(1, tag_status_code(reason)))
    if "image" in out:
        out["image"] = np.zeros_like(np.asarray(out["image"]))
    return out


@dataclass
class CameraDropout:
    """Bursts of lost camera frames: Gilbert's two-state Markov chain (the Gilbert-Elliott model
    with no loss in the good state, every frame lost in the bad one), one transition per frame.
    ``loss_rate`` is the long-run fraction of frames lost, ``mean_burst`` the mean number of frames
    in a burst, so ``P(bad -> good) = 1 / mean_burst`` and ``P(good -> bad) = loss_rate /
    ((1 - loss_rate) mean_burst)`` (at most 1: ``loss_rate <= mean_burst / (mean_burst + 1)``).
    The first frame's state is drawn from the stationary distribution. A lost frame reads as the tag
    not detected, ``tag_reason`` :data:`REASON_FRAME_LOST` (an image output reads all black)."""

    loss_rate: float = 0.05
    mean_burst: float = 3.0
    bad: bool = field(default=False, init=False)
    started: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        self.loss_rate = check_real("CameraDropout.loss_rate", self.loss_rate, low=0.0, high=1.0)
        self.mean_burst = check_real("CameraDropout.mean_burst", self.mean_burst, "frames", low=1.0, high=1e6)
        b = self.mean_burst
        if self.loss_rate > b / (b + 1.0):
            raise ValueError(
                f"CameraDropout: a loss_rate of {self.loss_rate:g} cannot be met with bursts of "
                f"{b:g} frames on average (at most mean_burst / (mean_burst + 1) = {b / (b + 1):.4g})"
            )
        self.p_recover = 1.0 / b
        self.p_fail = self.loss_rate / ((1.0 - self.loss_rate) * b) if self.loss_rate > 0 else 0.0

    def reset(self, rng: np.random.Generator) -> None:
        self.bad = False
        self.started = False

    def apply(self, reading: Reading, time: float, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        if "tag_corners" not in reading and "image" not in reading:
            return dict(reading)
        u = float(rng.random())
        if not self.started:
            self.started = True
            self.bad = u < self.loss_rate
        else:
            self.bad = u >= self.p_recover if self.bad else u < self.p_fail
        return lost_tag(reading, REASON_FRAME_LOST) if self.bad else dict(reading)


#: The tag's four corners in its own square (edge 2, half-width 1).
TAG_SQUARE = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])


@dataclass
class TagOcclusion:
    """Episodes of an occluder over part of the tag (spray, a deck crew member's foot, a hose).

    Episodes start as a Poisson process of ``rate`` (1/s) and last an exponential time of mean
    ``mean_duration`` (s): an alternating renewal process, started in its stationary state. Each
    episode draws a disc in the tag's own square (half-width 1): its centre uniform over the tag
    widened by its radius, its radius uniform in ``radius`` (fractions of the tag's half-width:
    one number, or (low, high)). Square-fiducial detectors (AprilTag, ArUco) find the tag from its
    four border corners, so while the disc covers a corner the tag is not detected, ``tag_reason``
    :data:`REASON_OCCLUDED`; a disc over the interior only is absorbed by the code's error
    correction and the corners read normally. The state advances with the reading's time."""

    rate: float = 0.05
    mean_duration: float = 2.0
    radius: float | Sequence[float] = (0.3, 1.0)
    active: bool = field(default=False, init=False)
    next_change: float = field(default=math.inf, init=False)
    centre: NDArray[np.float64] = field(default_factory=lambda: np.zeros(2), init=False)
    disc: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        self.rate = check_non_negative("TagOcclusion.rate", self.rate, "1/s", high=1e3)
        self.mean_duration = check_positive("TagOcclusion.mean_duration", self.mean_duration, "s", high=1e4)
        r = self.radius
        if isinstance(r, Sequence | np.ndarray) and not isinstance(r, str):
            if len(r) != 2:
                raise TypeError(f"TagOcclusion.radius must be a number or (low, high), got {describe(r)}")
            lo = check_positive("TagOcclusion.radius[0]", r[0], high=4.0)
            self._radius = (lo, check_real("TagOcclusion.radius[1]", r[1], low=lo, high=4.0))
        else:
            v = check_positive("TagOcclusion.radius", r, high=4.0)
            self._radius = (v, v)

    def _start(self, t: float, rng: np.random.Generator) -> None:
        lo, hi = self._radius
        self.disc = lo if hi == lo else float(rng.uniform(lo, hi))
        self.centre = rng.uniform(-1.0 - self.disc, 1.0 + self.disc, 2)
        self.active = True
        self.next_change = t + float(rng.exponential(self.mean_duration))

    def _end(self, t: float, rng: np.random.Generator) -> None:
        self.active = False
        self.next_change = t + float(rng.exponential(1.0 / self.rate)) if self.rate > 0 else math.inf

    def reset(self, rng: np.random.Generator) -> None:
        busy = self.rate * self.mean_duration
        if float(rng.random()) < busy / (1.0 + busy):
            self._start(0.0, rng)  # memoryless: the remaining duration is exponential too
        else:
            self._end(0.0, rng)

    def covered(self) -> NDArray[np.bool_]:
        """(4,) which corners the current occluder covers (all False between episodes)."""
        if not self.active:
            return np.zeros(4, bool)
        d = TAG_SQUARE - self.centre
        return np.asarray((d * d).sum(axis=1) <= self.disc * self.disc)

    def apply(self, reading: Reading, time: float, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        if "tag_corners" not in reading:
            return dict(reading)
        while time >= self.next_change:
            if self.active:
                self._end(self.next_change, rng)
            else:
                self._start(self.next_change, rng)
        if bool(np.asarray(reading.get("tag_detected", True))) and self.covered().any():
            return lost_tag(reading, REASON_OCCLUDED)
        return dict(reading)


def _step(name: str, value: Any, high: float, unit: str) -> tuple[float, NDArray[np.float64] | None]:
    """A bias step: a magnitude (random direction per episode) or a fixed 3-vector."""
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str):
        if len(value) != 3:
            raise TypeError(f"{name} must be a magnitude ({unit}) or 3 numbers, got {describe(value)}")
        vec = np.array(
            [check_real(f"{name}[{i}]", v, unit, low=-high, high=high) for i, v in enumerate(value)]
        )
        return float(np.linalg.norm(vec)), vec
    return check_non_negative(name, value, unit, high=high), None


@dataclass
class ImuBiasStep:
    """A step in the IMU's biases from the onset (a shock, a temperature jump): ``gyro`` (rad/s) is
    added to ``angular_velocity``, ``accel`` (m/s^2) to ``linear_acceleration`` (body frame). Each is
    a magnitude, in a direction drawn uniformly on the sphere per episode, or a fixed 3-vector; 0
    leaves that sensor alone. The attitude output (``quaternion``) is not changed."""

    gyro: float | Sequence[float] = 0.01
    accel: float | Sequence[float] = 0.0
    onset: float | Sequence[float] = (0.0, 10.0)
    start: float = field(default=0.0, init=False)
    gyro_step: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3), init=False)
    accel_step: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3), init=False)

    def __post_init__(self) -> None:
        self._gyro = _step("ImuBiasStep.gyro", self.gyro, MAX_GYRO_STEP, "rad/s")
        self._accel = _step("ImuBiasStep.accel", self.accel, MAX_ACCEL_STEP, "m/s^2")
        if self._gyro[0] == 0.0 and self._accel[0] == 0.0:
            raise ValueError("ImuBiasStep: gyro and accel are both 0: the fault would do nothing")
        self._window = check_onset("ImuBiasStep.onset", self.onset)

    def reset(self, rng: np.random.Generator) -> None:
        self.start = _draw_onset(self._window, rng)
        steps = []
        for magnitude, vec in (self._gyro, self._accel):
            if vec is not None:
                steps.append(vec.copy())
            else:
                u = rng.normal(size=3)
                steps.append(magnitude * u / max(float(np.linalg.norm(u)), 1e-12))
        self.gyro_step, self.accel_step = steps

    def apply(self, reading: Reading, time: float, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        out = dict(reading)
        if time < self.start:
            return out
        for key, step in (("angular_velocity", self.gyro_step), ("linear_acceleration", self.accel_step)):
            if key in out:
                v = np.asarray(out[key])
                out[key] = (v + step).astype(v.dtype)
        return out


__all__ = [
    "MAX_ACCEL_STEP",
    "MAX_GYRO_STEP",
    "MAX_ONSET_S",
    "N_TOF",
    "REASON_FRAME_LOST",
    "REASON_OCCLUDED",
    "TAG_SQUARE",
    "CameraDropout",
    "ImuBiasStep",
    "Reading",
    "TagOcclusion",
    "ToFDead",
    "ToFStuck",
    "check_onset",
    "check_tof_sensors",
    "lost_tag",
]
