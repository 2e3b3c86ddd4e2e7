"""The backend-neutral configuration of the deck envs: frozen, typed, checked dataclasses and
:func:`make_config`, which resolves every part of a :class:`DeckLandingConfig` once from the
``gym.make`` options. Imports neither PyBullet nor Gymnasium: a second backend builds from the same
config.

Modules: :mod:`~ihrcf_env.config.world` (:class:`WorldConfig`), :mod:`~ihrcf_env.config.sensors`
(camera, ToF, IMU), :mod:`~ihrcf_env.config.vehicle` (quadrotor, autopilot, navigation),
:mod:`~ihrcf_env.config.wind` (wind, disturbances), :mod:`~ihrcf_env.config.task` (start, arena,
deck motion, thresholds, rewards), :mod:`~ihrcf_env.config.levels` (the levels of
``DeckLanding-v2``), :mod:`~ihrcf_env.config.observation` (the estimator wrappers' part),
:mod:`~ihrcf_env.config.landing` (:class:`DeckLandingConfig`) and :mod:`~ihrcf_env.config.make`
(:func:`make_config` and its part-builders).
"""

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.levels import DEFAULT_LEVEL, LEVELS, Level
from ihrcf_env.config.make import TASK_DEFAULTS, make_config
from ihrcf_env.config.observation import ObservationConfig, fused_params_for_tof, resolve_observation
from ihrcf_env.config.sensors import VL53L1X, CameraConfig, ImagingParams, IMUConfig, IMUNoise, ToFConfig
from ihrcf_env.config.task import TaskConfig
from ihrcf_env.config.vehicle import NavigationConfig, NavigationErrors, QuadParams, VelocityGains
from ihrcf_env.config.wind import Disturbance, DragModel, WindParams
from ihrcf_env.config.world import DeckConfig, WorldConfig

__all__ = [
    "DEFAULT_LEVEL",
    "LEVELS",
    "TASK_DEFAULTS",
    "VL53L1X",
    "CameraConfig",
    "DeckConfig",
    "DeckLandingConfig",
    "Disturbance",
    "DragModel",
    "IMUConfig",
    "IMUNoise",
    "ImagingParams",
    "Level",
    "NavigationConfig",
    "NavigationErrors",
    "ObservationConfig",
    "QuadParams",
    "TaskConfig",
    "ToFConfig",
    "VelocityGains",
    "WindParams",
    "WorldConfig",
    "fused_params_for_tof",
    "make_config",
    "resolve_observation",
]
