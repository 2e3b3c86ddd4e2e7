"""The one path of the options: ``gym.make`` keyword arguments -> a resolved :class:`DeckLandingConfig`.

:func:`make_config` takes every option of every deck task (the env's, the task's and the observation
wrappers') and returns a :class:`~ihrcf_env.config.landing.DeckLandingConfig`, or raises TypeError
(wrong kind) / ValueError (out of range, inconsistent, absurd magnitude) naming the option. It
touches no physics client: a bad option fails before any physics client or temporary file exists.
Every part is resolved here, once, by its part-builder; the env and the wrappers take their part:

* ``world``: :class:`~ihrcf_env.config.world.WorldConfig` (:func:`world_part`: control rate,
  camera, ToF, IMU, autopilot feedback, deck plate and tag, Stewart geometry, action mode);
* ``task``: :class:`~ihrcf_env.config.task.TaskConfig` (:func:`task_part`: start, arena, deck
  motion, thresholds, rewards, and the landing goal of the landing tasks);
* ``observation``: :class:`~ihrcf_env.config.observation.ObservationConfig`
  (:func:`~ihrcf_env.config.observation.resolve_observation`: the estimator wrappers' options, the
  calibration loaded once and matched to the camera, the fused filter's parameters for the ToF
  model and the task);
* ``wind`` (:class:`~ihrcf_env.config.wind.WindParams` or None), ``disturbances``,
  ``render_mode``, ``chase_size``, and the ``task_name`` and ``level`` they were made for.

``task`` names the task whose defaults apply (:data:`TASK_DEFAULTS`): ``"hover"`` (the paper's
hover-and-track experiment, ``ihrcf_env/DeckHover-v0``), ``"landing-v1"``
(``ihrcf_env/DeckLanding-v1``) or ``"landing-v2"`` (``ihrcf_env/DeckLanding-v2``, graded by
``level``, :mod:`ihrcf_env.config.levels`). Options of one task only (:data:`LANDING_OPTIONS`,
:data:`HOVER_OPTIONS`) are refused by the other.

Sensor realism: ``sensor_preset`` (``"ideal"`` or ``"realistic"``) chooses together the camera
(``camera_quality``), the ToF sensors (``tof_noise``: one ray, or the VL53L1X cone model), the IMU
(``imu_noise``) and the autopilot's feedback (``autopilot_feedback``: ``"truth"`` or a drifting
GNSS/INS ``"estimated"`` state); see :data:`SENSOR_PRESETS`. Each of those options, given,
overrides the preset; ``tof_noise``, ``imu_noise`` and ``autopilot_feedback`` also take their
model's parameter dataclass or a dict of some of its parameters (overriding the realistic
defaults, e.g. ``tof_noise={"ambient": 1.0}``).

Start altitude bounds: the lowest start must be :data:`~ihrcf_env.config.task.MIN_START_ALTITUDE`
above the deck origin (legs 0.10 m below the drone's centre, a tilted deck rising under it); the
highest start, above the deck's highest reach, must stay
:data:`~ihrcf_env.config.task.CEILING_MARGIN` below ``arena_ceiling``.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from ihrcf_env._components import component_checks
from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.levels import DEFAULT_LEVEL, LEVELS
from ihrcf_env.config.observation import check_observation_options, resolve_checked
from ihrcf_env.config.sensors import (
    CAMERA_QUALITIES,
    IMU_NOISE_PRESETS,
    MAX_RANGE_BOUNDS,
    PIPELINE_LATENCY,
    TOF_PRESETS,
    VL53L1X,
    CameraConfig,
    IMUConfig,
    IMUNoise,
    ToFConfig,
)
from ihrcf_env.config.task import (
    DEFAULT_HORIZON_S,
    Arena,
    DeckMotion,
    LandingGoal,
    ProfileSpec,
    RewardWeightsV1,
    StartDistribution,
    TaskConfig,
    Thresholds,
)
from ihrcf_env.config.vehicle import FEEDBACK_MODES, NavigationConfig, NavigationErrors, VelocityGains
from ihrcf_env.config.wind import Disturbance, WindParams
from ihrcf_env.config.world import ACTION_MODES, CAMERA_MODELS, CAMERA_OUTPUTS, DeckConfig, WorldConfig
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.checks import (
    check_bool,
    check_int,
    check_positive,
    check_real,
    check_reals,
    check_str,
    describe,
    from_fields,
)
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS, FusedParams
from ihrcf_env.core.estimators.detector import apriltag_ids
from ihrcf_env.core.forecast import ForecastOptions
from ihrcf_env.core.ship import ShipOptions

if TYPE_CHECKING:
    from ihrcf_env.core.detector_model import DetectorModel

__all__ = [
    "AUTOPILOTS",
    "HOVER_OPTIONS",
    "LANDING_OPTIONS",
    "REMOVED_OPTIONS",
    "SENSOR_PRESETS",
    "TASK_DEFAULTS",
    "V2_THRESHOLDS",
    "check_removed_options",
    "level_faults",
    "make_config",
    "model_option",
    "task_part",
    "world_part",
]

#: Largest camera image side (px).
MAX_IMAGE_SIZE = 4096
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
    # the deck and the wind come from the level (config/levels.py)
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
)
#: Options of the hover task only (its observation wrapper's).
HOVER_OPTIONS: tuple[str, ...] = ("keep_image", "flatten")
#: The observation wrappers' options (:func:`~ihrcf_env.config.observation.resolve_observation`).
OBSERVATION_OPTIONS: tuple[str, ...] = (
    "raw",
    "calibration",
    "keep_image",
    "flatten",
    "max_residual",
    "estimators",
    "fused_params",
    "privileged",
    "deck_motion",
    "deck_forecast",
)
#: Options that were removed -> why and what to use instead: given, they are refused by name
#: (ValueError), not silently ignored.
REMOVED_OPTIONS: dict[str, str] = {
    "batch_estimators": (
        "the option and the batched estimators were removed (each env of a vector env runs its own "
        'estimators); the batched path is the JAX backend, gym.make_vec(id, num_envs, backend="jax")'
    ),
    "physics": (
        "the option and the numpy batched physics were removed (every world flies in PyBullet); the "
        'batched path is the JAX backend, gym.make_vec(id, num_envs, backend="jax")'
    ),
}
#: ``autopilot``: the classic position loop, or the wind-holding one (anti-windup and a
#: disturbance observer, :class:`~ihrcf_env.sim.drone.VelocityController`).
AUTOPILOTS: tuple[str, ...] = ("classic", "wind_hold")

M = TypeVar("M")


class _Options:
    """The options of one :func:`make_config` call with their task's defaults: ``o[name]`` is the
    option as given, ``o.pick(name)`` the option or its task's default when left at None."""

    def __init__(self, options: Mapping[str, Any], defaults: Mapping[str, Any]) -> None:
        self.given = dict(options)
        self.defaults = dict(defaults)

    def __getitem__(self, name: str) -> Any:
        return self.given[name]

    def pick(self, name: str) -> Any:
        value = self.given[name]
        return self.defaults[name] if value is None else value


def level_faults(faults: Mapping[str, Any] | None, has_camera: bool) -> Mapping[str, Any] | None:
    """A level's default ``faults``, less the camera's when the world has no camera."""
    if faults is None or has_camera:
        return faults
    return {k: v for k, v in faults.items() if k != "camera_dropout"}


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


def _detector(model: str, detector_model: object) -> DetectorModel | None:
    """The projected camera's detector model (the shipped file for None, or a path), loaded here so
    a missing or corrupt file fails before any physics client exists."""
    if detector_model is None and model != "projected":
        return None
    from ihrcf_env.core.detector_model import DetectorModel, default_detector_model_path

    if detector_model is None:
        return DetectorModel.load(default_detector_model_path())
    if model != "projected":
        raise ValueError('detector_model is used only by camera_model="projected": drop it')
    if isinstance(detector_model, DetectorModel):
        return detector_model
    if isinstance(detector_model, str | os.PathLike):
        return DetectorModel.load(detector_model)
    raise TypeError(
        "detector_model must be a DetectorModel, a path to a detector-model file or None, got "
        f"{type(detector_model).__name__} {detector_model!r}"
    )


def _camera_options(
    has_camera: bool,
    camera_model: object,
    camera_output: object,
    camera_hz: object,
    detector_model: object,
    control_hz: int,
) -> tuple[str, str, int | None, DetectorModel | None]:
    """Checked (camera_model, camera_output, camera_hz, detector model) of :func:`make_config`.

    ``camera_output`` None means ``"image"`` for the rendered camera and ``"corners"`` for the
    projected one."""
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
        if control_hz % hz != 0:
            raise ValueError(
                f"camera_hz must be a positive divisor of control_hz ({control_hz}) in Hz, got {hz!r}"
            )
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
    return model, output, hz, _detector(model, detector_model)


def _camera_part(o: _Options, preset: Mapping[str, str], has_camera: bool) -> CameraConfig | None:
    """The camera's config (None without a camera)."""
    distortion = check_reals("camera_distortion", o["camera_distortion"], 2, low=-1.0, high=1.0)
    if not has_camera and any(distortion):
        raise ValueError(
            f"camera_distortion {o['camera_distortion']!r} has no effect with camera=False: drop it or "
            "turn the camera on"
        )
    quality = o["camera_quality"]
    if quality is not None:
        quality = check_str("camera_quality", quality, CAMERA_QUALITIES)
        if quality != "ideal" and not has_camera:
            raise ValueError(
                f"camera_quality {quality!r} has no effect with camera=False: drop it or turn the camera on"
            )
    if not has_camera:
        return None
    return _built(
        "camera options",
        CameraConfig,
        width=check_int("camera_width", o["camera_width"], low=16, high=MAX_IMAGE_SIZE),
        height=check_int("camera_height", o["camera_height"], low=16, high=MAX_IMAGE_SIZE),
        fov=check_real("camera_fov", o["camera_fov"], "rad", low=math.radians(5), high=math.radians(170)),
        distortion=distortion,
        quality=preset["camera_quality"] if quality is None else quality,
        latency=o.pick("camera_latency"),
    )


def world_part(o: _Options, obs: Any) -> WorldConfig:
    """The :class:`WorldConfig` of the options ``o`` (``obs``: the checked observation options,
    which decide whether the rendered camera renders only the tag's window)."""
    has_camera = check_bool("camera", o["camera"])
    camera_output = o["camera_output"]
    no_image = o.given["task"] != "hover" or obs.keep_image is False or obs.flatten
    if has_camera and not obs.raw and camera_output is None and no_image:
        camera_output = "corners"  # no image in the observation: the rendered camera renders the tag window
    rate = check_int("control_hz", o["control_hz"], low=1, high=1000)
    cam_model, cam_output, cam_hz, detector = _camera_options(
        has_camera, o["camera_model"], camera_output, o["camera_hz"], o["detector_model"], rate
    )
    preset = SENSOR_PRESETS[check_str("sensor_preset", o.pick("sensor_preset"), tuple(SENSOR_PRESETS))]
    cam = _camera_part(o, preset, has_camera)
    tof_model = model_option(
        "tof_noise", o["tof_noise"], preset["tof_noise"], tuple(TOF_PRESETS), VL53L1X, VL53L1X()
    )
    max_range = check_real(
        "tof_max_range", o["tof_max_range"], "m", low=MAX_RANGE_BOUNDS[0], high=MAX_RANGE_BOUNDS[1]
    )
    tof = _built("tof_hz", ToFConfig, max_range=max_range, noise=tof_model, rate_hz=o.pick("tof_hz"))
    imu_model = model_option(
        "imu_noise", o["imu_noise"], preset["imu_noise"], IMU_NOISE_PRESETS, IMUNoise, IMUNoise()
    )
    imu = _built("imu_hz", IMUConfig, imu_model, rate_hz=o["imu_hz"])
    feedback = model_option(
        "autopilot_feedback",
        o["autopilot_feedback"],
        preset["autopilot_feedback"],
        FEEDBACK_MODES,
        NavigationErrors,
        NavigationErrors(),
    )
    deck = _built(
        "tag_size",
        DeckConfig,
        tag_id=check_int("tag_id", o["tag_id"], low=0, high=apriltag_ids() - 1),
        tag_size=check_positive("tag_size", o["tag_size"], "m", high=10.0),
    )
    registry = component_checks()
    extra = registry.check_sensor_names(o["sensors"])
    faults = o["faults"]
    return WorldConfig(
        gains=VelocityGains(wind_hold=check_str("autopilot", o.pick("autopilot"), AUTOPILOTS) == "wind_hold"),
        ground_effect=check_bool("ground_effect", o.pick("ground_effect")),
        control_hz=rate,
        action_mode=check_str("action_mode", o["action_mode"], ACTION_MODES),
        camera=cam,
        tof=tof,
        imu=imu,
        navigation=NavigationConfig(feedback),
        deck=deck,
        camera_model=cam_model,
        camera_output=cam_output,
        camera_hz=cam_hz,
        detector_model=detector,
        extra_sensors=extra,
        measurement_noise=registry.check_measurement_noise(o["measurement_noise"], extra),
        faults=registry.check_faults(
            level_faults(o.defaults.get("faults"), cam is not None) if faults is None else faults,
            registry.world_measurements(cam_output if cam is not None else None, extra),
            {"tof_max_range": max_range},
        ),
    )


def task_part(o: _Options) -> TaskConfig:
    """The :class:`TaskConfig` of the options ``o``."""
    task = o.given["task"]
    goal = None
    if task != "hover":
        weights = o["reward_weights"]
        goal = LandingGoal(
            success_radius=0.15 if o["success_radius"] is None else o["success_radius"],
            start_in_view=True if o["start_in_view"] is None else o["start_in_view"],
            view_margin=0.1 if o["view_margin"] is None else o["view_margin"],
            reward=RewardWeightsV1()
            if weights is None
            else from_fields("reward_weights", RewardWeightsV1, weights),
        )
    ship = o["ship"]
    return TaskConfig(
        start=StartDistribution(
            o.pick("start_altitude"),
            o.pick("start_altitude_jitter"),
            o.pick("start_offset"),
            o.pick("start_yaw"),
            o.pick("start_trimmed"),
        ),
        arena=Arena(o["arena_half_width"], o["arena_ceiling"]),
        deck=DeckMotion(
            o.pick("deck_profile"),
            o["sea_state_amplitudes"],
            o.pick("random_deck_start"),
            DEFAULT_HORIZON_S if o["horizon_s"] is None else o["horizon_s"],
            o.defaults.get("ship") if ship is None and o["deck_profile"] is None else ship,
        ),
        max_velocity=o["max_velocity"],
        landing=goal,
        thresholds=V2_THRESHOLDS if task == "landing-v2" else Thresholds(),
    )


def _wind_part(wind: object) -> WindParams | None:
    """``wind``: True (the default :class:`WindParams`), False or None (calm), a WindParams or a dict
    of some of its fields."""
    if wind is None or isinstance(wind, bool | np.bool_):
        return WindParams() if wind else None
    return from_fields("wind", WindParams, wind)


def _task_and_level(task: object, level: object) -> tuple[str, str | None, dict[str, Any]]:
    """The checked task name and level, and the defaults they set."""
    name = check_str("task", task, tuple(TASK_DEFAULTS))
    defaults = dict(TASK_DEFAULTS[name])
    if name == "landing-v2":
        lvl = check_str("level", DEFAULT_LEVEL if level is None else level, tuple(LEVELS))
        defaults.update(LEVELS[lvl].defaults())
        return name, lvl, defaults
    if level is not None:
        raise ValueError("level is an option of the landing task v2 (ihrcf_env/DeckLanding-v2) only")
    return name, None, defaults


def check_removed_options(options: Mapping[str, Any]) -> None:
    """Refuses the options of :data:`REMOVED_OPTIONS` by name (ValueError saying what replaces
    them), and any other unknown name (TypeError, as an unexpected keyword argument)."""
    for name in options:
        if name in REMOVED_OPTIONS:
            raise ValueError(f"{name}: {REMOVED_OPTIONS[name]}")
    if options:
        raise TypeError(f"make_config() got an unexpected keyword argument {next(iter(options))!r}")


def _check_task_options(o: _Options) -> None:
    """Refuses the options of the other task (:data:`LANDING_OPTIONS`, :data:`HOVER_OPTIONS`)."""
    landing = o.given["task"] != "hover"
    flags = ("privileged", "deck_motion", "flatten")
    given = {n: (o[n] or None) if n in flags else o[n] for n in (*LANDING_OPTIONS, *HOVER_OPTIONS)}
    wrong = [n for n in (HOVER_OPTIONS if landing else LANDING_OPTIONS) if given[n] is not None]
    if wrong:
        other = (
            "hover task (ihrcf_env/DeckHover-v0)" if landing else "landing task (ihrcf_env/DeckLanding-v1)"
        )
        raise ValueError(f"{', '.join(wrong)}: option(s) of the {other} only")


def make_config(
    *,
    task: str = "hover",
    render_mode: str | None = None,
    action_mode: str = "velocity",
    level: str | None = None,
    autopilot: str | None = None,
    ground_effect: bool | None = None,
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
    deck_forecast: bool | ForecastOptions | Mapping[str, Any] | None = False,
    **removed: Any,
) -> DeckLandingConfig:
    """The resolved configuration of a deck task (module docstring). Options left at None take
    ``task``'s default (:data:`TASK_DEFAULTS`). Raises TypeError / ValueError naming the option
    (a removed option, :data:`REMOVED_OPTIONS`: ValueError saying what replaces it).
    ``disturbances`` are deep-copied: every env gets its own."""
    check_removed_options(removed)
    options = dict(locals())
    del options["removed"]
    name, lvl, defaults = _task_and_level(task, level)
    o = _Options({**options, "task": name}, defaults)
    obs = check_observation_options(**{k: o[k] for k in OBSERVATION_OPTIONS})
    _check_task_options(o)
    world = world_part(o, obs)
    task_cfg = task_part(o)
    if world.camera is None and not obs.raw:
        raise ValueError(
            "camera=False leaves IHRCF and ATDA without an image: use camera=True, or raw=True for a "
            "camera-less simulation"
        )
    cfg = DeckLandingConfig(
        world=world,
        task=task_cfg,
        observation=resolve_checked(world, name, obs, calibration),
        render_mode=render_mode,
        chase_size=chase_size,
        disturbances=disturbances,  # type: ignore[arg-type]  # checked, made a tuple
        wind=_wind_part(o.pick("wind")),
        task_name=name,
        level=lvl,
    )
    return dataclasses.replace(cfg, disturbances=copy.deepcopy(cfg.disturbances)) if cfg.disturbances else cfg
