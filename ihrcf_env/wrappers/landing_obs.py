"""The RL observation of ``ihrcf_env/DeckLanding-v1``: one float32 Box with named slices.

:class:`LandingObservation` wraps the raw landing env, runs the estimators on its observation
(:class:`~ihrcf_env.wrappers.estimator_stage.EstimatorStage`) and returns one flat, normalised
vector that SB3's ``MlpPolicy`` (and RLlib) take as it is.
Each field is stored as ``physical value / scale``, clipped into the Box; the named slices are
``env.get_wrapper_attr("obs_slices")`` and the scales ``env.get_wrapper_attr("obs_scales")``
(:func:`landing_obs_fields` gives both for any estimator set). The *heading frame* is the drone's
level frame: x forward along its yaw, y left, z up, computed from the IMU's attitude (not ground
truth). Default layout (50 values, three estimators):

=============================  ====  ========  ===================================================
name                           size  scale     meaning
=============================  ====  ========  ===================================================
``ranges``                     4     max range ToF ps1..ps4 (m); an invalid reading reads 1
``ranges_valid``               4     1         1 = valid
``imu.up``                     3     1         world up axis in the body frame (IMU attitude)
``imu.angular_velocity``       3     5 rad/s   body rates (IMU)
``imu.linear_acceleration``    3     9.81      specific force, body frame (IMU; +1 on z at hover)
``nav_velocity``               3     1 m/s     the autopilot's velocity estimate, heading frame
per estimator ``E`` (``ihrcf``, ``atda``, ``fused``), 10 values each:
``E.position``                 3     2 m       deck origin (tag centre), heading frame
``E.normal``                   3     1         deck normal, heading frame (x, y: the deck's tilt)
``E.yaw``                      2     1         cos, sin of the deck's yaw relative to the drone
``E.valid``                    1     1         1 = the estimate is valid this step
``E.age``                      1     1 s       age of the values shown (s, <= 10)
=============================  ====  ========  ===================================================

``deck_motion=True`` (opt-in; default off, so the default layout stays 50 values) appends the fused
filter's deck motion, the rates a memoryless policy cannot take from one observation: ``motion.velocity``
(3, 1 m/s: the deck origin's velocity relative to the drone, heading frame) and ``motion.normal_rate``
(3, 1/s: the rate of change of the deck normal, heading frame), from
:meth:`~ihrcf_env.core.estimators.fused.FusedEstimator.motion` (sensor-derived, not ground truth);
held like an estimate block while the filter is not converged (zeros before it ever was).

``deck_forecast=True`` (or a dict of :class:`~ihrcf_env.core.forecast.ForecastOptions` fields; opt-in,
needs the ``fused`` estimator) appends the deck-motion forecast fed by the fused estimate
(:mod:`ihrcf_env.wrappers.forecast_feed`): per horizon the forecast ``forecast.heave`` (0.1 m, about
the deck's mean height), ``.heave_rate`` (1 m/s), ``.roll`` and ``.pitch`` (0.1 rad, heading frame)
and their standard deviations (``forecast.heave_std``, ...), then ``forecast.quiet`` (probability that
the touchdown window ahead is quiet) and ``forecast.valid``; all 0 until the forecaster's first fit.
``info["forecast"]`` carries the same values unscaled.

While an estimate is invalid its block keeps the last valid values and ``age`` grows (the time
since the camera frame behind them, also ``info[f"{E}_age"]``); before
the first valid estimate the block is zeros with age 10. No ground truth is in the observation
unless ``privileged=True`` (for asymmetric actor-critic: a critic may read it, a deployed actor
must not), which appends ``ground_truth.position`` (3, 2 m), ``.normal`` (3), ``.yaw`` (2),
``.velocity`` (3, drone relative to the deck, heading frame, 1 m/s) and ``.wind`` (3, heading frame,
1 m/s): 64 values. Ground truth is always in ``info`` (see the env), the raw estimates too.

:func:`make_deck_landing_v1` is the entry point of ``ihrcf_env/DeckLanding-v1``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.make import make_config
from ihrcf_env.config.observation import ObservationConfig, resolve_observation
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS, FusedEstimator, FusedParams, PoseEstimate
from ihrcf_env.core.forecast import ForecastOptions
from ihrcf_env.core.frames import matrix_from_euler, matrix_from_quat
from ihrcf_env.core.landing_layout import (
    ESTIMATE_FIELDS,
    MAX_AGE,
    MOTION,
    MOTION_FIELDS,
    POSITION_SCALE,
    RATE_SCALE,
    TRUTH_FIELDS,
    sensor_fields,
)
from ihrcf_env.core.landing_layout import landing_blocks as core_landing_blocks
from ihrcf_env.envs.vector_options import refuse_vector_options
from ihrcf_env.wrappers.estimates import GROUND_TRUTH, base_config, spec_form
from ihrcf_env.wrappers.estimator_stage import EstimatorStage
from ihrcf_env.wrappers.forecast_feed import FORECAST, ForecastFeed, forecast_fields
from ihrcf_env.wrappers.layout import Block, build_layout


def landing_obs_fields(
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    max_range: float = 4.0,
    privileged: bool = False,
    deck_motion: bool = False,
    forecast_horizons: int = 0,
) -> tuple[dict[str, slice], dict[str, float], NDArray[np.float32], NDArray[np.float32]]:
    """(slices, scales, low, high) of the observation (module docstring) for these estimators,
    ToF ``max_range`` (m), ``privileged``, ``deck_motion`` and the number of ``forecast_horizons``
    (0: no forecast block). ``slices`` also has each estimator's whole block under its name and
    ``"all"``; ``scales[name]`` turns a slice back into physical units."""
    lay = build_layout(landing_blocks(estimators, max_range, privileged, deck_motion, forecast_horizons))
    return lay.slices, lay.scales, lay.low, lay.high


def landing_blocks(
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    max_range: float = 4.0,
    privileged: bool = False,
    deck_motion: bool = False,
    forecast_horizons: int = 0,
) -> list[Block]:
    """The blocks of the landing observation (:func:`landing_obs_fields`), in order
    (:func:`ihrcf_env.core.landing_layout.landing_blocks` with the forecast block)."""
    forecast = (FORECAST, forecast_fields(forecast_horizons)) if forecast_horizons > 0 else None
    return core_landing_blocks(estimators, max_range, privileged, deck_motion, forecast)


def heading_rotation(quaternion: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(R_lb, R_lw): heading-frame-from-body and heading-frame-from-world rotations for the attitude
    ``quaternion`` (x, y, z, w; world from body)."""
    R_wb = matrix_from_quat(np.asarray(quaternion, dtype=np.float64))
    yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    R_lw = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return R_lw @ R_wb, R_lw


class LandingObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The flat landing observation (module docstring) of a raw deck env.

    Args:
        env: a raw deck-landing env (Dict observation with the tag corners or the image).
        calibration, max_residual, estimators, fused_params: the estimators' options, as for
            :class:`~ihrcf_env.wrappers.estimates.DeckPoseObservation`.
        privileged: append the ground-truth block (asymmetric actor-critic); default False.
        deck_motion: append the fused filter's deck motion (module docstring; needs the ``fused``
            estimator); default False.
        deck_forecast: append the deck-motion forecast (module docstring; True, or a
            :class:`~ihrcf_env.core.forecast.ForecastOptions` or a dict of its fields; needs the
            ``fused`` estimator); default False.
        observation: the resolved :class:`~ihrcf_env.config.observation.ObservationConfig` (as
            :func:`~ihrcf_env.config.make.make_config` makes it); given, the options above are not
            read again (``calibration`` only for the spec). Otherwise the options are resolved once
            against the env's config (its world and task), as ``gym.make`` resolves them.

    Attributes: ``obs_slices`` (name -> slice), ``obs_scales`` (name -> scale: physical = value *
    scale), ``estimator_names``, ``estimators`` (name -> source), ``stage``, ``privileged``,
    ``deck_motion``, ``forecast`` (the :class:`~ihrcf_env.wrappers.forecast_feed.ForecastFeed`, or
    None), ``observation_config`` (the resolved options).
    """

    def __init__(
        self,
        env: gym.Env,
        calibration: Calibration | str | os.PathLike[str] | None = None,
        max_residual: float = 0.01,
        estimators: Iterable[str] = DEFAULT_ESTIMATORS,
        fused_params: FusedParams | None = None,
        privileged: bool = False,
        deck_motion: bool = False,
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
                max_residual=max_residual,
                estimators=estimators,
                fused_params=fused_params,
                privileged=privileged,
                deck_motion=deck_motion,
                deck_forecast=deck_forecast,
            )
        fc_opts = opts.deck_forecast
        recorded: dict[str, Any] = {} if fc_opts is None else {"deck_forecast": fc_opts}
        recorded = dict(
            calibration=calibration,
            max_residual=opts.max_residual,
            estimators=opts.estimators,
            fused_params=fused_params if observation is None else opts.fused_params,
            privileged=opts.privileged,
            deck_motion=opts.deck_motion,
            **recorded,
        )
        gym.utils.RecordConstructorArgs.__init__(self, **spec_form(recorded))
        gym.Wrapper.__init__(self, env)
        world = config.world
        #: the resolved observation config (:class:`~ihrcf_env.config.observation.ObservationConfig`)
        self.observation_config: ObservationConfig = opts
        self.stage = EstimatorStage.for_world(world, opts)
        names = opts.estimators
        self.estimators = self.stage.sources
        self.estimator_names: tuple[str, ...] = names
        self.pose_keys: tuple[str, ...] = (*names, GROUND_TRUTH)
        self.privileged = opts.privileged
        self.deck_motion = opts.deck_motion
        fused_source = self.stage.sources.get("fused")
        self._fused = fused_source if opts.deck_motion and isinstance(fused_source, FusedEstimator) else None
        #: the deck-motion forecast (``deck_forecast``), else None
        self.forecast: ForecastFeed | None = None
        if opts.deck_forecast is not None:
            self.forecast = ForecastFeed(opts.deck_forecast, config.task.deck.length_scale)
        self._max_range = float(world.tof.max_range)
        horizons = 0 if self.forecast is None else self.forecast.horizons.size
        self.obs_slices, self.obs_scales, low, high = landing_obs_fields(
            self.estimator_names, self._max_range, self.privileged, self.deck_motion, horizons
        )
        self.observation_space = spaces.Box(low, high, low.shape, np.float32)
        self._low, self._high = low, high
        self._held: dict[str, NDArray[np.float64]] = {}  # estimator -> last valid scaled block
        self._held_time: dict[str, float] = {}  # estimator -> time (s) of the frame behind it
        self._motion = np.zeros(6)  # last deck motion block (heading frame)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        raw, info = self.reset_raw(seed=seed, options=options)
        return self._flatten(raw, info), info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        return self.observe_step(*self.env.step(action))

    def observe_step(
        self,
        raw: dict[str, Any],
        reward: SupportsFloat,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> tuple[Any, float, bool, bool, dict]:
        """:meth:`step` given the wrapped env's step results (a vector env steps the task itself):
        :meth:`take_step`, then the observation."""
        raw, reward, terminated, truncated, info = self.take_step(raw, reward, terminated, truncated, info)
        return self._flatten(raw, info), reward, terminated, truncated, info

    def reset_raw(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Reset the wrapped env and this wrapper's state; the raw observation and info (the first
        half of :meth:`reset`: :meth:`complete` makes the observation)."""
        self._held, self._held_time = {}, {}
        self._motion = np.zeros(6)
        if self.forecast is not None:
            self.forecast.reset()
        self.stage.reset()
        return self.env.reset(seed=seed, options=options)

    def take_step(
        self,
        raw: dict[str, Any],
        reward: SupportsFloat,
        terminated: bool,
        truncated: bool,
        info: dict[str, Any],
    ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """Take the wrapped env's step results (this wrapper's clock advances one step); returns
        them (the first half of :meth:`step`: :meth:`complete` makes the observation)."""
        self.stage.tick()
        return raw, float(reward), terminated, truncated, info

    def complete(
        self,
        raw: Mapping[str, Any],
        info: dict[str, Any],
        estimates: dict[str, PoseEstimate] | None,
        motion: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
    ) -> NDArray[np.float32]:
        """The observation of ``raw`` (from :meth:`reset_raw` / :meth:`take_step`) given the
        ``estimates`` of the frame ``stage.prepare(raw)`` returned (None when it returned None) and
        the fused filter's deck ``motion`` after them (see :meth:`observe`); adds the estimates'
        reasons and ages to ``info``."""
        out = self.observe(raw, info, self.stage.finish(estimates), motion)
        self.stage.add_info(info)
        return out

    def _flatten(self, raw: Mapping[str, Any], info: dict[str, Any]) -> NDArray[np.float32]:
        frame = self.stage.prepare(raw)
        estimates = None if frame is None else self.stage.estimator.update(frame)
        motion = self._fused.motion() if self._fused is not None else None
        return self.complete(raw, info, estimates, motion)

    def observe(
        self,
        obs: Mapping[str, Any],
        info: Mapping[str, Any],
        estimates: Mapping[str, PoseEstimate],
        motion: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ) -> NDArray[np.float32]:
        """The flat observation of a raw observation ``obs`` (and its ``info``, for the
        privileged block) given the ``estimates`` shown now (:attr:`stage` has taken them) and the
        fused filter's deck ``motion`` (velocity m/s, normal rate 1/s, world frame; None:
        undefined), which ``deck_motion=True`` shows. Updates the held blocks."""
        sl, sc = self.obs_slices, self.obs_scales
        out = np.zeros(sl["all"].stop, np.float64)
        imu = obs["imu"]
        R_lb, R_lw = heading_rotation(imu["quaternion"])
        R_wb = R_lw.T @ R_lb
        out[sl["ranges"]] = np.asarray(obs["ranges"], np.float64) / sc["ranges"]
        out[sl["ranges_valid"]] = np.asarray(obs["ranges_valid"], np.float64)
        out[sl["imu.up"]] = R_wb[2, :]
        out[sl["imu.angular_velocity"]] = np.asarray(imu["angular_velocity"], np.float64) / RATE_SCALE
        out[sl["imu.linear_acceleration"]] = np.asarray(imu["linear_acceleration"], np.float64) / GRAVITY
        out[sl["nav_velocity"]] = R_lw @ np.asarray(obs["nav_velocity"], np.float64)
        now = self.stage.time
        for name in self.estimator_names:
            est = estimates[name]
            if est.valid:
                self._held[name] = self._pose_block(R_lb, est.position, est.euler)
                self._held_time[name] = now - self.stage.ages.get(name, 0.0)
            if name in self._held:
                out[sl[f"{name}.position"].start : sl[f"{name}.valid"].start] = self._held[name]
                out[sl[f"{name}.age"]] = (now - self._held_time[name]) / sc[f"{name}.age"]
            else:
                out[sl[f"{name}.age"]] = MAX_AGE
            out[sl[f"{name}.valid"]] = float(bool(est.valid))
        if self.deck_motion:
            if motion is not None:
                self._motion = np.concatenate([R_lw @ motion[0], R_lw @ motion[1]])
            out[sl[MOTION]] = self._motion
        if self.forecast is not None:
            block, fc_info = self.forecast.observe(
                now,
                float(np.asarray(obs["nav_velocity"], np.float64)[2]),
                self.stage.last_frame,
                estimates["fused"],
                R_lb,
                R_lw,
            )
            out[sl[FORECAST]] = block
            if isinstance(info, dict):
                info[FORECAST] = fc_info
        if self.privileged:
            R_lb_true, R_lw_true = heading_rotation(info["drone_quaternion_world"])
            pose = self._pose_block(R_lb_true, info["deck_position_body"], None, info["deck_rotation_body"])
            velocity = R_lw_true @ np.asarray(info["relative_velocity"], np.float64)
            wind = R_lw_true @ np.asarray(info["wind_velocity"], np.float64)
            out[sl[GROUND_TRUTH]] = np.concatenate([pose, velocity, wind])
        return np.clip(out, self._low, self._high).astype(np.float32)

    @staticmethod
    def _pose_block(
        R_lb: NDArray[np.float64],
        position: Any,
        euler: Any,
        rotation: Any = None,
    ) -> NDArray[np.float64]:
        """Scaled (position 3, normal 3, cos/sin yaw 2) of a deck pose in the body frame."""
        R_bd = (
            np.asarray(rotation, np.float64)
            if rotation is not None
            else matrix_from_euler(*(float(v) for v in euler))
        )
        p = R_lb @ np.asarray(position, dtype=np.float64) / POSITION_SCALE
        R_ld = R_lb @ R_bd
        yaw = math.atan2(R_ld[1, 0], R_ld[0, 0])
        return np.concatenate([p, R_ld[:, 2], [math.cos(yaw), math.sin(yaw)]])


def make_landing(task: str, config: DeckLandingConfig | None = None, **options: Any) -> gym.Env:
    """A landing task's env from validated options (:func:`~ihrcf_env.config.make.make_config`
    with ``task``) wrapped with :class:`LandingObservation` (``raw=True``: the raw env), or from an
    already resolved ``config`` of that task (then only ``calibration`` may be given beside it, as
    the spec records it; nothing is validated or loaded again). No image is observed, so the
    rendered camera renders only the tag's window (``camera_output="corners"`` unless given).
    Everything is checked before any physics client exists; a failed wrapper closes the env."""
    if config is None:
        refuse_vector_options(options)
        config = make_config(task=task, **options)
    else:
        _check_resolved(task, config, options)
    from ihrcf_env.envs.landing_v1 import DeckLandingV1Env, DeckLandingV2Env

    env = (DeckLandingV2Env if task == "landing-v2" else DeckLandingV1Env)(config)
    if config.observation.raw:
        return env
    try:
        return LandingObservation(
            env,
            calibration=options.get("calibration"),  # as given: the spec records it
            observation=config.observation,
        )
    except BaseException:
        env.close()
        raise


def _check_resolved(task: str, config: object, options: dict[str, Any]) -> None:
    """Refuse a ``config`` that is not a resolved config of ``task``, or options beside it."""
    if not isinstance(config, DeckLandingConfig):
        raise TypeError(
            f"config must be a DeckLandingConfig (ihrcf_env.make_config), got {type(config).__name__}"
        )
    if config.task_name != task:
        raise ValueError(f"config: a config of task {config.task_name!r} given to the {task!r} env")
    extra = sorted(set(options) - {"calibration"})
    if extra:
        raise ValueError(f"config: give either a resolved config or options, not both (got {extra})")


def make_deck_landing_v1(**options: Any) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckLanding-v1`` (:func:`make_landing`)."""
    return make_landing("landing-v1", **options)


def make_deck_landing_v2(**options: Any) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckLanding-v2`` (:func:`make_landing`; ``level=`` grades it)."""
    return make_landing("landing-v2", **options)


__all__ = [
    "ESTIMATE_FIELDS",
    "MAX_AGE",
    "MOTION",
    "MOTION_FIELDS",
    "POSITION_SCALE",
    "RATE_SCALE",
    "TRUTH_FIELDS",
    "LandingObservation",
    "heading_rotation",
    "landing_obs_fields",
    "make_deck_landing_v1",
    "make_deck_landing_v2",
    "make_landing",
    "sensor_fields",
]
