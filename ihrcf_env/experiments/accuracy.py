"""The paper's accuracy experiment: a motionless drone hovering 1 m above the moving deck.

The drone holds its world pose (zero velocity actions) straight above the deck centre, nose along
the deck, while the deck moves beneath it; the IHRCF and ATDA deck poses (body frame) are scored
against ground truth over the valid frames (:mod:`ihrcf_env.core.metrics`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym

from ihrcf_env.control.hover import HoverGains, HoverTracker
from ihrcf_env.core.metrics import ErrorStats
from ihrcf_env.experiments.rollout import Recording, rollout

#: ``env.reset`` options of the paper's hover: 1 m above the deck centre, aligned with the deck.
HOVER_START: dict[str, Any] = {"altitude": 1.0, "offset": (0.0, 0.0), "yaw": 0.0}


def hover_rollout(
    env: gym.Env, frames: int, seed: int = 0, altitude: float = 1.0, track: str | None = None
) -> Recording:
    """Reset ``env`` (``ihrcf_env/DeckHover-v0``) to :data:`HOVER_START` (at ``altitude`` m above
    the deck) and record ``frames`` control steps of the hover; score it with
    :meth:`Recording.error_stats`.

    ``track=None``: zero velocity commands, the autopilot holds its position (on its own drifting
    navigation estimate under ``autopilot_feedback="estimated"``). ``track="fused"`` (or another
    estimate's key): the drone is kept horizontally over the tag by :class:`HoverTracker` on that
    estimate (0.5 (m/s)/m, no vertical or yaw command: the altitude stays on the autopilot, so the
    deck still heaves beneath the drone as in the paper's experiment) -- what a drone whose GNSS/INS
    drifts ~0.4 m in 30 s needs to keep the tag in view.
    """
    policy = None
    if track is not None:
        base = env.unwrapped
        tracker = HoverTracker(
            altitude,
            base.max_velocity,  # type: ignore[attr-defined]
            estimator=track,
            gains=HoverGains(k_xy=0.5, k_z=0.0, k_yaw=0.0),
        )
        policy = tracker.act
    return rollout(env, frames, policy, seed=seed, options={**HOVER_START, "altitude": float(altitude)})


def make_accuracy_env(
    frames: int,
    tof_noise: str | None = None,
    distortion: tuple[float, float] = (0.0, 0.0),
    calibration: str | Path | None = None,
    deck_profile: str = "paper",
    **env_kwargs: Any,
) -> gym.Env:
    """``ihrcf_env/DeckHover-v0`` for a ``frames``-step accuracy run (no image kept).

    Args:
        frames: control steps to be run; the episode limits are set beyond them.
        tof_noise: ``"ideal"`` or ``"realistic"`` ToF ranges; None follows ``sensor_preset``.
        distortion: camera radial distortion (k1, k2); a distorted camera needs ``calibration``.
        calibration: calibration file made for this camera (default: the shipped one).
        deck_profile: deck motion, ``"paper"`` by default.
        env_kwargs: further ``gym.make`` arguments.
    """
    hz = int(env_kwargs.get("control_hz", 20))
    if tof_noise is not None:
        env_kwargs["tof_noise"] = tof_noise
    return gym.make(
        "ihrcf_env/DeckHover-v0",
        calibration=calibration,
        keep_image=False,
        camera_distortion=tuple(distortion),
        deck_profile=deck_profile,
        max_episode_steps=frames + 10,
        horizon_s=frames / hz + 2,
        **env_kwargs,
    )


def accuracy(
    frames: int,
    tof_noise: str | None = None,
    distortion: tuple[float, float] = (0.0, 0.0),
    seed: int = 0,
    calibration: str | Path | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    altitude: float = 1.0,
    track: str | None = None,
) -> dict[str, ErrorStats]:
    """Run the paper's hover (``altitude`` m above the deck, 1 m in the paper) for ``frames`` steps;
    per estimator in the observation: MAE and peak (6,) = X, Y, Z (m), roll, pitch, yaw (deg), and
    the invalid-frame count.

    See :func:`make_accuracy_env` for the other arguments and :func:`hover_rollout` for ``track``.
    """
    env = make_accuracy_env(frames, tof_noise, distortion, calibration, **dict(env_kwargs or {}))
    try:
        return hover_rollout(env, frames, seed, altitude, track).error_stats()
    finally:
        env.close()


__all__ = [
    "HOVER_START",
    "accuracy",
    "hover_rollout",
    "make_accuracy_env",
]
