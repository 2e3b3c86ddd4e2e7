"""The RL observation of ``ihrcf_env/DeckLanding-v1``: one float32 Box with named slices.

:class:`LandingObservation` wraps a :class:`~ihrcf_env.wrappers.estimates.DeckPoseObservation`
(Dict) and returns one flat, normalised vector that SB3's ``MlpPolicy`` (and RLlib) take as it is.
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

While an estimate is invalid its block keeps the last valid values and ``age`` grows (the time
since the camera frame behind them, ``info[f"{E}_age"]`` of the estimates wrapper included); before
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
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS, FusedEstimator, FusedParams
from ihrcf_env.core.frames import matrix_from_euler, matrix_from_quat
from ihrcf_env.wrappers.estimates import (
    GROUND_TRUTH,
    DeckPoseObservation,
    check_wrapper_options,
    load_calibration,
)

if TYPE_CHECKING:
    from ihrcf_env.envs.deck_landing import DeckLandingEnv

#: Largest age (s) shown for an estimate; also the age of one never seen.
MAX_AGE = 10.0
POSITION_SCALE = 2.0  # m
RATE_SCALE = 5.0  # rad/s
#: (name, size, scale, bound of the scaled value); ranges' scale is the env's ``tof_max_range``.
SENSOR_FIELDS: tuple[tuple[str, int, float, float], ...] = (
    ("ranges", 4, math.nan, 1.0),
    ("ranges_valid", 4, 1.0, 1.0),
    ("imu.up", 3, 1.0, 1.0),
    ("imu.angular_velocity", 3, RATE_SCALE, 50.0 / RATE_SCALE),
    ("imu.linear_acceleration", 3, GRAVITY, 200.0 / GRAVITY),
    ("nav_velocity", 3, 1.0, 20.0),
)
ESTIMATE_FIELDS: tuple[tuple[str, int, float, float], ...] = (
    ("position", 3, POSITION_SCALE, 10.0 / POSITION_SCALE),
    ("normal", 3, 1.0, 1.0),
    ("yaw", 2, 1.0, 1.0),
    ("valid", 1, 1.0, 1.0),
    ("age", 1, 1.0, MAX_AGE),
)
TRUTH_FIELDS: tuple[tuple[str, int, float, float], ...] = (
    ("position", 3, POSITION_SCALE, 10.0 / POSITION_SCALE),
    ("normal", 3, 1.0, 1.0),
    ("yaw", 2, 1.0, 1.0),
    ("velocity", 3, 1.0, 20.0),
    ("wind", 3, 1.0, 40.0),
)
MOTION_FIELDS: tuple[tuple[str, int, float, float], ...] = (
    ("velocity", 3, 1.0, 20.0),
    ("normal_rate", 3, 1.0, 20.0),
)
#: Observation block of the fused filter's deck motion (``deck_motion=True``).
MOTION = "motion"
#: Fields whose scaled values lie in [0, bound] rather than [-bound, bound].
NON_NEGATIVE = ("ranges", "ranges_valid", "valid", "age")


def landing_obs_fields(
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    max_range: float = 4.0,
    privileged: bool = False,
    deck_motion: bool = False,
) -> tuple[dict[str, slice], dict[str, float], NDArray[np.float32], NDArray[np.float32]]:
    """(slices, scales, low, high) of the observation (module docstring) for these estimators,
    ToF ``max_range`` (m), ``privileged`` and ``deck_motion``. ``slices`` also has each estimator's
    whole block under its name and ``"all"``; ``scales[name]`` turns a slice back into physical
    units."""
    slices: dict[str, slice] = {}
    scales: dict[str, float] = {}
    lows: list[float] = []
    highs: list[float] = []
    blocks: list[tuple[str, tuple[tuple[str, int, float, float], ...]]] = [("", SENSOR_FIELDS)]
    blocks += [(name, ESTIMATE_FIELDS) for name in estimators]
    if deck_motion:
        blocks.append((MOTION, MOTION_FIELDS))
    if privileged:
        blocks.append((GROUND_TRUTH, TRUTH_FIELDS))
    i = 0
    for prefix, fields in blocks:
        start = i
        for field, n, scale, bound in fields:
            name = f"{prefix}.{field}" if prefix else field
            slices[name] = slice(i, i + n)
            scales[name] = float(max_range) if field == "ranges" else scale
            lo = 0.0 if field in NON_NEGATIVE else -bound
            lows += [lo] * n
            highs += [bound] * n
            i += n
        if prefix:
            slices[prefix] = slice(start, i)
    slices["all"] = slice(0, i)
    return slices, scales, np.array(lows, np.float32), np.array(highs, np.float32)


def heading_rotation(quaternion: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(R_lb, R_lw): heading-frame-from-body and heading-frame-from-world rotations for the attitude
    ``quaternion`` (x, y, z, w; world from body)."""
    R_wb = matrix_from_quat(np.asarray(quaternion, dtype=np.float64))
    yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    R_lw = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return R_lw @ R_wb, R_lw


class LandingObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """The flat v1 observation (module docstring) of a ``DeckPoseObservation`` Dict env.

    Args:
        env: a :class:`~ihrcf_env.wrappers.estimates.DeckPoseObservation`-wrapped deck-landing env
            (Dict observation, with or without the image: the image is dropped).
        privileged: append the ground-truth block (asymmetric actor-critic); default False.
        deck_motion: append the fused filter's deck motion (module docstring; needs the ``fused``
            estimator); default False.

    Attributes: ``obs_slices`` (name -> slice), ``obs_scales`` (name -> scale: physical = value *
    scale), ``estimator_names``, ``privileged``, ``deck_motion``.
    """

    def __init__(self, env: gym.Env, privileged: bool = False, deck_motion: bool = False) -> None:
        for name, flag in (("privileged", privileged), ("deck_motion", deck_motion)):
            if not isinstance(flag, bool | np.bool_):
                raise TypeError(f"{name} must be True or False, got {type(flag).__name__} {flag!r}")
        gym.utils.RecordConstructorArgs.__init__(
            self, privileged=bool(privileged), deck_motion=bool(deck_motion)
        )
        gym.Wrapper.__init__(self, env)
        pose_keys = env.get_wrapper_attr("pose_keys")
        self.estimator_names: tuple[str, ...] = tuple(k for k in pose_keys if k != GROUND_TRUTH)
        self.privileged = bool(privileged)
        self.deck_motion = bool(deck_motion)
        self._fused: FusedEstimator | None = None
        if self.deck_motion:
            fused = env.get_wrapper_attr("estimators").get("fused")
            if not isinstance(fused, FusedEstimator):
                raise ValueError(
                    "deck_motion needs the fused estimator (estimators must include 'fused'), "
                    f"got estimators {self.estimator_names}"
                )
            self._fused = fused
        base = cast("DeckLandingEnv", env.unwrapped)
        self._max_range = float(base.config.tof.max_range)
        self.obs_slices, self.obs_scales, low, high = landing_obs_fields(
            self.estimator_names, self._max_range, self.privileged, self.deck_motion
        )
        self.observation_space = spaces.Box(low, high, low.shape, np.float32)
        self._low, self._high = low, high
        self._held: dict[str, NDArray[np.float64]] = {}  # estimator -> last valid scaled block
        self._held_time: dict[str, float] = {}  # estimator -> time (s) of the frame behind it
        self._motion = np.zeros(6)  # last deck motion block (heading frame)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self._held, self._held_time = {}, {}
        self._motion = np.zeros(6)
        obs, info = self.env.reset(seed=seed, options=options)
        return self._flatten(obs, info), info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._flatten(obs, info), float(reward), terminated, truncated, info

    def _nav_velocity(self, info: Mapping[str, Any]) -> NDArray[np.float64]:
        if "nav_velocity" in info:
            return np.asarray(info["nav_velocity"], dtype=np.float64)
        return cast("DeckLandingEnv", self.env.unwrapped).world.nav_velocity()

    def _flatten(self, obs: Mapping[str, Any], info: Mapping[str, Any]) -> NDArray[np.float32]:
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
        out[sl["nav_velocity"]] = R_lw @ self._nav_velocity(info)
        now = float(info.get("time", 0.0))
        for name in self.estimator_names:
            est = obs[name]
            if int(est["valid"]):
                age = float(info.get(f"{name}_age", 0.0))
                self._held[name] = self._pose_block(R_lb, est["position"], est["euler"])
                self._held_time[name] = now - age
            if name in self._held:
                out[sl[f"{name}.position"].start : sl[f"{name}.valid"].start] = self._held[name]
                out[sl[f"{name}.age"]] = (now - self._held_time[name]) / sc[f"{name}.age"]
            else:
                out[sl[f"{name}.age"]] = MAX_AGE
            out[sl[f"{name}.valid"]] = float(int(est["valid"]))
        if self._fused is not None:
            motion = self._fused.motion()
            if motion is not None:
                self._motion = np.concatenate([R_lw @ motion[0], R_lw @ motion[1]])
            out[sl[MOTION]] = self._motion
        if self.privileged:
            base = cast("DeckLandingEnv", self.env.unwrapped)
            s = base.world.snapshot()
            R_lb_true, R_lw_true = heading_rotation(s.drone_quaternion)
            gt = sl[GROUND_TRUTH]
            pose = self._pose_block(R_lb_true, s.deck_position_body, None, s.deck_rotation_body)
            wind = getattr(base, "wind", None)
            w = wind.velocity(base.world.time) if wind is not None else np.zeros(3)
            out[gt] = np.concatenate([pose, R_lw_true @ s.relative_velocity, R_lw_true @ w])
        return np.clip(out, self._low, self._high).astype(np.float32)

    @staticmethod
    def _pose_block(
        R_lb: NDArray[np.float64],
        position: Any,
        euler: Any,
        rotation: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64]:
        """Scaled (position 3, normal 3, cos/sin yaw 2) of a deck pose in the body frame."""
        R_bd = rotation if rotation is not None else matrix_from_euler(*(float(v) for v in euler))
        p = R_lb @ np.asarray(position, dtype=np.float64) / POSITION_SCALE
        R_ld = R_lb @ R_bd
        yaw = math.atan2(R_ld[1, 0], R_ld[0, 0])
        return np.concatenate([p, R_ld[:, 2], [math.cos(yaw), math.sin(yaw)]])


def make_deck_landing_v1(
    raw: bool = False,
    privileged: bool = False,
    deck_motion: bool = False,
    calibration: Calibration | str | os.PathLike[str] | None = None,
    max_residual: float = 0.01,
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    fused_params: FusedParams | None = None,
    **env_kwargs: Any,
) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckLanding-v1``: :class:`~ihrcf_env.envs.landing_v1.DeckLandingV1Env`
    wrapped with the estimators (:class:`DeckPoseObservation`, no image) and
    :class:`LandingObservation`; ``raw=True`` gives the raw env. No image is observed, so the rendered
    camera renders only the tag's window (``camera_output="corners"`` unless given). Options are
    checked before any physics client exists; a failed wrapper closes the env."""
    names = check_wrapper_options(calibration, False, False, max_residual, estimators, raw, fused_params)
    for name, flag in (("privileged", privileged), ("deck_motion", deck_motion)):
        if not isinstance(flag, bool | np.bool_):
            raise TypeError(f"{name} must be True or False, got {type(flag).__name__} {flag!r}")
    if deck_motion and "fused" not in names:
        raise ValueError(
            f"deck_motion needs the fused estimator (estimators must include 'fused'), got {names}"
        )
    from ihrcf_env.envs.landing_v1 import DeckLandingV1Env

    if raw:
        for name, flag in (("privileged", privileged), ("deck_motion", deck_motion)):
            if flag:
                raise ValueError(f"{name} is an observation-wrapper option: it has no effect with raw=True")
        return DeckLandingV1Env(**env_kwargs)
    if env_kwargs.get("camera", True) is not False:
        env_kwargs.setdefault("camera_output", "corners")  # no image in the observation: the tag window
    load_calibration(calibration)  # a bad file fails before any physics client exists
    env = DeckLandingV1Env(**env_kwargs)
    try:
        poses = DeckPoseObservation(
            env,
            calibration=calibration,  # as given: the env spec records it (gym.make(env.spec) rebuilds)
            keep_image=False,
            max_residual=max_residual,
            estimators=names,
            fused_params=fused_params,
        )
        return LandingObservation(poses, privileged=bool(privileged), deck_motion=bool(deck_motion))
    except BaseException:
        env.close()
        raise
