"""The one path of the options: ``gym.make`` keyword arguments -> a validated :class:`DeckLandingConfig`.

:func:`make_config` takes every option of every deck task (the env's, the task's and the observation
wrappers') and returns a :class:`DeckLandingConfig`, or raises TypeError (wrong kind) / ValueError
(out of range, inconsistent, absurd magnitude) naming the option. It touches no PyBullet client: a
bad option fails before any physics client or temporary file exists. The env takes the config; each
component gets its typed part:

* ``world``: :class:`~ihrcf_env.sim.world.WorldConfig` (control rate, camera, ToF, IMU, autopilot
  feedback, deck plate and tag, Stewart geometry, action mode);
* ``task``: :class:`~ihrcf_env.envs.task_config.TaskConfig` (start, arena, deck motion, thresholds,
  rewards, and the landing goal of the landing task);
* ``observation``: :class:`ObservationConfig` (the estimator wrappers' options, the calibration
  loaded and checked against the camera);
* ``wind`` (:class:`~ihrcf_env.sim.disturbances.WindParams` or None), ``disturbances``,
  ``render_mode``, ``chase_size``.

``task`` names the task whose defaults apply (:data:`TASK_DEFAULTS`): ``"hover"`` (the paper's
hover-and-track experiment, ``ihrcf_env/DeckHover-v0``) or ``"landing-v1"``
(``ihrcf_env/DeckLanding-v1``). Options of one task only (:data:`LANDING_OPTIONS`,
:data:`HOVER_OPTIONS`) are refused by the other.

Sensor realism: ``sensor_preset`` (``"ideal"`` or ``"realistic"``) chooses together the camera
(``camera_quality``), the ToF sensors (``tof_noise``: one ray, or the VL53L1X cone model), the IMU
(``imu_noise``) and the autopilot's feedback (``autopilot_feedback``: ``"truth"`` or a drifting
GNSS/INS ``"estimated"`` state); see :data:`SENSOR_PRESETS`. Each of those options, given,
overrides the preset; ``tof_noise``, ``imu_noise`` and ``autopilot_feedback`` also take their
model's parameter dataclass or a dict of some of its parameters (overriding the realistic
defaults, e.g. ``tof_noise={"ambient": 1.0}``).

Start altitude bounds: the lowest start must be :data:`MIN_START_ALTITUDE` above the deck origin
(legs 0.10 m below the drone's centre, a tilted deck rising under it); the highest start, above
the deck's highest reach, must stay :data:`CEILING_MARGIN` below ``arena_ceiling``.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

import cv2
import numpy as np

from ihrcf_env.core.batch.pipeline import BATCHED, batchable_names
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.checks import (
    check_bool,
    check_int,
    check_positive,
    check_real,
    check_reals,
    check_str,
    describe,
    from_fields,
    set_field,
)
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS, FusedParams, check_estimator_names
from ihrcf_env.core.profiles import check_sea_state_amplitudes
from ihrcf_env.core.ship import ShipOptions
from ihrcf_env.envs.levels import DEFAULT_LEVEL, LEVELS
from ihrcf_env.envs.task_config import (
    ARENA_MARGIN,
    CEILING_MARGIN,
    DEFAULT_HORIZON_S,
    MIN_START_ALTITUDE,
    Arena,
    DeckMotion,
    LandingGoal,
    ProfileSpec,
    RewardWeightsV1,
    StartDistribution,
    TaskConfig,
    Thresholds,
)
from ihrcf_env.sim.deck import DeckConfig
from ihrcf_env.sim.disturbances import Disturbance, WindParams
from ihrcf_env.sim.drone import VelocityGains
from ihrcf_env.sim.navigation import FEEDBACK_MODES, NavigationConfig, NavigationErrors
from ihrcf_env.sim.registry import (
    check_faults,
    check_measurement_noise,
    check_sensor_names,
    world_measurements,
)
from ihrcf_env.sim.sensors import TOF_PRESETS, CameraConfig, ToFConfig
from ihrcf_env.sim.sensors.camera import CAMERA_QUALITIES, PIPELINE_LATENCY
from ihrcf_env.sim.sensors.imu import IMU_NOISE_PRESETS, IMUConfig, IMUNoise
from ihrcf_env.sim.sensors.tof import MAX_RANGE_BOUNDS as TOF_RANGES
from ihrcf_env.sim.sensors.tof import VL53L1X
from ihrcf_env.sim.world import ACTION_MODES, CAMERA_MODELS, CAMERA_OUTPUTS, WorldConfig

if TYPE_CHECKING:
    from ihrcf_env.core.detector_model import DetectorModel

__all__ = [
    "ARENA_MARGIN",
    "CEILING_MARGIN",
    "DEFAULT_HORIZON_S",
    "MIN_START_ALTITUDE",
    "DeckLandingConfig",
    "ObservationConfig",
    "make_config",
]

#: Largest chase-view image side (px).
MAX_CHASE_SIZE = 4096
#: Largest camera image side (px).
MAX_IMAGE_SIZE = 4096
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
#: The landing tasks' start and sensors: 1.5-3 m up, any yaw, a 1 m offset disc, realistic sensors.
_LANDING_START: dict[str, Any] = {
    "random_deck_start": True,
    "sensor_preset": "realistic",
    "start_altitude": 2.25,
    "start_altitude_jitter": 0.75,
    "start_offset": 1.0,
    "start_yaw": math.pi,
}
#: The defaults that differ between the tasks (an option left at None takes its task's value).
TASK_DEFAULTS: dict[str, dict[str, Any]] = {
    "hover": {
        "deck_profile": "paper",
        "random_deck_start": False,
        "sensor_preset": "ideal",
        "start_altitude": 1.0,
        "start_altitude_jitter": 0.05,
        "start_offset": 0.1,
        "start_yaw": 0.2,
        "start_trimmed": False,
        "wind": False,
        "autopilot": "classic",
        "ground_effect": False,
        "camera_latency": 0.0,
        "tof_hz": None,
    },
    "landing-v1": {
        **_LANDING_START,
        "deck_profile": "sea_state",
        "start_trimmed": False,
        "wind": True,
        "autopilot": "classic",
        "ground_effect": False,
        "camera_latency": 0.0,
        "tof_hz": None,
    },
    # the deck and the wind come from the level (envs/levels.py)
    "landing-v2": {
        **_LANDING_START,
        "start_trimmed": True,
        "autopilot": "wind_hold",
        "ground_effect": True,
        "camera_latency": PIPELINE_LATENCY,
        "tof_hz": 30.0,
    },
}
#: Touchdown limits of the landing task v2: a drone holding position in a 12-15 m/s wind leans
#: 17-20 deg into it, so the relative tilt allowed at touchdown is 20 deg (v1: 10 deg).
V2_THRESHOLDS = Thresholds(success_tilt=math.radians(20.0))
#: Options of the landing tasks only.
LANDING_OPTIONS: tuple[str, ...] = (
    "success_radius",
    "start_in_view",
    "view_margin",
    "reward_weights",
    "privileged",
    "deck_motion",
    "batch_estimators",
)
#: Options of the hover task only (its observation wrapper's).
HOVER_OPTIONS: tuple[str, ...] = ("keep_image", "flatten")
#: ``autopilot``: the classic position loop, or the wind-holding one (anti-windup and a
#: disturbance observer, :class:`~ihrcf_env.sim.drone.VelocityController`).
AUTOPILOTS: tuple[str, ...] = ("classic", "wind_hold")
#: Largest IHRCF rigid-fit residual threshold (m).
MAX_RESIDUAL = 1.0


def level_faults(faults: Mapping[str, Any] | None, has_camera: bool) -> Mapping[str, Any] | None:
    """A level's default ``faults``, less the camera's when the world has no camera."""
    if faults is None or has_camera:
        return faults
    return {k: v for k, v in faults.items() if k != "camera_dropout"}


def fused_params_for_tof(model: VL53L1X | None, task: str = "") -> FusedParams:
    """The fused filter's parameters for the env's ToF model: with the VL53L1X model (per-sensor
    constant offsets of sigma ``offset_sigma``) a common-mode range-offset state of prior sigma
    ``offset_sigma / 2`` (the mean of four independent offsets); the ideal ToF (None): none. On
    ``task="landing-v2"`` (a ship deck, Froude-scaled: full-scale accelerations at a few times the
    frequency) the position also restarts at agreeing measurements (``reseed_agreeing``)."""
    offset = 0.0 if model is None or model.offset_sigma <= 0 else model.offset_sigma / 2
    return FusedParams(range_offset_sigma=offset, reseed_agreeing=task == "landing-v2")


@dataclass(frozen=True)
class ObservationConfig:
    """What the estimator wrappers observe (:mod:`ihrcf_env.wrappers`).

    ``raw``: no wrapper (the raw env's Dict observation); ``calibration``: the loaded calibration
    (None when raw or without a camera), checked against the camera; ``keep_image`` / ``flatten``:
    the hover task's wrapper options; ``max_residual`` (m): IHRCF's rigid-fit threshold;
    ``estimators``: registered names, in order; ``fused_params``: the fused filter's parameters
    (from :func:`make_config`: resolved from the ToF model when not given); ``privileged`` /
    ``deck_motion``: the landing task's flat observation options; ``batch_estimators``: run the
    estimators through their batched form (:mod:`ihrcf_env.core.batch.pipeline`) with one row, the
    arithmetic of a vector env's batched sub-envs."""

    raw: bool = False
    calibration: Calibration | None = None
    keep_image: bool | None = None
    flatten: bool = False
    max_residual: float = 0.01
    estimators: tuple[str, ...] = DEFAULT_ESTIMATORS
    fused_params: FusedParams | None = None
    privileged: bool = False
    deck_motion: bool = False
    batch_estimators: bool = False


def load_calibration(calibration: object) -> Calibration:
    """The calibration itself, the file at a path, or the shipped file for None (TypeError naming
    ``calibration`` for anything else; the file's CalibrationError for a bad file)."""
    if isinstance(calibration, Calibration):
        return calibration
    if calibration is None:
        return Calibration.load(default_calibration_path())
    if isinstance(calibration, str | os.PathLike):
        return Calibration.load(calibration)
    raise TypeError(
        "calibration must be a Calibration, a path (str or os.PathLike) to a calibration file, or "
        f"None for the shipped file; got {describe(calibration)}"
    )


def observation_options(
    *,
    raw: object = False,
    calibration: object = None,
    keep_image: object = None,
    flatten: object = False,
    max_residual: object = 0.01,
    estimators: object = DEFAULT_ESTIMATORS,
    fused_params: object = None,
    privileged: object = False,
    deck_motion: object = False,
    batch_estimators: object = False,
) -> ObservationConfig:
    """The wrapper options' type and range checks (no file read): an :class:`ObservationConfig`
    without its calibration, ``fused_params`` None when not given."""
    is_raw = check_bool("raw", raw)
    if calibration is not None and not isinstance(calibration, Calibration | str | os.PathLike):
        raise TypeError(
            "calibration must be a Calibration, a path (str or os.PathLike) to a calibration file, or "
            f"None for the shipped file; got {describe(calibration)}"
        )
    keep = None if keep_image is None else check_bool("keep_image", keep_image)
    flat = check_bool("flatten", flatten)
    residual = check_positive("max_residual", max_residual, "m", high=MAX_RESIDUAL)
    names = check_estimator_names(estimators)  # type: ignore[arg-type]
    if fused_params is not None and not isinstance(fused_params, FusedParams):
        raise TypeError(
            "fused_params must be an ihrcf_env.core.estimators.FusedParams or None, got "
            f"{describe(fused_params)}"
        )
    priv = check_bool("privileged", privileged)
    motion = check_bool("deck_motion", deck_motion)
    if motion and "fused" not in names:
        raise ValueError(
            f"deck_motion needs the fused estimator (estimators must include 'fused'), got {names}"
        )
    batch = check_bool("batch_estimators", batch_estimators)
    if batch and not batchable_names(names):
        raise ValueError(
            f"batch_estimators: the batched form covers the built-in estimators {sorted(BATCHED)} "
            f"only, got {list(names)}"
        )
    if is_raw:
        given = [
            n
            for n, v, d in (
                ("keep_image", keep, None),
                ("flatten", flat, False),
                ("privileged", priv, False),
                ("deck_motion", motion, False),
                ("batch_estimators", batch, False),
                ("calibration", calibration, None),
                ("fused_params", fused_params, None),
            )
            if v != d
        ]
        if given:
            raise ValueError(f"{', '.join(given)}: observation-wrapper options have no effect with raw=True")
    return ObservationConfig(
        raw=is_raw,
        keep_image=keep,
        flatten=flat,
        max_residual=residual,
        estimators=names,
        fused_params=fused_params,
        privileged=priv,
        deck_motion=motion,
        batch_estimators=batch,
    )


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
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    render_mode: str | None = None
    chase_size: tuple[int, int] = (640, 480)
    disturbances: tuple[Disturbance, ...] = ()
    wind: WindParams | None = None

    def __post_init__(self) -> None:
        if self.render_mode is not None:
            check_str("render_mode", self.render_mode, RENDER_MODES)
        size = self.chase_size
        if not (isinstance(size, Sequence | np.ndarray) and not isinstance(size, str) and len(size) == 2):
            raise TypeError(f"chase_size must be (width, height) in pixels, got {size!r}")
        w = check_int("chase_size[0]", size[0], low=1, high=MAX_CHASE_SIZE)
        h = check_int("chase_size[1]", size[1], low=1, high=MAX_CHASE_SIZE)
        set_field(self, "chase_size", (w, h))
        if isinstance(self.disturbances, str | Disturbance) or not isinstance(self.disturbances, Sequence):
            raise TypeError(f"disturbances must be a sequence of Disturbance, got {self.disturbances!r}")
        for d in self.disturbances:
            if not isinstance(d, Disturbance):
                raise TypeError(
                    f"disturbances: {d!r} is not a Disturbance "
                    "(reset(rng) and __call__(t, position, velocity))"
                )
        set_field(self, "disturbances", tuple(self.disturbances))
        if self.wind is not None and not isinstance(self.wind, WindParams):
            raise TypeError(f"wind must be WindParams or None, got {describe(self.wind)}")

        deck = self.world.deck
        check_int("tag_id", deck.tag_id, low=0, high=apriltag_ids() - 1)
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


M = TypeVar("M")


def model_option(
    name: str, value: object, preset: str, names: Sequence[str], cls: type[M], default: M
) -> str | M:
    """A sensor-model option: None (the ``sensor_preset``'s choice ``preset``), one of ``names``, an
    instance of the parameter dataclass ``cls``, or a mapping of some of its parameters (overrides of
    ``default``, the realistic model). Bad names or parameters raise naming ``name`` (and the key)."""
    if value is None:
        return preset
    if isinstance(value, str):
        return check_str(name, value, names)
    if isinstance(value, cls | Mapping):
        return from_fields(name, cls, value, default)
    raise TypeError(
        f"{name} must be one of {tuple(names)}, a {cls.__name__} or a dict of its parameters, "
        f"got {describe(value)}"
    )


def _built(option: str, build: Any, *args: Any, **kwargs: Any) -> Any:
    """``build(*args, **kwargs)`` with the option's name in front of a TypeError / ValueError."""
    try:
        return build(*args, **kwargs)
    except (TypeError, ValueError) as e:
        msg = str(e)
        raise type(e)(msg if option in msg else f"{option}: {msg}") from None


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
        hz = check_int("camera_hz", camera_hz, low=1, high=10_000)
        rate = check_int("control_hz", control_hz, low=1, high=10_000)
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


def _wind_option(wind: object) -> WindParams | None:
    """``wind``: True (the default :class:`WindParams`), False or None (calm), a WindParams or a dict
    of some of its fields."""
    if wind is None or isinstance(wind, bool | np.bool_):
        return WindParams() if wind else None
    return from_fields("wind", WindParams, wind)


def make_config(
    *,
    task: str = "hover",
    render_mode: str | None = None,
    action_mode: str = "velocity",
    level: str | None = None,
    autopilot: str | None = None,
    ground_effect: bool | None = None,
    physics: str = "pybullet",
    control_hz: int = 20,
    deck_profile: ProfileSpec | None = None,
    sea_state_amplitudes: Mapping[str, float] | None = None,
    ship: ShipOptions | Mapping[str, Any] | None = None,
    random_deck_start: bool | None = None,
    camera: bool = True,
    camera_width: int = 512,
    camera_height: int = 512,
    camera_fov: float = math.radians(60.0),
    camera_distortion: tuple[float, float] = (0.0, 0.0),
    camera_model: str = "rendered",
    camera_output: str | None = None,
    camera_hz: int | None = None,
    camera_latency: float | None = None,
    tof_hz: float | None = None,
    imu_hz: float | None = None,
    detector_model: str | os.PathLike[str] | DetectorModel | None = None,
    sensor_preset: str | None = None,
    camera_quality: str | None = None,
    tof_noise: str | Mapping[str, Any] | VL53L1X | None = None,
    imu_noise: str | Mapping[str, Any] | IMUNoise | None = None,
    autopilot_feedback: str | Mapping[str, Any] | NavigationErrors | None = None,
    tof_max_range: float = 4.0,
    tag_id: int = 0,
    tag_size: float = 0.4,
    start_altitude: float | None = None,
    start_altitude_jitter: float | None = None,
    start_offset: float | None = None,
    start_yaw: float | None = None,
    start_trimmed: bool | None = None,
    max_velocity: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
    arena_half_width: float = 5.0,
    arena_ceiling: float = 6.0,
    horizon_s: float | None = None,
    chase_size: tuple[int, int] = (640, 480),
    wind: bool | WindParams | Mapping[str, Any] | None = None,
    disturbances: Sequence[Disturbance] = (),
    sensors: Sequence[str] = (),
    measurement_noise: Mapping[str, str] | None = None,
    faults: Mapping[str, Any] | None = None,
    success_radius: float | None = None,
    start_in_view: bool | None = None,
    view_margin: float | None = None,
    reward_weights: RewardWeightsV1 | Mapping[str, float] | None = None,
    raw: bool = False,
    calibration: Calibration | str | os.PathLike[str] | None = None,
    keep_image: bool | None = None,
    flatten: bool = False,
    max_residual: float = 0.01,
    estimators: Sequence[str] = DEFAULT_ESTIMATORS,
    fused_params: FusedParams | None = None,
    privileged: bool = False,
    deck_motion: bool = False,
    batch_estimators: bool = False,
) -> DeckLandingConfig:
    """The validated configuration of a deck task (module docstring). Options left at None take
    ``task``'s default (:data:`TASK_DEFAULTS`). Raises TypeError / ValueError naming the option.
    ``disturbances`` are deep-copied: every env gets its own."""
    defaults = dict(TASK_DEFAULTS[check_str("task", task, tuple(TASK_DEFAULTS))])
    landing = task != "hover"
    if task == "landing-v2":
        defaults.update(
            LEVELS[check_str("level", DEFAULT_LEVEL if level is None else level, tuple(LEVELS))].defaults()
        )
    elif level is not None:
        raise ValueError("level is an option of the landing task v2 (ihrcf_env/DeckLanding-v2) only")

    def pick(name: str, value: Any) -> Any:
        return defaults[name] if value is None else value

    obs = observation_options(
        raw=raw,
        calibration=calibration,
        keep_image=keep_image,
        flatten=flatten,
        max_residual=max_residual,
        estimators=estimators,
        fused_params=fused_params,
        privileged=privileged,
        deck_motion=deck_motion,
        batch_estimators=batch_estimators,
    )
    is_raw = obs.raw
    given = {
        "success_radius": success_radius,
        "start_in_view": start_in_view,
        "view_margin": view_margin,
        "reward_weights": reward_weights,
        "privileged": privileged or None,
        "deck_motion": deck_motion or None,
        "batch_estimators": batch_estimators or None,
        "keep_image": keep_image,
        "flatten": flatten or None,
    }
    wrong = [n for n in (HOVER_OPTIONS if landing else LANDING_OPTIONS) if given[n] is not None]
    if wrong:
        other = (
            "hover task (ihrcf_env/DeckHover-v0)" if landing else "landing task (ihrcf_env/DeckLanding-v1)"
        )
        raise ValueError(f"{', '.join(wrong)}: option(s) of the {other} only")

    has_camera = check_bool("camera", camera)
    if (
        has_camera
        and not is_raw
        and camera_output is None
        and (landing or obs.keep_image is False or obs.flatten)
    ):
        camera_output = "corners"  # no image in the observation: the rendered camera renders the tag window
    distortion = check_reals("camera_distortion", camera_distortion, 2, low=-1.0, high=1.0)
    if not has_camera and any(distortion):
        raise ValueError(
            f"camera_distortion {camera_distortion!r} has no effect with camera=False: drop it or "
            "turn the camera on"
        )
    rate = check_int("control_hz", control_hz, low=1, high=1000)
    cam_model, cam_output, cam_hz, detector = _camera_options(
        has_camera, camera_model, camera_output, camera_hz, detector_model, rate
    )
    preset_name = check_str("sensor_preset", pick("sensor_preset", sensor_preset), tuple(SENSOR_PRESETS))
    preset = SENSOR_PRESETS[preset_name]
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
        cam = _built(
            "camera options",
            CameraConfig,
            width=check_int("camera_width", camera_width, low=16, high=MAX_IMAGE_SIZE),
            height=check_int("camera_height", camera_height, low=16, high=MAX_IMAGE_SIZE),
            fov=check_real("camera_fov", camera_fov, "rad", low=math.radians(5), high=math.radians(170)),
            distortion=distortion,
            quality=quality,
            latency=pick("camera_latency", camera_latency),
        )
    tof_model = model_option(
        "tof_noise", tof_noise, preset["tof_noise"], tuple(TOF_PRESETS), VL53L1X, VL53L1X()
    )
    max_range = check_real("tof_max_range", tof_max_range, "m", low=TOF_RANGES[0], high=TOF_RANGES[1])
    tof = _built("tof_hz", ToFConfig, max_range=max_range, noise=tof_model, rate_hz=pick("tof_hz", tof_hz))
    imu = _built(
        "imu_hz",
        IMUConfig,
        model_option("imu_noise", imu_noise, preset["imu_noise"], IMU_NOISE_PRESETS, IMUNoise, IMUNoise()),
        rate_hz=imu_hz,
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
    deck = _built(
        "tag_size",
        DeckConfig,
        tag_id=check_int("tag_id", tag_id, low=0, high=apriltag_ids() - 1),
        tag_size=check_positive("tag_size", tag_size, "m", high=10.0),
    )
    extra = check_sensor_names(sensors)
    world = WorldConfig(
        gains=VelocityGains(
            wind_hold=check_str("autopilot", pick("autopilot", autopilot), AUTOPILOTS) == "wind_hold"
        ),
        ground_effect=check_bool("ground_effect", pick("ground_effect", ground_effect)),
        physics=physics,
        control_hz=rate,
        action_mode=check_str("action_mode", action_mode, ACTION_MODES),
        camera=cam,
        tof=tof,
        imu=imu,
        navigation=navigation,
        deck=deck,
        camera_model=cam_model,
        camera_output=cam_output,
        camera_hz=cam_hz,
        detector_model=detector,
        extra_sensors=extra,
        measurement_noise=check_measurement_noise(measurement_noise, extra),
        faults=check_faults(
            level_faults(defaults.get("faults"), cam is not None) if faults is None else faults,
            world_measurements(cam_output if cam is not None else None, extra),
            {"tof_max_range": max_range},
        ),
    )
    goal = None
    if landing:
        weights = (
            RewardWeightsV1()
            if reward_weights is None
            else from_fields("reward_weights", RewardWeightsV1, reward_weights)
        )
        goal = LandingGoal(
            success_radius=0.15 if success_radius is None else success_radius,
            start_in_view=True if start_in_view is None else start_in_view,
            view_margin=0.1 if view_margin is None else view_margin,
            reward=weights,
        )
    task_cfg = TaskConfig(
        start=StartDistribution(
            pick("start_altitude", start_altitude),
            pick("start_altitude_jitter", start_altitude_jitter),
            pick("start_offset", start_offset),
            pick("start_yaw", start_yaw),
            pick("start_trimmed", start_trimmed),
        ),
        arena=Arena(arena_half_width, arena_ceiling),
        deck=DeckMotion(
            pick("deck_profile", deck_profile),
            sea_state_amplitudes,
            pick("random_deck_start", random_deck_start),
            DEFAULT_HORIZON_S if horizon_s is None else horizon_s,
            defaults.get("ship") if ship is None and deck_profile is None else ship,  # type: ignore[arg-type]
        ),
        max_velocity=max_velocity,
        landing=goal,
        thresholds=V2_THRESHOLDS if task == "landing-v2" else Thresholds(),
    )
    if not has_camera and not is_raw:
        raise ValueError(
            "camera=False leaves IHRCF and ATDA without an image: use camera=True, or raw=True for a "
            "camera-less simulation"
        )
    cal = None
    if not is_raw:
        cal = load_calibration(calibration)
        assert cam is not None
        cal.check_matches(cam.width, cam.height, cam.fov, world.rig, distortion=cam.distortion)
    observation = dataclasses.replace(
        obs,
        calibration=cal,
        fused_params=None
        if is_raw
        else (obs.fused_params if obs.fused_params is not None else fused_params_for_tof(tof.model, task)),
    )
    cfg = DeckLandingConfig(
        world=world,
        task=task_cfg,
        observation=observation,
        render_mode=render_mode,
        chase_size=chase_size,
        disturbances=disturbances,  # type: ignore[arg-type]  # checked, made a tuple
        wind=_wind_option(pick("wind", wind)),
    )
    return dataclasses.replace(cfg, disturbances=copy.deepcopy(cfg.disturbances)) if cfg.disturbances else cfg
