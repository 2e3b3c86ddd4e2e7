"""Observation wrapper exposing the deck-pose estimates (IHRCF, ATDA, fused) beside ground truth.

Each of ``obs["ihrcf"]``, ``obs["atda"]``, ``obs["fused"]`` and ``obs["ground_truth"]`` is a Dict with

* ``"position"``: (3,) float32, the deck frame origin (tag centre) in the drone body frame (m),
* ``"euler"``: (3,) float32, roll, pitch, yaw of the deck in the body frame (rad, Z-Y-X),
* ``"valid"``: int 0/1.

While an estimate is invalid (tag not found, fewer than 3 valid ranges, degenerate geometry, range
outside the calibration table, fit residual too large; for ``fused``: not converged yet, or the tag
lost for longer than its timeout) it reports position (0, 0, 0) and euler (0, 0, 0) with
``valid = 0``; the reason is in ``info[f"{name}_reason"]`` (``info["ihrcf_reason"]``,
``info["atda_reason"]``, ``info["fused_reason"]``) and the fit residual in
``info[f"{name}_residual"]`` (IHRCF m, ATDA px, fused: position 1-sigma m);
the estimates themselves are on ``wrapper.last_estimates`` (name -> PoseEstimate). Values are
clipped into the space's bounds; never NaN. Ground truth comes from the env's ``info``; the
estimators read only the raw observation (:mod:`ihrcf_env.wrappers.estimator_stage`).

The estimators are those of :data:`~ihrcf_env.core.estimators.DEFAULT_ESTIMATORS` (``ihrcf``,
``atda``, ``fused``) unless ``estimators=`` names others of the registry
(:mod:`ihrcf_env.core.estimators.registry`); everything below loops over their names, in order.
Every estimator gets the same :class:`~ihrcf_env.core.estimators.SensorFrame` per step: the tag
corners (detected once), the ranges, the IMU sample and the frame's time, so a temporal filter
(``fused``) sees the real frame interval. ``fused_params`` sets the fused
filter's :class:`~ihrcf_env.core.estimators.FusedParams`; by default they follow the env's ToF model
(:func:`~ihrcf_env.config.observation.fused_params_for_tof`: the VL53L1X's per-sensor offsets give the
filter a common-mode range-offset state).

``flatten=True`` gives one float32 Box for RL libraries, laid out as :func:`flat_slices` says (also
``wrapper.flat_slices``): ranges (4), ranges_valid (4), imu quaternion (4), angular velocity (3),
linear acceleration (3), then for each estimator and finally ground_truth a 7-value block of
position (3), euler (3), valid (1): 46 values by default (18 sensor values, then the ``ihrcf``,
``atda``, ``fused`` and ``ground_truth`` blocks). The image is not part of it. Use the named slices
rather than numbers::

    s = flat_slices()          # or env.get_wrapper_attr("flat_slices")
    obs[s["ihrcf"]]            # the IHRCF block, slice(18, 25)
    obs[s["fused.position"]]   # slice(32, 35)
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.make import make_config
from ihrcf_env.config.observation import ObservationConfig, resolve_observation
from ihrcf_env.core.arrays import clip
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.estimators import (
    DEFAULT_ESTIMATORS,
    DeckPoseEstimator,
    DeckPoseSource,
    FusedParams,
    PoseEstimate,
    SensorFrame,
    check_estimator_names,
)
from ihrcf_env.core.forecast import ForecastOptions
from ihrcf_env.envs.vector_options import refuse_vector_options
from ihrcf_env.wrappers.estimator_stage import EstimatorStage
from ihrcf_env.wrappers.forecast_feed import FORECAST, ForecastFeed
from ihrcf_env.wrappers.layout import Block, Field, Layout, build_layout

POSITION_BOUND = 10.0  # m
FORECAST_BOUND = 20.0  # m, m/s, rad: bound of the hover observation's forecast values
#: The key of the ground-truth pose block; always after the estimators.
GROUND_TRUTH = "ground_truth"
#: The pose keys of ``ihrcf_env/DeckHover-v0``, in observation order.
ESTIMATE_KEYS: tuple[str, ...] = (*DEFAULT_ESTIMATORS, GROUND_TRUTH)
#: Fields of one pose block of the flat observation.
POSE_FIELDS: tuple[Field, ...] = (
    Field("position", 3, -POSITION_BOUND, POSITION_BOUND, unit="m", meaning="deck position, body frame"),
    Field("euler", 3, -math.pi, math.pi, unit="rad", meaning="the deck's roll, pitch, yaw in the body frame"),
    Field("valid", 1, 0.0, 1.0, meaning="1 = valid"),
)
POSE_SIZE = sum(f.size for f in POSE_FIELDS)
#: Paths in the raw observation of the sensor values at the start of the flat observation.
SENSOR_PATHS: dict[str, tuple[str, ...]] = {
    "ranges": ("ranges",),
    "ranges_valid": ("ranges_valid",),
    "imu.quaternion": ("imu", "quaternion"),
    "imu.angular_velocity": ("imu", "angular_velocity"),
    "imu.linear_acceleration": ("imu", "linear_acceleration"),
}


def hover_layout(estimators: Iterable[str] = DEFAULT_ESTIMATORS, max_range: float = 4.0) -> Layout:
    """The flat layout (``flatten=True``) for these estimators and ToF ``max_range`` (m)."""
    return build_layout(hover_blocks(estimators, max_range))


def hover_blocks(estimators: Iterable[str] = DEFAULT_ESTIMATORS, max_range: float = 4.0) -> list[Block]:
    """The blocks of the flat hover observation (:func:`hover_layout`), in order."""
    sensors = (
        Field("ranges", 4, 0.0, max_range, unit="m", meaning="ToF ranges ps1..ps4"),
        Field("ranges_valid", 4, 0.0, 1.0, meaning="1 = valid"),
        Field("imu.quaternion", 4, -1.0, 1.0, meaning="attitude x, y, z, w, world from body"),
        Field("imu.angular_velocity", 3, -50.0, 50.0, unit="rad/s", meaning="body rates, body frame"),
        Field(
            "imu.linear_acceleration", 3, -200.0, 200.0, unit="m/s^2", meaning="specific force, body frame"
        ),
    )
    names = (*check_estimator_names(estimators), GROUND_TRUTH)
    return [("", sensors), *((name, POSE_FIELDS) for name in names)]


def flat_slices(estimators: Iterable[str] = DEFAULT_ESTIMATORS) -> dict[str, slice]:
    """Named slices of the flat observation (``flatten=True``) for the given estimators.

    Keys: ``"ranges"``, ``"ranges_valid"``, ``"imu.quaternion"``, ``"imu.angular_velocity"``,
    ``"imu.linear_acceleration"``, then for each estimator name and ``"ground_truth"`` the whole
    7-value block under its name and its parts under ``f"{name}.position"``, ``f"{name}.euler"``,
    ``f"{name}.valid"``; ``"all"`` is the whole vector. For DeckHover-v0: ``ihrcf`` 18:25,
    ``atda`` 25:32, ``fused`` 32:39, ``ground_truth`` 39:46 (``all`` 0:46).
    """
    return hover_layout(estimators).slices


def _pose_space() -> spaces.Dict:
    return spaces.Dict(
        {
            "position": spaces.Box(-POSITION_BOUND, POSITION_BOUND, (3,), np.float32),
            "euler": spaces.Box(-math.pi, math.pi, (3,), np.float32),
            "valid": spaces.Discrete(2),
        }
    )


def _pose_obs(position: Any, euler: Any, valid: bool) -> dict[str, Any]:
    return {
        "position": clip(position, -POSITION_BOUND, POSITION_BOUND).astype(np.float32),
        "euler": clip(euler, -math.pi, math.pi).astype(np.float32),
        "valid": int(bool(valid)),
    }


def _get(tree: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    for key in path:
        tree = tree[key]
    return tree


def spec_form(value: Any) -> Any:
    """``value`` as a wrapper's spec records it: the form it takes back from JSON
    (``EnvSpec.to_json`` / ``from_json``), so a made env's spec re-makes it: tuples as lists,
    :class:`FusedParams` and other dataclasses as dicts of their fields, paths as str, numpy
    scalars and arrays as numbers and lists. Other values pass as they are."""
    if isinstance(value, tuple | list):
        return [spec_form(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): spec_form(v) for k, v in value.items()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type | Calibration):
        return {f.name: spec_form(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.ndarray | np.generic):
        return spec_form(value.tolist())
    return value


def base_config(env: gym.Env) -> DeckLandingConfig:
    """The validated config of a deck env (possibly wrapped): its declared layout."""
    config = getattr(env.unwrapped, "config", None)
    if not isinstance(config, DeckLandingConfig):
        raise TypeError(
            f"env must be an ihrcf_env deck env (with a DeckLandingConfig), got {env.unwrapped!r}"
        )
    return config


class DeckPoseObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Adds each estimator's deck pose and ``ground_truth`` (body frame) to the observation.

    Args:
        env: a deck env (possibly wrapped) with its camera on.
        calibration: a :class:`Calibration`, a path (str or os.PathLike) to a calibration file, or
            None for the file shipped in ``assets/`` (which must match the env's camera; otherwise a
            :class:`~ihrcf_env.core.calibration.CalibrationError` gives the command that makes one).
        keep_image: keep the raw camera image in the observation (bool); None (default): keep it if
            the env delivers one (``camera_output="image"``). True with an env that delivers only
            the tag corners (``camera_model="projected"`` or ``camera_output="corners"``) raises.
        flatten: return one float32 Box (see :func:`flat_slices`); implies no image (bool).
        max_residual: IHRCF rigid-fit RMS (m) above which the estimate is declared invalid.
        estimators: registered estimator names, in observation order (default ihrcf, atda, fused).
        fused_params: :class:`~ihrcf_env.core.estimators.FusedParams` of the fused estimator, or
            None for the defaults matching the env's ToF model and task.
        deck_forecast: add ``obs["forecast"]``, the deck-motion forecast fed by the fused estimate
            (True, or a :class:`~ihrcf_env.core.forecast.ForecastOptions` or a dict of its fields;
            the Dict observation only, with the ``fused`` estimator): ``mean`` and ``std``
            (horizons x 4: heave m about its mean, heave rate m/s, roll and pitch rad in the drone's
            heading frame), ``quiet`` and ``valid``, as :mod:`ihrcf_env.wrappers.forecast_feed`
            describes; ``info["forecast"]`` carries the same. Default False.
        observation: the resolved :class:`~ihrcf_env.config.observation.ObservationConfig` (as
            :func:`~ihrcf_env.config.make.make_config` makes it); given, the options above are not
            read again (``calibration`` only for the spec). Otherwise the options are resolved once
            against the env's config, as ``gym.make`` resolves them.

    Bad options raise TypeError / ValueError naming the option before anything is built.

    Attributes:
        stage: the :class:`~ihrcf_env.wrappers.estimator_stage.EstimatorStage`.
        observation_config: the resolved options.
        estimator: the :class:`DeckPoseEstimator` (detection once per frame + the estimators).
        estimators: ordered mapping name -> :class:`DeckPoseSource`.
        pose_keys: the estimator names then ``"ground_truth"``: the pose blocks, in order.
        flat_slices: name -> slice of the flat observation (see :func:`flat_slices`).
        last_estimates / last_frame / last_ages: of the last observation (None / {} before reset).
        forecast: the :class:`~ihrcf_env.wrappers.forecast_feed.ForecastFeed` (``deck_forecast``),
            or None.
    """

    def __init__(
        self,
        env: gym.Env,
        calibration: Calibration | str | os.PathLike[str] | None = None,
        keep_image: bool | None = None,
        flatten: bool = False,
        max_residual: float = 0.01,
        estimators: Iterable[str] = DEFAULT_ESTIMATORS,
        fused_params: FusedParams | None = None,
        deck_forecast: bool | ForecastOptions | Mapping[str, Any] | None = False,
        *,
        observation: ObservationConfig | None = None,
    ) -> None:
        config = base_config(env)
        opts = observation
        if opts is None:  # resolved here, for the env's world and task
            opts = resolve_observation(
                config.world,
                config.task_name,
                calibration=calibration,
                keep_image=keep_image,
                flatten=flatten,
                max_residual=max_residual,
                estimators=estimators,
                fused_params=fused_params,
                deck_forecast=deck_forecast,
            )
        fc_opts = opts.deck_forecast
        recorded: dict[str, Any] = {} if fc_opts is None else {"deck_forecast": fc_opts}
        recorded = dict(
            calibration=calibration,
            keep_image=opts.keep_image,
            flatten=opts.flatten,
            max_residual=opts.max_residual,
            estimators=opts.estimators,
            fused_params=fused_params if observation is None else opts.fused_params,
            **recorded,
        )
        gym.utils.RecordConstructorArgs.__init__(self, **spec_form(recorded))
        gym.ObservationWrapper.__init__(self, env)
        world = config.world
        #: the resolved observation config (:class:`~ihrcf_env.config.observation.ObservationConfig`)
        self.observation_config: ObservationConfig = opts
        self.stage = EstimatorStage.for_world(world, opts)
        self.calibration = self.stage.calibration
        names = opts.estimators
        self.estimator: DeckPoseEstimator = self.stage.estimator
        self.estimators: dict[str, DeckPoseSource] = self.stage.sources
        self.pose_keys: tuple[str, ...] = (*names, GROUND_TRUTH)
        self.layout = hover_layout(names, world.tof.max_range)
        self.flat_slices: dict[str, slice] = self.layout.slices
        has_image = world.camera_output == "image"
        if opts.keep_image and not has_image:
            raise ValueError(
                f"keep_image=True needs the camera image, but the env delivers only the tag corners "
                f'(camera_model={world.camera_model!r}, camera_output="corners"): use '
                'keep_image=False, or camera_model="rendered" with camera_output="image"'
            )
        self.flatten = opts.flatten
        self.keep_image = has_image and opts.keep_image is not False and not self.flatten
        inner = env.observation_space
        if not isinstance(inner, spaces.Dict):
            raise ValueError(f"the env's observation space must be a Dict, got {type(inner).__name__}")
        d = {k: v for k, v in inner.spaces.items() if k != "image" or self.keep_image}
        for key in self.pose_keys:
            d[key] = _pose_space()
        #: the deck-motion forecast (``deck_forecast``, Dict observation only), else None
        self.forecast: ForecastFeed | None = None
        if fc_opts is not None:
            self.forecast = ForecastFeed(fc_opts, config.task.deck.length_scale)
            d[FORECAST] = _forecast_space(len(fc_opts.horizons))
        self._dict_space = spaces.Dict(d)
        sl = self.flat_slices
        self._flat_sensors = tuple((path, sl[name]) for name, path in SENSOR_PATHS.items())
        self._flat_poses = tuple(
            (key, sl[f"{key}.position"], sl[f"{key}.euler"], sl[f"{key}.valid"].start)
            for key in self.pose_keys
        )
        if self.flatten:
            lay = self.layout
            self.observation_space = spaces.Box(lay.low, lay.high, (lay.size,), np.float32)
        else:
            self.observation_space = self._dict_space

    @property
    def last_estimates(self) -> dict[str, PoseEstimate] | None:
        return self.stage.last_estimates

    @property
    def last_frame(self) -> SensorFrame | None:
        return self.stage.last_frame

    @property
    def last_ages(self) -> dict[str, float]:
        return self.stage.ages

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self.stage.reset()
        if self.forecast is not None:
            self.forecast.reset()
        obs, info = self.env.reset(seed=seed, options=options)
        out = self._observe(obs, info)
        return out, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.stage.tick()
        out = self._observe(obs, info)
        return out, float(reward), terminated, truncated, info

    def _observe(self, obs: dict[str, Any], info: dict[str, Any]) -> Any:
        """The wrapped observation; adds each estimate's reason, residual and age to ``info``."""
        out = self.observation(obs, info)
        self.stage.add_info(info)
        return out

    def observation(self, observation: dict[str, Any], info: Mapping[str, Any] | None = None) -> Any:
        """The wrapped observation of a raw one taken now; ground truth from ``info``
        (``deck_position_body``, ``deck_euler_body``; zeros and ``valid = 0`` without them)."""
        estimates = self.stage.update(observation)
        if info is not None and "deck_position_body" in info:
            gt_pos, gt_euler, gt_valid = info["deck_position_body"], info["deck_euler_body"], True
        else:
            gt_pos, gt_euler, gt_valid = np.zeros(3), np.zeros(3), False
        if not self.flatten:
            poses = {name: _pose_obs(e.position, e.euler, e.valid) for name, e in estimates.items()}
            poses[GROUND_TRUTH] = _pose_obs(gt_pos, gt_euler, gt_valid)
            out = {k: v for k, v in observation.items() if k != "image" or self.keep_image}
            out.update(poses)
            if self.forecast is not None:
                out[FORECAST] = self._forecast(observation, estimates, info)
            return out
        flat = np.empty(self.layout.size, np.float32)
        for path, sl in self._flat_sensors:
            flat[sl] = _get(observation, path)
        for key, position_sl, euler_sl, valid_i in self._flat_poses:
            if key == GROUND_TRUTH:
                position, euler, valid = gt_pos, gt_euler, gt_valid
            else:
                e = estimates[key]
                position, euler, valid = e.position, e.euler, e.valid
            # as _pose_obs: float64 values rounded to float32 by the assignment, as by astype
            flat[position_sl] = clip(position, -POSITION_BOUND, POSITION_BOUND)
            flat[euler_sl] = clip(euler, -math.pi, math.pi)
            flat[valid_i] = int(bool(valid))
        return flat

    def _forecast(
        self,
        observation: Mapping[str, Any],
        estimates: Mapping[str, PoseEstimate],
        info: Mapping[str, Any] | None,
    ) -> dict[str, Any]:
        """The ``forecast`` entry (:func:`_forecast_space`); ``info["forecast"]`` gets the same."""
        assert self.forecast is not None
        _, fc = self.forecast.observe_imu(
            self.stage.time,
            float(np.asarray(observation["nav_velocity"], np.float64)[2]),
            self.stage.last_frame,
            estimates["fused"],
            observation["imu"]["quaternion"],
        )
        if isinstance(info, dict):
            info[FORECAST] = fc
        return {
            "mean": clip(fc["mean"], -FORECAST_BOUND, FORECAST_BOUND).astype(np.float32),
            "std": clip(fc["std"], 0.0, FORECAST_BOUND).astype(np.float32),
            "quiet": np.array([fc["quiet_probability"]], np.float32),
            "valid": int(fc["valid"]),
        }


def _forecast_space(horizons: int) -> spaces.Dict:
    """The hover observation's ``forecast`` (``deck_forecast``): ``mean`` and ``std`` (horizons, 4)
    of heave about its mean (m), heave rate (m/s), roll and pitch (rad, heading frame), ``quiet``
    (probability that the touchdown window ahead is quiet) and ``valid`` (see
    :mod:`ihrcf_env.wrappers.forecast_feed`)."""
    return spaces.Dict(
        {
            "mean": spaces.Box(-FORECAST_BOUND, FORECAST_BOUND, (horizons, 4), np.float32),
            "std": spaces.Box(0.0, FORECAST_BOUND, (horizons, 4), np.float32),
            "quiet": spaces.Box(0.0, 1.0, (1,), np.float32),
            "valid": spaces.Discrete(2),
        }
    )


def make_deck_hover(**options: Any) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckHover-v0``: the env of the validated options
    (:func:`~ihrcf_env.config.make.make_config`, ``task="hover"``) wrapped with
    :class:`DeckPoseObservation`, or the raw :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`
    with ``raw=True``. Everything is checked (and the calibration read and matched to the camera)
    before the env is built; if the wrapper still fails, the env is closed before the error
    propagates. Without the image in the observation (``keep_image=False`` or ``flatten=True``)
    the rendered camera renders only the tag's window (``camera_output="corners"``, unless given)."""
    refuse_vector_options(options)
    config = make_config(task="hover", **options)
    from ihrcf_env.envs.deck_landing import DeckLandingEnv

    env = DeckLandingEnv(config)
    if config.observation.raw:
        return env
    try:
        return DeckPoseObservation(
            env,
            calibration=options.get("calibration"),  # as given: the spec records it
            observation=config.observation,
        )
    except BaseException:
        env.close()
        raise


__all__ = [
    "ESTIMATE_KEYS",
    "GROUND_TRUTH",
    "DeckPoseObservation",
    "flat_slices",
    "hover_layout",
    "make_deck_hover",
]
