"""The deck-landing task's configuration: every ``gym.make`` option, validated in one place.

:func:`make_config` takes the keyword arguments of ``gym.make("ihrcf_env/DeckLandingRaw-v0", ...)``
(the names and defaults of :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`) and returns a
:class:`DeckLandingConfig`, or raises TypeError (wrong type) / ValueError (out of range,
inconsistent) with the option's name in the message. It touches no PyBullet client: a bad option
fails before any physics client or temporary file exists.

A :class:`DeckLandingConfig` holds

* ``world``: the simulated world, :class:`~ihrcf_env.sim.world.WorldConfig` (control rate, camera,
  ToF, deck plate and tag, Stewart geometry, action mode);
* ``task``: :class:`TaskConfig`, i.e. the start distribution (:class:`StartDistribution`), the
  arena (:class:`Arena`), the deck motion (:class:`DeckMotion`), success/crash thresholds
  (:class:`Thresholds`), reward weights (:class:`RewardWeights`) and the velocity action scale;
* ``render_mode``, ``chase_size`` and ``disturbances``.

Each dataclass checks its own fields in ``__post_init__`` (messages name the ``gym.make`` option);
:class:`DeckLandingConfig` checks what involves several of them: the start altitudes against the
deck's highest reach and the arena's ceiling, the arena against the deck, the sea-state amplitudes
against the Stewart legs' stroke, the tag id.

Sensor realism: ``sensor_preset`` (``"ideal"``, the default and every result before the option
existed, bit for bit; or ``"realistic"``) chooses together the camera (``camera_quality``), the ToF
sensors (``tof_noise``: one ray, or the VL53L1X cone model), the IMU (``imu_noise``: BMI088
noise, biases and attitude-filter error) and the autopilot's feedback (``autopilot_feedback``:
``"truth"`` or a drifting GNSS/INS ``"estimated"`` state); see :data:`SENSOR_PRESETS`. Each of those
options, given, overrides the preset; ``tof_noise``, ``imu_noise`` and ``autopilot_feedback`` also
take their model's parameter dataclass (:class:`~ihrcf_env.sim.sensors.tof.VL53L1X`,
:class:`~ihrcf_env.sim.sensors.imu.IMUNoise`, :class:`~ihrcf_env.sim.navigation.NavigationErrors`)
or a dict of some of its parameters (overriding the realistic defaults, e.g.
``tof_noise={"ambient": 1.0}``); a bad parameter raises naming the option and the key.

Start altitude bounds: the drone's landing legs reach 0.10 m below its centre, and a tilted,
moving deck rises under a drone that is off its centre, so the lowest start (``start_altitude -
start_altitude_jitter``, or ``reset(options={"altitude": ...})``) must be at least
:data:`MIN_START_ALTITUDE` = 0.3 m above the deck origin, otherwise an episode could end (even
"successfully") at its first step. Note that below ~0.45 m (:data:`TAG_VIEW_ALTITUDE`) the
0.40 m tag no longer fits in the 60 deg camera's view, so the tag-based estimators cannot see it
there. The highest start, above the deck's highest possible position, must stay
:data:`CEILING_MARGIN` below ``arena_ceiling``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from numbers import Integral, Real
from typing import TYPE_CHECKING, Any, TypeVar

import cv2
import numpy as np

from ihrcf_env.core.profiles import (
    PROFILE_NAMES,
    MotionProfile,
    check_sea_state_amplitudes,
    make_profile,
    sea_state_amplitudes,
)
from ihrcf_env.sim.deck import DeckConfig
from ihrcf_env.sim.disturbances import Disturbance
from ihrcf_env.sim.navigation import FEEDBACK_MODES, NavigationConfig, NavigationErrors
from ihrcf_env.sim.sensors import TOF_PRESETS, CameraConfig, ToFConfig
from ihrcf_env.sim.sensors.camera import CAMERA_QUALITIES
from ihrcf_env.sim.sensors.imu import IMU_NOISE_PRESETS, IMUConfig, IMUNoise
from ihrcf_env.sim.sensors.tof import VL53L1X
from ihrcf_env.sim.world import ACTION_MODES, CAMERA_MODELS, CAMERA_OUTPUTS, WorldConfig

if TYPE_CHECKING:
    from ihrcf_env.core.detector_model import DetectorModel

#: Seconds of deck motion checked against the legs' stroke at reset when ``horizon_s`` is None.
DEFAULT_HORIZON_S = 600.0
#: Longest ``horizon_s`` (s): the check samples the profile at 20 Hz over the whole horizon.
MAX_HORIZON_S = 3600.0
#: Lowest start altitude above the deck origin (m): legs 0.10 m below the centre plus a tilted deck.
MIN_START_ALTITUDE = 0.3
#: Below about this altitude (m) the 0.40 m tag leaves the default camera's view.
TAG_VIEW_ALTITUDE = 0.45
#: The highest start stays this far (m) below ``arena_ceiling``.
CEILING_MARGIN = 0.5
#: ``arena_half_width`` exceeds the start offset and the deck's half size by at least this (m).
ARENA_MARGIN = 0.5
#: Largest chase-view image side (px).
MAX_CHASE_SIZE = 4096
RENDER_MODES: tuple[str, ...] = ("human", "rgb_array")
#: ``sensor_preset``: the model each preset selects for ``camera_quality``, ``tof_noise``,
#: ``imu_noise`` and ``autopilot_feedback`` (each option, given, overrides its preset).
SENSOR_PRESETS: dict[str, dict[str, str]] = {
    "ideal": {
        "camera_quality": "ideal",
        "tof_noise": "ideal",
        "imu_noise": "ideal",
        "autopilot_feedback": "truth",
    },
    "realistic": {
        "camera_quality": "realistic",
        "tof_noise": "realistic",
        "imu_noise": "realistic",
        "autopilot_feedback": "estimated",
    },
}


# -- type checks (each names the option) ------------------------------------------------------------
def _is_real(value: object) -> bool:
    return isinstance(value, Real) and not isinstance(value, bool | np.bool_)


def check_real(name: str, value: object, unit: str = "") -> float:
    """``value`` as a finite float; TypeError for non-numbers and bools, ValueError for NaN/inf."""
    if not _is_real(value):
        raise TypeError(f"{name} must be a real number{unit}, got {type(value).__name__} {value!r}")
    v = float(value)  # type: ignore[arg-type]
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite{unit}, got {value!r}")
    return v


def check_int(name: str, value: object) -> int:
    """``value`` as an int; TypeError for floats (even 20.0), strings and bools."""
    if not isinstance(value, Integral) or isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    return int(value)


def check_bool(name: str, value: object) -> bool:
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {type(value).__name__} {value!r}")
    return bool(value)


def check_reals(name: str, value: object, n: int, unit: str = "") -> tuple[float, ...]:
    """``value`` as a tuple of ``n`` finite floats (a sequence or 1-D array of real numbers)."""
    items = list(value) if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str) else None
    if items is None or len(items) != n:
        raise TypeError(f"{name} must be {n} real numbers{unit}, got {type(value).__name__} {value!r}")
    return tuple(check_real(f"{name}[{i}]", v, unit) for i, v in enumerate(items))


def check_str(name: str, value: object, choices: Sequence[str]) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {tuple(choices)}, got {type(value).__name__} {value!r}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {tuple(choices)}, got {value!r}")
    return value


def _positive(name: str, value: float, unit: str = "") -> None:
    if not value > 0:
        raise ValueError(f"{name} must be > 0{unit}, got {value!r}")


def _non_negative(name: str, value: float, unit: str = "") -> None:
    if not value >= 0:
        raise ValueError(f"{name} must be >= 0{unit}, got {value!r}")


def check_non_negative_fields(obj: object, name: Callable[[str], str]) -> None:
    """Check every field of the frozen dataclass ``obj`` is a finite real >= 0 (errors named by
    ``name(field)``) and store it as a float."""
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        v = check_real(name(f.name), getattr(obj, f.name))
        _non_negative(name(f.name), v)
        _set(obj, f.name, v)


def _set(obj: object, attr: str, value: object) -> None:
    """Normalise a field of a frozen dataclass in ``__post_init__``."""
    object.__setattr__(obj, attr, value)


# -- the task ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StartDistribution:
    """Seeded start of an episode relative to the deck frame origin: altitude uniform in
    ``altitude +- altitude_jitter`` (m), horizontal offset uniform in ``+-offset`` per world axis
    (m), yaw uniform in ``+-yaw`` (rad). Options ``start_altitude``, ``start_altitude_jitter``,
    ``start_offset``, ``start_yaw``."""

    altitude: float = 1.0
    altitude_jitter: float = 0.05
    offset: float = 0.1
    yaw: float = 0.2

    def __post_init__(self) -> None:
        _set(self, "altitude", check_real("start_altitude", self.altitude, " (m)"))
        _set(self, "altitude_jitter", check_real("start_altitude_jitter", self.altitude_jitter, " (m)"))
        _set(self, "offset", check_real("start_offset", self.offset, " (m)"))
        _set(self, "yaw", check_real("start_yaw", self.yaw, " (rad)"))
        _non_negative("start_altitude_jitter", self.altitude_jitter, " (m)")
        _non_negative("start_offset", self.offset, " (m)")
        if not 0 <= self.yaw <= math.pi:
            raise ValueError(f"start_yaw must be in [0, pi] (rad), got {self.yaw!r}")
        if self.lowest < MIN_START_ALTITUDE:
            raise ValueError(
                f"start_altitude - start_altitude_jitter = {self.altitude:g} - {self.altitude_jitter:g} m "
                f"is below the lowest allowed start, {MIN_START_ALTITUDE} m above the deck: the drone's "
                f"legs reach 0.10 m below its centre and a tilted deck rises under it, so an episode "
                f"could end at its first step (note: below ~{TAG_VIEW_ALTITUDE} m the tag also leaves "
                f"the camera's view)"
            )

    @property
    def lowest(self) -> float:
        return self.altitude - self.altitude_jitter

    @property
    def highest(self) -> float:
        return self.altitude + self.altitude_jitter


@dataclass(frozen=True)
class Arena:
    """The drone crashes ("left the arena") beyond ``+-half_width`` (m) in world x or y, or above
    ``ceiling`` (m, world z). Options ``arena_half_width``, ``arena_ceiling``."""

    half_width: float = 5.0
    ceiling: float = 6.0

    def __post_init__(self) -> None:
        _set(self, "half_width", check_real("arena_half_width", self.half_width, " (m)"))
        _set(self, "ceiling", check_real("arena_ceiling", self.ceiling, " (m)"))
        _positive("arena_half_width", self.half_width, " (m)")
        _positive("arena_ceiling", self.ceiling, " (m)")


@dataclass(frozen=True)
class Thresholds:
    """Touchdown on the deck is a success if the approach speed along the deck normal is below
    ``success_speed`` (m/s) and the drone-deck tilt below ``success_tilt`` (rad); a tilt over
    ``crash_tilt`` (rad) in flight is a crash."""

    success_speed: float = 0.5
    success_tilt: float = math.radians(10.0)
    crash_tilt: float = math.radians(60.0)

    def __post_init__(self) -> None:
        for name, unit in (("success_speed", " (m/s)"), ("success_tilt", " (rad)"), ("crash_tilt", " (rad)")):
            v = check_real(f"Thresholds.{name}", getattr(self, name), unit)
            _positive(f"Thresholds.{name}", v, unit)
            _set(self, name, v)
        if not self.success_tilt < self.crash_tilt <= math.pi:
            raise ValueError(
                f"Thresholds need success_tilt < crash_tilt <= pi, got {self.success_tilt}, {self.crash_tilt}"
            )


@dataclass(frozen=True)
class RewardWeights:
    """Per-step reward ``-position_xy |e_xy| - position_z max(e_z, 0) - velocity |v_rel| -
    attitude tilt - action |a|^2``, plus ``+success`` / ``-crash`` at the end (all weights >= 0)."""

    position_xy: float = 1.0
    position_z: float = 0.2
    velocity: float = 0.1
    attitude: float = 0.1
    action: float = 0.01
    success: float = 100.0
    crash: float = 100.0

    def __post_init__(self) -> None:
        check_non_negative_fields(self, lambda n: f"RewardWeights.{n}")


ProfileSpec = str | Callable[[float], Any] | MotionProfile


@dataclass(frozen=True)
class DeckMotion:
    """How the deck moves. Options ``deck_profile``, ``sea_state_amplitudes`` (only with
    ``"sea_state"``), ``random_deck_start`` (start at a seeded time in [0, 130) s of the profile)
    and ``horizon_s`` (seconds of motion checked against the legs' stroke at reset; beyond it the
    deck stops rather than fail mid-episode)."""

    profile: ProfileSpec = "paper"
    sea_state_amplitudes: Mapping[str, float] | None = None
    random_start: bool = False
    horizon_s: float = DEFAULT_HORIZON_S

    def __post_init__(self) -> None:
        prof = self.profile
        if isinstance(prof, str):
            check_str("deck_profile", prof, PROFILE_NAMES)
        elif not (isinstance(prof, MotionProfile) or callable(prof)):
            raise TypeError(
                f"deck_profile must be one of {PROFILE_NAMES}, a MotionProfile or a callable "
                f"t -> (offset (3,), rpy (3,)), got {type(prof).__name__} {prof!r}"
            )
        if self.sea_state_amplitudes is not None:
            if prof != "sea_state":
                raise ValueError(
                    f"sea_state_amplitudes is only used with deck_profile='sea_state', got "
                    f"deck_profile={prof!r}: drop it or choose 'sea_state'"
                )
            sea_state_amplitudes(self.sea_state_amplitudes)  # types, names, signs
            _set(self, "sea_state_amplitudes", dict(self.sea_state_amplitudes))
        _set(self, "random_start", check_bool("random_deck_start", self.random_start))
        h = check_real("horizon_s", self.horizon_s, " (s)")
        if not 0 < h <= MAX_HORIZON_S:
            raise ValueError(f"horizon_s must be in (0, {MAX_HORIZON_S:g}] s, got {self.horizon_s!r}")
        _set(self, "horizon_s", h)

    def make_profile(self, rng: np.random.Generator) -> MotionProfile:
        """This episode's profile (a sea state draws its periods and phases from ``rng``)."""
        return make_profile(self.profile, rng, self.sea_state_amplitudes)


@dataclass(frozen=True)
class TaskConfig:
    """The landing task: start, arena, deck motion, outcome thresholds, reward and action scale
    (``max_velocity``: m/s, m/s, m/s, rad/s per unit velocity action)."""

    start: StartDistribution = field(default_factory=StartDistribution)
    arena: Arena = field(default_factory=Arena)
    deck: DeckMotion = field(default_factory=DeckMotion)
    thresholds: Thresholds = field(default_factory=Thresholds)
    reward: RewardWeights = field(default_factory=RewardWeights)
    max_velocity: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        mv = check_reals("max_velocity", self.max_velocity, 4, " (m/s, m/s, m/s, rad/s)")
        if min(mv) <= 0:
            raise ValueError(f"max_velocity must be 4 positive numbers (m/s, m/s, m/s, rad/s), got {mv!r}")
        _set(self, "max_velocity", mv)
        if self.start.offset + ARENA_MARGIN > self.arena.half_width:
            raise ValueError(
                f"start_offset {self.start.offset:g} m must stay {ARENA_MARGIN} m inside arena_half_width "
                f"{self.arena.half_width:g} m"
            )


# -- everything ----------------------------------------------------------------------------------
@functools.cache
def apriltag_ids() -> int:
    """Number of tags in the AprilTag 36h11 family (valid ``tag_id`` 0 .. n - 1)."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    return int(dictionary.bytesList.shape[0])


@dataclass(frozen=True)
class DeckLandingConfig:
    """The whole configuration of a :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`."""

    world: WorldConfig = field(default_factory=WorldConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    render_mode: str | None = None
    chase_size: tuple[int, int] = (640, 480)
    disturbances: tuple[Disturbance, ...] = ()

    def __post_init__(self) -> None:
        if self.render_mode is not None:
            check_str("render_mode", self.render_mode, RENDER_MODES)
        size = self.chase_size
        if not (isinstance(size, Sequence | np.ndarray) and not isinstance(size, str) and len(size) == 2):
            raise TypeError(f"chase_size must be (width, height) in pixels, got {size!r}")
        w, h = check_int("chase_size[0]", size[0]), check_int("chase_size[1]", size[1])
        if not (0 < w <= MAX_CHASE_SIZE and 0 < h <= MAX_CHASE_SIZE):
            raise ValueError(
                f"chase_size must be (width, height) in [1, {MAX_CHASE_SIZE}] pixels, got {size!r}"
            )
        _set(self, "chase_size", (w, h))
        if isinstance(self.disturbances, str | Disturbance) or not isinstance(self.disturbances, Sequence):
            raise TypeError(f"disturbances must be a sequence of Disturbance, got {self.disturbances!r}")
        for d in self.disturbances:
            if not isinstance(d, Disturbance):
                raise TypeError(
                    f"disturbances: {d!r} is not a Disturbance "
                    "(reset(rng) and __call__(t, position, velocity))"
                )
        _set(self, "disturbances", tuple(self.disturbances))

        deck = self.world.deck
        tag_id = check_int("tag_id", deck.tag_id)
        if not 0 <= tag_id < apriltag_ids():
            raise ValueError(f"tag_id must be in [0, {apriltag_ids() - 1}] for AprilTag 36h11, got {tag_id}")
        task = self.task
        if task.arena.half_width < deck.size / 2 + ARENA_MARGIN:
            raise ValueError(
                f"arena_half_width {task.arena.half_width:g} m must exceed the deck's half size "
                f"({deck.size / 2:g} m) by {ARENA_MARGIN} m"
            )
        top = self.max_start_altitude
        if task.start.highest > top:
            raise ValueError(
                f"start_altitude + start_altitude_jitter = {task.start.highest:g} m above the deck would "
                f"start within {CEILING_MARGIN} m of arena_ceiling {task.arena.ceiling:g} m (the deck "
                f"origin reaches up to {self.deck_reach:.3f} m): the highest start allowed is "
                f"{top:.3f} m; lower start_altitude or raise arena_ceiling"
            )
        if task.deck.profile == "sea_state":
            check_sea_state_amplitudes(task.deck.sea_state_amplitudes, self.world.stewart)

    @property
    def deck_reach(self) -> float:
        """Upper bound (m, world z) of the deck origin: top joints at most ``max_leg`` above the base
        joints, the origin at most ``joint_depth`` above their centroid."""
        g = self.world.stewart
        return g.base_height + g.max_leg + g.joint_depth

    @property
    def max_start_altitude(self) -> float:
        """Highest start altitude above the deck origin (m) that stays clear of the ceiling."""
        return self.task.arena.ceiling - CEILING_MARGIN - self.deck_reach


T = TypeVar("T")


def _build(cls: type[T], options: Mapping[str, tuple[str, object]], **fixed: object) -> T:
    """``cls(**fields)`` from ``{option name: (field name, value)}``; a ValueError/TypeError of the
    dataclass' own checks is re-raised with the option's name in front (each option is first tried
    alone, so the error is pinned on the right one)."""
    for option, (attr, value) in options.items():
        try:
            cls(**{attr: value})
        except (TypeError, ValueError) as e:
            msg = str(e)
            raise type(e)(msg if option in msg else f"{option}: {msg}") from None
    return cls(**{attr: value for attr, value in options.values()}, **fixed)


M = TypeVar("M")


def model_option(
    name: str,
    value: object,
    preset: str,
    names: Sequence[str],
    cls: type[M],
    default: M,
) -> str | M:
    """A sensor-model option: None (the ``sensor_preset``'s choice ``preset``), one of ``names``, an
    instance of the parameter dataclass ``cls``, or a mapping of some of its parameters (overrides of
    ``default``, the realistic model). Bad names or parameters raise naming ``name`` (and the key)."""
    if value is None:
        return preset
    if isinstance(value, str):
        return check_str(name, value, names)
    if isinstance(value, cls):
        return value
    if isinstance(value, Mapping):
        known = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        for key, v in value.items():
            if key not in known:
                raise ValueError(f"{name} has no parameter {key!r}; known: {', '.join(known)}")
            try:
                dataclasses.replace(default, **{key: v})  # type: ignore[type-var]
            except (TypeError, ValueError) as e:
                raise type(e)(f"{name}[{key!r}]: {e}") from None
        return dataclasses.replace(default, **value)  # type: ignore[type-var]
    raise TypeError(
        f"{name} must be one of {tuple(names)}, a {cls.__name__} or a dict of its parameters, "
        f"got {type(value).__name__} {value!r}"
    )


def _camera_options(
    has_camera: bool,
    camera_model: object,
    camera_output: object,
    camera_hz: object,
    detector_model: object,
    control_hz: object,
) -> tuple[str, str, int | None, DetectorModel | None]:
    """Checked (camera_model, camera_output, camera_hz, detector model) of :func:`make_config`.

    ``camera_output`` None means ``"image"`` for the rendered camera and ``"corners"`` for the
    projected one; the projected model's detector model is loaded here (the shipped file for None,
    or a path), so a missing or corrupt file fails before any physics client exists."""
    model = check_str("camera_model", camera_model, CAMERA_MODELS)
    output = model_default = "corners" if model == "projected" else "image"
    if camera_output is not None:
        output = check_str("camera_output", camera_output, CAMERA_OUTPUTS)
    if model == "projected" and output == "image":
        raise ValueError(
            'camera_output="image" is impossible with camera_model="projected" (no image is rendered; '
            'it delivers the tag corners): drop camera_output or use camera_model="rendered"'
        )
    hz: int | None = None
    if camera_hz is not None:
        hz = check_int("camera_hz", camera_hz)
        rate = check_int("control_hz", control_hz)
        if hz <= 0 or rate % hz != 0:
            raise ValueError(f"camera_hz must be a positive divisor of control_hz ({rate}) in Hz, got {hz!r}")
    if not has_camera:
        given = [
            n
            for n, v, d in (
                ("camera_model", model, "rendered"),
                ("camera_output", camera_output, None),
                ("camera_hz", camera_hz, None),
                ("detector_model", detector_model, None),
            )
            if v != d
        ]
        if given:
            raise ValueError(
                f"{', '.join(given)} has no effect with camera=False: drop it or turn the camera on"
            )
        return model, model_default, None, None
    if detector_model is None and model != "projected":
        return model, output, hz, None
    from ihrcf_env.core.detector_model import DetectorModel, default_detector_model_path

    detector: DetectorModel | None = None
    if detector_model is not None:
        if model != "projected":
            raise ValueError('detector_model is used only by camera_model="projected": drop it')
        if isinstance(detector_model, DetectorModel):
            detector = detector_model
        elif isinstance(detector_model, str | os.PathLike):
            detector = DetectorModel.load(detector_model)
        else:
            raise TypeError(
                "detector_model must be a DetectorModel, a path to a detector-model file or None, got "
                f"{type(detector_model).__name__} {detector_model!r}"
            )
    elif model == "projected":
        detector = DetectorModel.load(default_detector_model_path())
    return model, output, hz, detector


def make_config(
    *,
    render_mode: str | None = None,
    action_mode: str = "velocity",
    control_hz: int = 20,
    deck_profile: ProfileSpec = "paper",
    sea_state_amplitudes: Mapping[str, float] | None = None,
    random_deck_start: bool = False,
    camera: bool = True,
    camera_width: int = 512,
    camera_height: int = 512,
    camera_fov: float = math.radians(60.0),
    camera_distortion: tuple[float, float] = (0.0, 0.0),
    camera_model: str = "rendered",
    camera_output: str | None = None,
    camera_hz: int | None = None,
    detector_model: str | os.PathLike[str] | DetectorModel | None = None,
    sensor_preset: str = "ideal",
    camera_quality: str | None = None,
    tof_noise: str | Mapping[str, Any] | VL53L1X | None = None,
    imu_noise: str | Mapping[str, Any] | IMUNoise | None = None,
    autopilot_feedback: str | Mapping[str, Any] | NavigationErrors | None = None,
    tof_max_range: float = 4.0,
    tag_id: int = 0,
    tag_size: float = 0.4,
    start_altitude: float = 1.0,
    start_altitude_jitter: float = 0.05,
    start_offset: float = 0.1,
    start_yaw: float = 0.2,
    max_velocity: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
    arena_half_width: float = 5.0,
    arena_ceiling: float = 6.0,
    horizon_s: float | None = None,
    chase_size: tuple[int, int] = (640, 480),
    disturbances: Sequence[Disturbance] = (),
) -> DeckLandingConfig:
    """The configuration for the options of ``DeckLandingEnv`` (same names, same defaults; see the
    module docstring and the README's options table). Raises TypeError / ValueError naming the
    option. ``disturbances`` are deep-copied: every env gets its own."""
    has_camera = check_bool("camera", camera)
    distortion = check_reals("camera_distortion", camera_distortion, 2)
    if not has_camera and any(distortion):
        raise ValueError(
            f"camera_distortion {camera_distortion!r} has no effect with camera=False: drop it or "
            "turn the camera on"
        )
    cam_model, cam_output, cam_hz, detector = _camera_options(
        has_camera, camera_model, camera_output, camera_hz, detector_model, control_hz
    )
    preset = SENSOR_PRESETS[check_str("sensor_preset", sensor_preset, tuple(SENSOR_PRESETS))]
    quality = (
        preset["camera_quality"]
        if camera_quality is None
        else check_str("camera_quality", camera_quality, CAMERA_QUALITIES)
    )
    if camera_quality is not None and camera_quality != "ideal" and not has_camera:
        raise ValueError(
            f"camera_quality {camera_quality!r} has no effect with camera=False: drop it or turn the "
            "camera on"
        )
    cam = None
    if has_camera:
        cam = _build(
            CameraConfig,
            {
                "camera_width": ("width", check_int("camera_width", camera_width)),
                "camera_height": ("height", check_int("camera_height", camera_height)),
                "camera_fov": ("fov", check_real("camera_fov", camera_fov, " (rad)")),
                "camera_distortion": ("distortion", distortion),
                "camera_quality": ("quality", quality),
            },
        )
    tof_model = model_option(
        "tof_noise", tof_noise, preset["tof_noise"], tuple(TOF_PRESETS), VL53L1X, VL53L1X()
    )
    tof = _build(
        ToFConfig,
        {
            "tof_max_range": ("max_range", check_real("tof_max_range", tof_max_range, " (m)")),
            "tof_noise": ("noise", tof_model),
        },
    )
    imu = IMUConfig(
        model_option("imu_noise", imu_noise, preset["imu_noise"], IMU_NOISE_PRESETS, IMUNoise, IMUNoise())
    )
    navigation = NavigationConfig(
        model_option(
            "autopilot_feedback",
            autopilot_feedback,
            preset["autopilot_feedback"],
            FEEDBACK_MODES,
            NavigationErrors,
            NavigationErrors(),
        )
    )
    deck = _build(
        DeckConfig,
        {
            "tag_id": ("tag_id", check_int("tag_id", tag_id)),
            "tag_size": ("tag_size", check_real("tag_size", tag_size, " (m)")),
        },
    )
    world = _build(
        WorldConfig,
        {
            "control_hz": ("control_hz", check_int("control_hz", control_hz)),
            "action_mode": ("action_mode", check_str("action_mode", action_mode, ACTION_MODES)),
        },
        camera=cam,
        tof=tof,
        imu=imu,
        navigation=navigation,
        deck=deck,
        camera_model=cam_model,
        camera_output=cam_output,
        camera_hz=cam_hz,
        detector_model=detector,
    )
    task = TaskConfig(
        start=StartDistribution(start_altitude, start_altitude_jitter, start_offset, start_yaw),
        arena=Arena(arena_half_width, arena_ceiling),
        deck=DeckMotion(
            deck_profile,
            sea_state_amplitudes,
            random_deck_start,
            DEFAULT_HORIZON_S if horizon_s is None else horizon_s,
        ),
        max_velocity=max_velocity,
    )
    cfg = DeckLandingConfig(
        world=world,
        task=task,
        render_mode=render_mode,
        chase_size=chase_size,
        disturbances=disturbances,  # type: ignore[arg-type]  # checked, made a tuple
    )
    return dataclasses.replace(cfg, disturbances=copy.deepcopy(cfg.disturbances)) if cfg.disturbances else cfg
