"""The landing step's static configuration: :class:`StepParams`, built once per configuration from a
resolved :class:`~ihrcf_env.config.landing.DeckLandingConfig` by :func:`make_params`.

A :class:`StepParams` is a pytree without leaves: ``jax.jit`` treats it as static (one compilation
per params object; build it once and reuse it) and ``jax.vmap`` passes it through whatever its
``in_axes``. Its fields are host-side constants (Python numbers, numpy arrays and the kernels'
NamedTuples of them).

Supported: ``action_mode="velocity"``, ``camera_model="projected"`` with ``camera_output="corners"``
(or no camera), the built-in sensors with their presets, the ``camera_dropout`` and ``tof_dead``
faults, the env's wind and no other disturbance; options the step cannot honour raise ValueError
naming them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.core.collision import drone_boxes
from ihrcf_env.core.detector_model import DetectorModel
from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.core.ship import ShipOptions
from ihrcf_env.fast.advance import AdvanceConsts
from ihrcf_env.fast.autopilot import Gains, gains_of
from ihrcf_env.fast.deck_motion import ShipConstants, ship_constants, sines_arrays
from ihrcf_env.fast.dynamics import DroneParams, GroundEffectParams, drone_params
from ihrcf_env.fast.frames import dropout_params, pipe_size
from ihrcf_env.fast.imu import ImuParams, imu_params
from ihrcf_env.fast.navigation import NavConstants, nav_constants
from ihrcf_env.fast.rays import Scene, own_fraction
from ihrcf_env.fast.tag_camera import TagCameraSetup, tag_camera_setup
from ihrcf_env.fast.tof import ConeModel, ConeRays, cone_model
from ihrcf_env.fast.wind import WindConstants, wind_constants

__all__ = [
    "CameraConsts",
    "DeckConsts",
    "StepParams",
    "ToFConsts",
    "FLOAT_DTYPES",
    "check_float_dtype",
    "make_params",
]

#: The float types a step computes in.
FLOAT_DTYPES = ("float32", "float64")

#: Faults the step models (others are refused).
SUPPORTED_FAULTS = ("camera_dropout", "tof_dead")
#: Deck profiles: the ship (drawn from a key in JAX too), the sea state (host-drawn episodes only)
#: and the fixed ones.
SUPPORTED_PROFILES = ("ship", "sea_state", "paper", "static")
#: Ground effect's lowest height over the rotor radius (the simulator's default).
MIN_HEIGHT_RATIO = 0.5
#: Occlusion rays stop this far (m) short of the deck surface (the projected camera's margin).
RAY_MARGIN_M = 0.002
#: Tolerance (physics ticks) of the sample-clock arithmetic.
TICK_EPS = 1e-6
#: Longest episode (control steps) ``max_steps`` draws gusts for: every episode draw holds the
#: gusts of ``max_steps`` steps (a few hundred bytes a step per env; later steps hold the last gust).
MAX_STEPS = 100_000


def _drone_reach(centres: np.ndarray, halves: np.ndarray) -> float:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    corners = (centres[:, None, :] + signs[None] * halves[:, None, :]).reshape(-1, 3)
    return float(np.linalg.norm(corners, axis=1).max()) + 0.01


class DeckConsts(NamedTuple):
    """The deck: the profile ``kind`` (``"ship"`` or ``"sines"``), the ship's constants or the fixed
    sum of sines (amplitudes, frequencies Hz, phases (6, K)), the Stewart geometry and the plate."""

    kind: str
    ship: ShipConstants | None
    sines: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    random: bool
    home_position: np.ndarray
    top_joints: np.ndarray
    base_joints: np.ndarray
    min_leg: float
    max_leg: float
    half_thickness: float
    top_half: float


class ToFConsts(NamedTuple):
    """The ToF array: the cone model (None: one ideal ray per sensor), its rays, the axes' starts
    and directions (ideal), ``max_range`` (m), the offsets' s.d. (m), the sample clock's ticks per
    sample (None: read at each control step) and the most samples per control period; the
    ``tof_dead`` fault (sensor count, onset window (s)) or None."""

    model: ConeModel | None
    rays: ConeRays | None
    starts: np.ndarray
    directions: np.ndarray
    max_range: float
    offset_sigma: float
    ticks_per_sample: float | None
    samples: int
    dead: tuple[int, tuple[float, float]] | None


class CameraConsts(NamedTuple):
    """The projected camera: its setup, ``realistic`` quality, latency (physics ticks), frame-pipe
    slots, the dropout fault's parameters (None: off), the imaging draw's parameters and the corner
    field's size (features per corner axis)."""

    setup: TagCameraSetup
    realistic: bool
    latency_ticks: float
    pipe: int
    dropout: tuple[float, float, float] | None
    imaging: Any
    field: int
    bound: float


class StepParams:
    """The step's configuration (module docstring); build with :func:`make_params`."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)

    # static configuration: hashed and compared by identity
    config: DeckLandingConfig
    observe: Callable[..., Any]
    dtype: Any
    substeps: int
    dt: float
    control_dt: float
    drone: DroneParams
    gains: Gains
    advance: AdvanceConsts
    deck: DeckConsts
    horizon_s: float
    wind: WindConstants | None
    gust_count: int
    nav: NavConstants | None
    scene: Scene
    tof: ToFConsts
    imu: ImuParams | None
    camera: CameraConsts | None
    max_velocity: np.ndarray
    landing: bool
    trimmed: bool
    keep_view: bool


jax.tree_util.register_pytree_node(StepParams, lambda p: ((), p), lambda p, _: p)


def _refuse(config: DeckLandingConfig) -> None:
    w = config.world
    if w.action_mode != "velocity":
        raise ValueError(f"action_mode={w.action_mode!r}: the JAX step supports 'velocity' only")
    if w.camera is not None and (w.camera_model != "projected" or w.camera_output != "corners"):
        raise ValueError(
            f"camera_model={w.camera_model!r}, camera_output={w.camera_output!r}: the JAX step "
            "supports the projected camera's corners only (camera_model='projected', camera_output='corners')"
        )
    if w.camera is not None and w.camera_every != 1:
        raise ValueError(f"camera_hz={w.camera_hz!r}: the JAX step supports a frame every control step only")
    if w.extra_sensors:
        raise ValueError(f"extra_sensors={list(w.extra_sensors)!r}: user sensors need the PyBullet env")
    if w.measurement_noise:
        raise ValueError("measurement_noise: user noise models need the PyBullet env")
    unknown = [name for name, _ in w.faults if name not in SUPPORTED_FAULTS]
    if unknown:
        raise ValueError(f"faults {unknown}: the JAX step models {list(SUPPORTED_FAULTS)} only")
    if config.disturbances:
        raise ValueError(
            "disturbances: Python disturbance objects need the PyBullet env (the wind is modelled)"
        )
    if w.imu.rate_hz is not None:
        raise ValueError(f"imu_hz={w.imu.rate_hz!r}: the JAX step reads the IMU at each control step only")
    profile = config.task.deck.profile
    if not isinstance(profile, str) or profile not in SUPPORTED_PROFILES:
        raise ValueError(f"deck_profile={profile!r}: the JAX step supports {list(SUPPORTED_PROFILES)}")


def flat_observation(raw: Any, truth: Any) -> jax.Array:
    """The default observation: the raw reading's fields flattened in order (float, (40,))."""
    del truth
    parts = [jnp.ravel(jnp.asarray(v)).astype(raw.ranges.dtype) for v in raw]
    return jnp.concatenate(parts)


def check_float_dtype(dtype: Any, name: str = "dtype") -> np.dtype:
    """``dtype`` (float32 or float64 in any spelling numpy reads: ``jnp.float32``, ``np.float64``,
    ``"float32"``) as a numpy dtype; TypeError naming ``name`` otherwise (float16, integers, bool,
    None: numpy would read None as float64)."""
    try:
        dt = None if dtype is None or isinstance(dtype, bool) else np.dtype(dtype)
    except TypeError:
        dt = None
    if dt is None or dt.name not in FLOAT_DTYPES:
        raise TypeError(f"{name} must be float32 or float64 (e.g. jnp.float32, 'float64'), got {dtype!r}")
    return dt


def make_params(
    config: DeckLandingConfig,
    observe: Callable[..., Any] | None = None,
    dtype: Any = jnp.float64,
    max_steps: int = 600,
) -> StepParams:
    """The :class:`StepParams` of ``config`` (a resolved config, as ``make_config`` gives it).
    ``observe(raw, truth)`` maps the step's :class:`~ihrcf_env.fast.raw.RawReading` and
    :class:`~ihrcf_env.fast.raw.Truth` to the observation (default: :func:`flat_observation`);
    ``dtype`` the float type of the state (float64 needs ``jax_enable_x64``); ``max_steps`` the
    longest episode (control steps) the wind's gusts are drawn for (later times hold the last
    gust). ValueError naming the option the step cannot honour."""
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or not 1 <= max_steps <= MAX_STEPS:
        raise ValueError(
            f"max_steps must be an int in [1, {MAX_STEPS}] (control steps the gusts are drawn for), "
            f"got {max_steps!r}"
        )
    dtype = check_float_dtype(dtype)
    if not isinstance(config, DeckLandingConfig):
        raise TypeError(f"config must be a DeckLandingConfig (ihrcf_env.make_config), got {config!r}")
    _refuse(config)
    w, task = config.world, config.task
    dt = 1.0 / w.physics_hz
    S = w.substeps
    drone = drone_params(w.quad)
    gains = gains_of(w.gains)
    centres, halves = drone_boxes()
    half_top = w.deck.size / 2
    ge = (
        GroundEffectParams(
            jnp.asarray(float(w.quad.rotor_radius)),
            jnp.asarray(0.0),
            jnp.asarray(MIN_HEIGHT_RATIO),
            jnp.asarray(half_top),
        )
        if w.ground_effect
        else None
    )
    wind = wind_constants(config.wind) if config.wind is not None else None
    adv = AdvanceConsts(
        drone,
        gains,
        ge,
        dt,
        1,
        half_top,
        w.deck.thickness,
        w.stewart.base_radius + 0.06,
        w.stewart.base_height,
        _drone_reach(centres, halves),
        centres,
        halves,
        wind.drag if wind is not None else None,
    )
    g = w.stewart
    deck_cfg = task.deck
    kind = "ship" if deck_cfg.profile == "ship" else "sines"
    sines = None
    if deck_cfg.profile == "paper":
        a, f, ph = sines_arrays(paper_profile().components)
        sines = (np.asarray(a), np.asarray(f), np.asarray(ph))
    elif deck_cfg.profile == "static":
        sines = (np.zeros((6, 1)), np.zeros((6, 1)), np.zeros((6, 1)))
    deck = DeckConsts(
        kind,
        ship_constants(deck_cfg.ship or ShipOptions()) if kind == "ship" else None,
        sines,
        deck_cfg.profile in ("ship", "sea_state"),
        np.asarray(g.home_position, dtype=np.float64),
        np.asarray(g.top_joints, dtype=np.float64),
        np.asarray(g.base_joints, dtype=np.float64),
        float(g.min_leg),
        float(g.max_leg),
        w.deck.thickness / 2,
        half_top,
    )
    horizon = max_steps * S * dt + 1.0  # s of gusts drawn per episode
    scene = Scene(
        jnp.asarray([half_top, half_top, w.deck.thickness / 2]),
        jnp.asarray(w.stewart.base_radius + 0.06),
        jnp.asarray(float(w.stewart.base_height)),
    )
    tof_cfg = w.tof
    sensors = np.asarray(w.rig.sensor_positions_body, dtype=np.float64).reshape(4, 3)
    axis = np.tile([0.0, 0.0, -1.0], (4, 1))
    model = tof_cfg.model
    rays = None
    if model is not None:
        d = model.directions()
        dirs_body = np.column_stack([d[:, 0], d[:, 1], -d[:, 2]])
        starts = np.repeat(sensors, model.rays, axis=0)
        dirs = np.tile(dirs_body, (4, 1))
        own = np.asarray(
            own_fraction(jnp.asarray(starts), jnp.asarray(dirs * tof_cfg.max_range), centres, halves)
        )
        if np.isfinite(own).any():
            raise ValueError(
                "rig: a ToF ray starts inside or hits the drone's own boxes; the JAX step needs clear rays"
            )
        rays = ConeRays(
            jnp.asarray(starts), jnp.asarray(dirs), jnp.asarray(own), jnp.zeros_like(jnp.asarray(dirs))
        )
    faults = dict(w.faults)
    dead = None
    if "tof_dead" in faults:
        fd = dict(faults["tof_dead"])
        if fd.get("sensors") is not None:
            raise ValueError("faults['tof_dead'].sensors: the JAX step draws the dead sensors (give count)")
        onset = fd.get("onset", 0.0)
        window = (
            (float(onset[0]), float(onset[1])) if isinstance(onset, tuple | list) else (float(onset),) * 2
        )
        dead = (int(fd.get("count", 1)), window)
    tps = None if tof_cfg.rate_hz is None else w.physics_hz / float(tof_cfg.rate_hz)
    tof = ToFConsts(
        cone_model(model) if model is not None else None,
        rays,
        sensors,
        axis,
        float(tof_cfg.max_range),
        float(model.offset_sigma) if model is not None else 0.0,
        tps,
        1 if tps is None else math.ceil(S / tps) + 1,
        dead,
    )
    imu = imu_params(w.imu.model) if w.imu.model is not None else None
    camera = None
    if w.camera is not None:
        cam = w.camera
        det = w.detector_model if w.detector_model is not None else DetectorModel.load()
        setup = tag_camera_setup(cam, w.rig, w.deck.tag_size, det, scene, (centres, halves), RAY_MARGIN_M)
        drop = None
        if "camera_dropout" in faults:
            fd = dict(faults["camera_dropout"])
            drop = dropout_params(float(fd.get("loss_rate", 0.05)), float(fd.get("mean_burst", 3.0)))
        latency_ticks = float(cam.latency) * w.physics_hz
        from ihrcf_env.core.detector_model import FIELD_FEATURES

        camera = CameraConsts(
            setup,
            cam.quality == "realistic",
            latency_ticks,
            pipe_size(latency_ticks, S) if cam.latency > 0 else 1,
            drop,
            cam.imaging,
            2 * FIELD_FEATURES,
            float(max(cam.width, cam.height)),
        )
    nav_errors = w.navigation.errors
    return StepParams(
        config=config,
        observe=observe if observe is not None else flat_observation,
        dtype=dtype,
        substeps=S,
        dt=dt,
        control_dt=S * dt,
        drone=drone,
        gains=gains,
        advance=adv,
        deck=deck,
        horizon_s=horizon,
        wind=wind,
        gust_count=(int(math.ceil(horizon / wind.sample_dt)) + 3) if wind is not None else 0,
        nav=nav_constants(nav_errors, dt) if nav_errors is not None else None,
        scene=scene,
        tof=tof,
        imu=imu,
        camera=camera,
        max_velocity=np.asarray(task.max_velocity, dtype=np.float64),
        landing=task.landing is not None,
        trimmed=bool(task.start.trimmed),
        keep_view=bool(
            task.start.trimmed
            and task.landing is not None
            and task.landing.start_in_view
            and w.camera is not None
        ),
    )
