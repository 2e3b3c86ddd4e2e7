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
clipped into the space's bounds; never NaN.

The estimators are those of :data:`~ihrcf_env.core.estimators.DEFAULT_ESTIMATORS` (``ihrcf``,
``atda``, ``fused``) unless ``estimators=`` names others of the registry
(:mod:`ihrcf_env.core.estimators.registry`); everything below loops over their names, in order.
Every estimator gets the same :class:`~ihrcf_env.core.estimators.SensorFrame` per step: the tag
corners (detected once), the ranges, the IMU sample and the simulated time (``info["time"]``), so
a temporal filter (``fused``) sees the real frame interval. ``fused_params`` sets the fused
filter's :class:`~ihrcf_env.core.estimators.FusedParams`; by default they follow the env's ToF model
(:func:`fused_params_for_tof`: the VL53L1X's per-sensor offsets give the filter a common-mode
range-offset state).

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

import math
import numbers
import os
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.core.arrays import clip
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import (
    DEFAULT_ESTIMATORS,
    DeckPoseEstimator,
    DeckPoseSource,
    FusedParams,
    ImuSample,
    PoseEstimate,
    SensorFrame,
    check_estimator_names,
)
from ihrcf_env.core.rig import SensorRig

if TYPE_CHECKING:
    from ihrcf_env.envs.deck_landing import DeckLandingEnv
    from ihrcf_env.sim.sensors.tof import VL53L1X

POSITION_BOUND = 10.0  # m
#: The key of the ground-truth pose block; always after the estimators.
GROUND_TRUTH = "ground_truth"
#: The pose keys of ``ihrcf_env/DeckLanding-v0``, in observation order.
ESTIMATE_KEYS: tuple[str, ...] = (*DEFAULT_ESTIMATORS, GROUND_TRUTH)
#: Fields of one pose block of the flat observation: (name, size).
POSE_FIELDS: tuple[tuple[str, int], ...] = (("position", 3), ("euler", 3), ("valid", 1))
POSE_SIZE = sum(n for _, n in POSE_FIELDS)
#: Sensor values at the start of the flat observation: (flat name, path in the raw observation, size).
SENSOR_FIELDS: tuple[tuple[str, tuple[str, ...], int], ...] = (
    ("ranges", ("ranges",), 4),
    ("ranges_valid", ("ranges_valid",), 4),
    ("imu.quaternion", ("imu", "quaternion"), 4),
    ("imu.angular_velocity", ("imu", "angular_velocity"), 3),
    ("imu.linear_acceleration", ("imu", "linear_acceleration"), 3),
)


def flat_slices(estimators: Iterable[str] = DEFAULT_ESTIMATORS) -> dict[str, slice]:
    """Named slices of the flat observation (``flatten=True``) for the given estimators.

    Keys: ``"ranges"``, ``"ranges_valid"``, ``"imu.quaternion"``, ``"imu.angular_velocity"``,
    ``"imu.linear_acceleration"``, then for each estimator name and ``"ground_truth"`` the whole
    7-value block under its name and its parts under ``f"{name}.position"``, ``f"{name}.euler"``,
    ``f"{name}.valid"``; ``"all"`` is the whole vector. For DeckLanding-v0: ``ihrcf`` 18:25,
    ``atda`` 25:32, ``fused`` 32:39, ``ground_truth`` 39:46 (``all`` 0:46).
    """
    out: dict[str, slice] = {}
    i = 0
    for name, _, n in SENSOR_FIELDS:
        out[name] = slice(i, i + n)
        i += n
    for key in (*check_estimator_names(estimators), GROUND_TRUTH):
        out[key] = slice(i, i + POSE_SIZE)
        for field, n in POSE_FIELDS:
            out[f"{key}.{field}"] = slice(i, i + n)
            i += n
    out["all"] = slice(0, i)
    return out


def _rig(calibration: Calibration) -> SensorRig:
    r = calibration.rig
    cp = r["camera_position"]
    return SensorRig(float(r["a"]), float(r["theta"]), (float(cp[0]), float(cp[1]), float(cp[2])))


def estimator_from_calibration(
    calibration: Calibration,
    tag_size: float,
    tag_id: int,
    max_residual: float = 0.01,
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    fused_params: FusedParams | None = None,
) -> DeckPoseEstimator:
    """A :class:`DeckPoseEstimator` using a calibration file's table (IHRCF, fused) and chessboard K
    (ATDA, fused)."""
    return DeckPoseEstimator(
        rig=_rig(calibration),
        tag_size=tag_size,
        tag_id=tag_id,
        K=calibration.K,
        dist=calibration.dist,
        touch_pixels=calibration.tables,
        max_residual=max_residual,
        estimators=estimators,
        fused=fused_params,
    )


def fused_params_for_tof(model: VL53L1X | None) -> FusedParams:
    """The fused filter's parameters for the env's ToF model: with the VL53L1X model (per-sensor
    constant offsets of sigma ``offset_sigma``) a common-mode range-offset state of prior sigma
    ``offset_sigma / 2`` (the mean of four independent offsets); the ideal ToF (None): none."""
    if model is None or model.offset_sigma <= 0:
        return FusedParams()
    return FusedParams(range_offset_sigma=model.offset_sigma / 2)


def _describe(value: Any) -> str:
    return f"{value!r} ({type(value).__name__})"


def check_wrapper_options(
    calibration: Any = None,
    keep_image: Any = None,
    flatten: Any = False,
    max_residual: Any = 0.01,
    estimators: Any = DEFAULT_ESTIMATORS,
    raw: Any = False,
    fused_params: Any = None,
) -> tuple[str, ...]:
    """Type and value checks of the wrapper's options, before anything is built: TypeError (wrong
    type) or ValueError (bad value) naming the option. Returns the estimator names as a tuple."""
    if keep_image is not None and not isinstance(keep_image, bool | np.bool_):
        raise TypeError(f"keep_image must be a bool (True or False) or None, got {_describe(keep_image)}")
    for name, value in (("raw", raw), ("flatten", flatten)):
        if not isinstance(value, bool | np.bool_):
            raise TypeError(f"{name} must be a bool (True or False), got {_describe(value)}")
    if isinstance(max_residual, bool | np.bool_) or not isinstance(max_residual, numbers.Real):
        raise TypeError(f"max_residual must be a real number (m), got {_describe(max_residual)}")
    if not (math.isfinite(float(max_residual)) and float(max_residual) > 0):
        raise ValueError(f"max_residual must be positive and finite (m), got {max_residual!r}")
    if calibration is not None and not isinstance(calibration, Calibration | str | os.PathLike):
        raise TypeError(
            "calibration must be a Calibration, a path (str or os.PathLike) to a calibration file, or "
            f"None for the shipped file; got {_describe(calibration)}"
        )
    if fused_params is not None and not isinstance(fused_params, FusedParams):
        raise TypeError(
            "fused_params must be an ihrcf_env.core.estimators.FusedParams or None, got "
            f"{_describe(fused_params)}"
        )
    return check_estimator_names(estimators)


def load_calibration(calibration: Calibration | str | os.PathLike[str] | None) -> Calibration:
    """The calibration itself, the file at a path, or the shipped file for None."""
    if isinstance(calibration, Calibration):
        return calibration
    return Calibration.load(default_calibration_path() if calibration is None else calibration)


def _pose_space() -> spaces.Dict:
    return spaces.Dict(
        {
            "position": spaces.Box(-POSITION_BOUND, POSITION_BOUND, (3,), np.float32),
            "euler": spaces.Box(-math.pi, math.pi, (3,), np.float32),
            "valid": spaces.Discrete(2),
        }
    )


def _pose_obs(position: NDArray[np.float64], euler: NDArray[np.float64], valid: bool) -> dict[str, Any]:
    return {
        "position": clip(position, -POSITION_BOUND, POSITION_BOUND).astype(np.float32),
        "euler": clip(euler, -math.pi, math.pi).astype(np.float32),
        "valid": int(bool(valid)),
    }


def _get(tree: Mapping[str, Any], path: tuple[str, ...]) -> Any:
    for key in path:
        tree = tree[key]
    return tree


def _bounds(space: spaces.Space, n: int, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(low, high) of a raw observation field that goes into the flat vector."""
    if isinstance(space, spaces.MultiBinary) and space.shape == (n,):
        return np.zeros(n), np.ones(n)
    if isinstance(space, spaces.Box) and space.shape == (n,):
        return space.low.astype(np.float64), space.high.astype(np.float64)
    raise ValueError(f"flatten=True: the env's {name} space must be a Box or MultiBinary of shape ({n},)")


class DeckPoseObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Adds each estimator's deck pose and ``ground_truth`` (body frame) to the observation.

    Args:
        env: a ``DeckLandingEnv`` (possibly wrapped) with its camera on.
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
            None for the defaults matching the env's ToF model (:func:`fused_params_for_tof`).

    Bad options raise TypeError / ValueError naming the option before anything is built.

    Attributes:
        estimator: the :class:`DeckPoseEstimator` (detection once per frame + the estimators).
        estimators: ordered mapping name -> :class:`DeckPoseSource` (``estimator.sources``).
        pose_keys: the estimator names then ``"ground_truth"``: the pose blocks, in order.
        flat_slices: name -> slice of the flat observation (see :func:`flat_slices`; also valid
            without ``flatten``, describing what the flat vector would be).
        last_estimates: name -> :class:`PoseEstimate` of the last observation (None before reset).
        last_frame: the last :class:`SensorFrame` fed to the estimators (None before reset).
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
    ) -> None:
        names = check_wrapper_options(
            calibration, keep_image, flatten, max_residual, estimators, fused_params=fused_params
        )
        gym.utils.RecordConstructorArgs.__init__(
            self,
            calibration=calibration,
            keep_image=keep_image,
            flatten=flatten,
            max_residual=max_residual,
            estimators=names,
            fused_params=fused_params,
        )
        gym.ObservationWrapper.__init__(self, env)
        base = cast("DeckLandingEnv", env.unwrapped)
        cam = getattr(base, "camera_config", None)
        if cam is None:
            raise ValueError(
                "camera=False leaves IHRCF and ATDA without an image: use camera=True, or raw=True "
                "(gym.make) / the raw env for a camera-less simulation"
            )
        cal = load_calibration(calibration)
        cal.check_matches(cam.width, cam.height, cam.fov, base.rig, distortion=cam.distortion)
        self.calibration = cal
        deck = base.config.deck
        if fused_params is None:
            fused_params = fused_params_for_tof(getattr(getattr(base.config, "tof", None), "model", None))
        self.estimator = estimator_from_calibration(
            cal, deck.tag_size, deck.tag_id, float(max_residual), estimators=names, fused_params=fused_params
        )
        self.estimators: dict[str, DeckPoseSource] = self.estimator.sources
        self.pose_keys: tuple[str, ...] = (*names, GROUND_TRUTH)
        self.flat_slices: dict[str, slice] = flat_slices(names)
        has_image = base.config.camera_output == "image"
        if keep_image and not has_image:
            raise ValueError(
                f"keep_image=True needs the camera image, but the env delivers only the tag corners "
                f'(camera_model={base.config.camera_model!r}, camera_output="corners"): use '
                'keep_image=False, or camera_model="rendered" with camera_output="image"'
            )
        self.flatten = bool(flatten)
        self.keep_image = has_image and keep_image is not False and not self.flatten
        self.last_estimates: dict[str, PoseEstimate] | None = None
        self.last_frame: SensorFrame | None = None
        self.last_ages: dict[str, float] = {}
        self._frame_times: dict[str, float] = {}  # estimator -> time (s) of the frame it last used
        self._camera_time = math.nan  # time (s) of the camera frame last fed to the estimators

        inner = env.observation_space
        if not isinstance(inner, spaces.Dict):
            raise ValueError(f"the env's observation space must be a Dict, got {type(inner).__name__}")
        d = {k: v for k, v in inner.spaces.items() if k != "image" or self.keep_image}
        for key in self.pose_keys:
            d[key] = _pose_space()
        self._dict_space = spaces.Dict(d)
        # the flat layout, resolved once: (path in the raw observation, slice), and per pose block
        # (key, position slice, euler slice, valid index)
        self._flat_sensors = tuple((path, self.flat_slices[name]) for name, path, _ in SENSOR_FIELDS)
        self._flat_poses = tuple(
            (
                key,
                self.flat_slices[f"{key}.position"],
                self.flat_slices[f"{key}.euler"],
                self.flat_slices[f"{key}.valid"].start,
            )
            for key in self.pose_keys
        )
        if self.flatten:
            size = self.flat_slices["all"].stop
            low, high = np.empty(size), np.empty(size)
            for name, path, n in SENSOR_FIELDS:
                sl = self.flat_slices[name]
                low[sl], high[sl] = _bounds(cast(spaces.Space, _get(inner.spaces, path)), n, name)
            for key in self.pose_keys:
                for field, bound in (("position", POSITION_BOUND), ("euler", math.pi), ("valid", None)):
                    sl = self.flat_slices[f"{key}.{field}"]
                    low[sl], high[sl] = (0.0, 1.0) if bound is None else (-bound, bound)
            self.observation_space = spaces.Box(
                low.astype(np.float32), high.astype(np.float32), (size,), np.float32
            )
        else:
            self.observation_space = self._dict_space

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self.estimator.reset()
        self.last_estimates = None
        self.last_frame = None
        self.last_ages = {}
        self._frame_times = {}
        self._camera_time = math.nan
        obs, info = self.env.reset(seed=seed, options=options)
        out = self._observe(obs, info)
        return out, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        out = self._observe(obs, info)
        return out, float(reward), terminated, truncated, info

    def _observe(self, obs: dict[str, Any], info: dict[str, Any]) -> Any:
        """The wrapped observation; adds each estimate's reason, residual and age to ``info``."""
        out = self.observation(
            obs,
            time=info.get("time"),
            camera_time=info.get("camera_time"),
            tag_reason=info.get("tag_reason", ""),
        )
        if self.last_estimates is not None:
            for name, est in self.last_estimates.items():
                info[f"{name}_reason"] = est.reason
                info[f"{name}_residual"] = est.residual
                info[f"{name}_age"] = self.last_ages.get(name, 0.0)
        return out

    def sensor_frame(
        self, observation: Mapping[str, Any], time: float | None = None, tag_reason: str = ""
    ) -> SensorFrame:
        """The :class:`SensorFrame` of a raw observation at ``time`` (s; None: unknown, NaN): the tag
        detected once in ``image``, or the env's ``tag_corners`` (``tag_reason``: why they are
        missing)."""
        imu = observation["imu"]
        t = math.nan if time is None else float(time)
        ranges = observation["ranges"]
        valid = np.asarray(observation["ranges_valid"]).astype(bool)
        sample = ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"])
        if "image" in observation:
            return self.estimator.frame(observation["image"], ranges, valid, time=t, imu=sample)
        detected = bool(observation["tag_detected"])
        return SensorFrame(
            time=t,
            corners=np.asarray(observation["tag_corners"], dtype=np.float64) if detected else None,
            ranges=np.asarray(ranges, dtype=np.float64),
            ranges_valid=valid,
            corners_reason="" if detected else tag_reason,
            imu=sample,
        )

    def observation(
        self,
        observation: dict[str, Any],
        time: float | None = None,
        camera_time: float | None = None,
        tag_reason: str = "",
    ) -> Any:
        """The wrapped observation of a raw one; ``time`` (s) is the frame's time (None: unknown).

        ``camera_time`` (s, the env's ``info["camera_time"]``): when the camera frame in
        ``observation`` was taken. If it is the frame the estimators already used (``camera_hz``
        below the control rate), the estimates are held, not recomputed; :attr:`last_ages` (and
        ``info[f"{name}_age"]``) say how old (s) the frame behind each estimate is."""
        now = math.nan if time is None else float(time)
        fresh = (
            camera_time is None
            or self.last_estimates is None
            or not (math.isfinite(camera_time) and camera_time == self._camera_time)
        )
        if fresh:
            frame = self.sensor_frame(observation, time, tag_reason)
            estimates = self.estimator.update(frame)
            self.last_frame = frame
            self.last_estimates = estimates
            stamp = now if camera_time is None else float(camera_time)
            self._camera_time = stamp
            self._frame_times = dict.fromkeys(estimates, stamp)
        assert self.last_estimates is not None
        estimates = self.last_estimates
        self.last_ages = {
            name: (now - t) if math.isfinite(now) and math.isfinite(t) else 0.0
            for name, t in self._frame_times.items()
        }
        gt_pos, gt_euler = cast("DeckLandingEnv", self.env.unwrapped).deck_pose_body()
        if not self.flatten:
            poses = {name: _pose_obs(e.position, e.euler, e.valid) for name, e in estimates.items()}
            poses[GROUND_TRUTH] = _pose_obs(gt_pos, gt_euler, True)
            out = {k: v for k, v in observation.items() if k != "image" or self.keep_image}
            out.update(poses)
            return out
        flat = np.empty(self.flat_slices["all"].stop, np.float32)
        for path, sl in self._flat_sensors:
            flat[sl] = _get(observation, path)
        for key, position_sl, euler_sl, valid_i in self._flat_poses:
            if key == GROUND_TRUTH:
                position, euler, valid = gt_pos, gt_euler, True
            else:
                e = estimates[key]
                position, euler, valid = e.position, e.euler, e.valid
            # as _pose_obs: float64 values rounded to float32 by the assignment, as by astype
            flat[position_sl] = clip(position, -POSITION_BOUND, POSITION_BOUND)
            flat[euler_sl] = clip(euler, -math.pi, math.pi)
            flat[valid_i] = int(bool(valid))
        return flat


def make_deck_landing(
    raw: bool = False,
    calibration: Calibration | str | os.PathLike[str] | None = None,
    keep_image: bool | None = None,
    flatten: bool = False,
    max_residual: float = 0.01,
    estimators: Iterable[str] = DEFAULT_ESTIMATORS,
    fused_params: FusedParams | None = None,
    **env_kwargs: Any,
) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckLanding-v0``: the env wrapped with :class:`DeckPoseObservation`,
    or the raw :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv` with ``raw=True``.

    The wrapper's options are checked and the calibration file is read before the env is built; if
    the wrapper still fails (e.g. a calibration made for another camera), the env is closed before
    the error propagates.

    Without the image in the observation (``keep_image=False`` or ``flatten=True``) the rendered
    camera renders only the tag's window (``camera_output="corners"``, unless given)."""
    names = check_wrapper_options(
        calibration, keep_image, flatten, max_residual, estimators, raw, fused_params
    )
    from ihrcf_env.envs.deck_landing import DeckLandingEnv

    if raw:
        if keep_image is not None or flatten:
            raise ValueError("keep_image and flatten are wrapper options: they have no effect with raw=True")
        return DeckLandingEnv(**env_kwargs)
    if (keep_image is False or flatten) and env_kwargs.get("camera", True) is not False:
        env_kwargs.setdefault("camera_output", "corners")
    cal = load_calibration(calibration)
    env = DeckLandingEnv(**env_kwargs)
    try:
        return DeckPoseObservation(
            env,
            calibration=cal,
            keep_image=keep_image,
            flatten=flatten,
            max_residual=max_residual,
            estimators=names,
            fused_params=fused_params,
        )
    except BaseException:
        env.close()
        raise
