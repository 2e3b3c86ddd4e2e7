"""Observation wrapper exposing the IHRCF and ATDA deck-pose estimates beside ground truth.

Each of ``obs["ihrcf"]``, ``obs["atda"]`` and ``obs["ground_truth"]`` is a Dict with

* ``"position"``: (3,) float32, the deck frame origin (tag centre) in the drone body frame (m),
* ``"euler"``: (3,) float32, roll, pitch, yaw of the deck in the body frame (rad, Z-Y-X),
* ``"valid"``: int 0/1.

While an estimate is invalid (tag not found, fewer than 3 valid ranges, degenerate geometry, range
outside the calibration table, fit residual too large) it reports position (0, 0, 0) and euler
(0, 0, 0) with ``valid = 0``; the reason is in ``info["ihrcf_reason"]`` / ``info["atda_reason"]``
(also on ``wrapper.last_estimates``). Values are clipped into the space's bounds; never NaN.

``flatten=True`` gives one float32 Box for RL libraries, in this order: ranges (4), ranges_valid (4),
imu quaternion (4), angular velocity (3), linear acceleration (3), then for ihrcf, atda and
ground_truth each position (3), euler (3), valid (1): 39 values. The image is not part of it.
"""

from __future__ import annotations

import math
import os
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import DeckPoseEstimator, PoseEstimate
from ihrcf_env.core.rig import SensorRig

POSITION_BOUND = 10.0  # m
ESTIMATE_KEYS = ("ihrcf", "atda", "ground_truth")


def estimator_from_calibration(
    calibration: Calibration, tag_size: float, tag_id: int, max_residual: float = 0.01
) -> DeckPoseEstimator:
    """A :class:`DeckPoseEstimator` using a calibration file's table (IHRCF) and chessboard K (ATDA)."""
    return DeckPoseEstimator(
        rig=SensorRig(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in calibration.rig.items()}),
        tag_size=tag_size,
        tag_id=tag_id,
        K=calibration.K,
        dist=calibration.dist,
        touch_pixels=calibration.tables,
        max_residual=max_residual,
    )


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
        "position": np.clip(position, -POSITION_BOUND, POSITION_BOUND).astype(np.float32),
        "euler": np.clip(euler, -math.pi, math.pi).astype(np.float32),
        "valid": int(bool(valid)),
    }


class DeckPoseObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Adds ``ihrcf``, ``atda`` and ``ground_truth`` deck poses (body frame) to the observation.

    Args:
        env: a ``DeckLandingEnv`` (possibly wrapped) with its camera on.
        calibration: a :class:`Calibration`, a path to a calibration file, or None for the file
            shipped in ``assets/`` (which must match the env's camera; otherwise a
            :class:`~ihrcf_env.core.calibration.CalibrationError` gives the command that makes one).
        keep_image: keep the raw camera image in the observation.
        flatten: return one float32 Box (see the module docstring); implies no image.
        max_residual: IHRCF rigid-fit RMS (m) above which the estimate is declared invalid.
    """

    def __init__(
        self,
        env: gym.Env,
        calibration: Calibration | str | os.PathLike[str] | None = None,
        keep_image: bool = True,
        flatten: bool = False,
        max_residual: float = 0.01,
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, calibration=calibration, keep_image=keep_image, flatten=flatten, max_residual=max_residual
        )
        gym.ObservationWrapper.__init__(self, env)
        base = env.unwrapped
        cam = getattr(base, "camera_config", None)
        if cam is None:
            raise ValueError(
                "camera=False leaves IHRCF and ATDA without an image: use camera=True, or raw=True "
                "(gym.make) / the raw env for a camera-less simulation"
            )
        if not (math.isfinite(max_residual) and max_residual > 0):
            raise ValueError(f"max_residual must be positive (m), got {max_residual!r}")
        if calibration is None:
            cal = Calibration.load(default_calibration_path())
        elif isinstance(calibration, Calibration):
            cal = calibration
        else:
            cal = Calibration.load(calibration)
        cal.check_matches(cam.width, cam.height, cam.fov, base.rig, distortion=cam.distortion)
        self.calibration = cal
        deck = base.config.deck
        self.estimator = estimator_from_calibration(cal, deck.tag_size, deck.tag_id, max_residual)
        self.keep_image = bool(keep_image) and not flatten
        self.flatten = bool(flatten)
        self.last_estimates: tuple[PoseEstimate, PoseEstimate] | None = None

        inner = env.observation_space
        assert isinstance(inner, spaces.Dict)
        d = {k: v for k, v in inner.spaces.items() if k != "image" or self.keep_image}
        for key in ESTIMATE_KEYS:
            d[key] = _pose_space()
        self._dict_space = spaces.Dict(d)
        if self.flatten:
            lows, highs = [], []
            for key in ("ranges", "ranges_valid"):
                sp = inner[key]
                lows.append(np.zeros(4) if key == "ranges_valid" else sp.low)
                highs.append(np.ones(4) if key == "ranges_valid" else sp.high)
            for key in ("quaternion", "angular_velocity", "linear_acceleration"):
                lows.append(inner["imu"][key].low)
                highs.append(inner["imu"][key].high)
            for _ in ESTIMATE_KEYS:
                lows += [np.full(3, -POSITION_BOUND), np.full(3, -math.pi), np.zeros(1)]
                highs += [np.full(3, POSITION_BOUND), np.full(3, math.pi), np.ones(1)]
            low = np.concatenate(lows).astype(np.float32)
            high = np.concatenate(highs).astype(np.float32)
            self.observation_space = spaces.Box(low, high, low.shape, np.float32)
        else:
            self.observation_space = self._dict_space

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self.estimator.reset()
        obs, info = self.env.reset(seed=seed, options=options)
        out = self.observation(obs)
        self._add_reasons(info)
        return out, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        out = self.observation(obs)
        self._add_reasons(info)
        return out, reward, terminated, truncated, info

    def _add_reasons(self, info: dict) -> None:
        if self.last_estimates is not None:
            info["ihrcf_reason"] = self.last_estimates[0].reason
            info["atda_reason"] = self.last_estimates[1].reason
            info["ihrcf_residual"] = self.last_estimates[0].residual

    def observation(self, observation: dict[str, Any]) -> Any:
        ihrcf, atda = self.estimator.estimate(
            observation["image"], observation["ranges"], observation["ranges_valid"].astype(bool)
        )
        self.last_estimates = (ihrcf, atda)
        gt_pos, gt_euler = self.env.unwrapped.deck_pose_body()
        out = {k: v for k, v in observation.items() if k != "image" or self.keep_image}
        out["ihrcf"] = _pose_obs(ihrcf.position, ihrcf.euler, ihrcf.valid)
        out["atda"] = _pose_obs(atda.position, atda.euler, atda.valid)
        out["ground_truth"] = _pose_obs(gt_pos, gt_euler, True)
        if not self.flatten:
            return out
        imu = out["imu"]
        parts = [
            out["ranges"],
            out["ranges_valid"].astype(np.float32),
            imu["quaternion"],
            imu["angular_velocity"],
            imu["linear_acceleration"],
        ]
        for key in ESTIMATE_KEYS:
            e = out[key]
            parts += [e["position"], e["euler"], np.array([e["valid"]], np.float32)]
        return np.concatenate(parts).astype(np.float32)


def make_deck_landing(
    raw: bool = False,
    calibration: Calibration | str | os.PathLike[str] | None = None,
    keep_image: bool = True,
    flatten: bool = False,
    max_residual: float = 0.01,
    **env_kwargs: Any,
) -> gym.Env:
    """Entry point of ``ihrcf_env/DeckLanding-v0``: the env wrapped with :class:`DeckPoseObservation`,
    or the raw :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv` with ``raw=True``."""
    from ihrcf_env.envs.deck_landing import DeckLandingEnv

    env = DeckLandingEnv(**env_kwargs)
    if raw:
        return env
    try:
        return DeckPoseObservation(
            env, calibration=calibration, keep_image=keep_image, flatten=flatten, max_residual=max_residual
        )
    except Exception:
        env.close()
        raise
