"""The one rollout: fly a policy in the wrapped env and record every step for scoring.

Used by the accuracy experiment (a motionless hover, :mod:`ihrcf_env.experiments.accuracy`), the
hover-and-track run (:mod:`ihrcf_env.experiments.hover_and_track`) and the tests.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import euler_from_matrix, matrix_from_quat, wrap_angle
from ihrcf_env.core.metrics import ErrorStats, error_stats, pose_errors
from ihrcf_env.experiments.progress import Progress

#: A policy: the env's observation -> normalised action in [-1, 1]^4.
Policy = Callable[[Mapping[str, Any]], ArrayLike]


@dataclass
class Recording:
    """Time series of one rollout, one row per control step (after the step).

    Poses are the deck's in the drone body frame (FLU), positions in m and Euler angles
    (roll, pitch, yaw, Z-Y-X) in rad; an invalid estimate reads zeros with ``valid = False``.
    """

    time: NDArray[np.float64]  # (n,) s, simulated
    position: dict[str, NDArray[np.float64]]  # source -> (n, 3) m
    euler: dict[str, NDArray[np.float64]]  # source -> (n, 3) rad
    valid: dict[str, NDArray[np.bool_]]  # estimator -> (n,)
    ranges: NDArray[np.float64]  # (n, 4) m
    ranges_valid: NDArray[np.bool_]  # (n, 4)
    command: NDArray[np.float64]  # (n, 4) (vx, vy, vz, yaw rate) in m/s, rad/s
    drone_minus_deck: NDArray[np.float64]  # (n, 3) m, world, ground truth (reporting only)
    heading_error: NDArray[np.float64]  # (n,) rad, drone yaw minus deck yaw, ground truth (reporting only)
    wall_time: float  # s, the simulation loop
    settings: dict[str, Any] = field(default_factory=dict)
    ended_early: str = ""  # why the episode ended before the requested steps ("" if it did not)
    estimators: tuple[str, ...] = ("ihrcf", "atda")  # recorded estimators, in observation order

    @property
    def sources(self) -> tuple[str, ...]:
        """Recorded deck-pose sources: ``"gt"`` (ground truth), then the estimators."""
        return ("gt", *self.estimators)

    @property
    def n(self) -> int:
        """Number of recorded control steps."""
        return int(self.time.shape[0])

    def pose_errors(self, estimator: str) -> NDArray[np.float64]:
        """(n, 6) estimate minus ground truth (m, deg; see :func:`ihrcf_env.core.metrics.pose_errors`),
        NaN rows where ``estimator`` is invalid."""
        return pose_errors(
            self.position[estimator],
            self.euler[estimator],
            self.position["gt"],
            self.euler["gt"],
            self.valid[estimator],
        )

    def error_stats(self) -> dict[str, ErrorStats]:
        """Per recorded estimator: MAE, peak and invalid count over the run."""
        return {k: error_stats(self.pose_errors(k)) for k in self.estimators}


def _yaw(quaternion: ArrayLike) -> float:
    return float(euler_from_matrix(matrix_from_quat(quaternion))[2])


def rollout(
    env: gym.Env,
    steps: int,
    policy: Policy | None = None,
    *,
    seed: int | None = 0,
    options: Mapping[str, Any] | None = None,
    progress: bool = False,
) -> Recording:
    """Reset ``env`` and step it ``steps`` times (fewer if the episode ends), recording every step.

    Args:
        env: ``ihrcf_env/DeckHover-v0`` (the wrapped env, dict observation), velocity actions.
        steps: control steps to run.
        policy: observation -> normalised action; ``None`` sends zeros (the autopilot holds its pose).
        seed, options: passed to ``env.reset``.
        progress: report progress on stderr (:class:`~ihrcf_env.experiments.progress.Progress`: a
            bar on a terminal, a plain line every few seconds otherwise).
    """
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps!r}")
    base = env.unwrapped
    hz = float(base.config.world.control_hz)  # type: ignore[attr-defined]
    max_velocity = np.asarray(base.max_velocity, dtype=np.float64)  # type: ignore[attr-defined]
    n = int(steps)
    obs, info = env.reset(seed=seed, options=dict(options) if options is not None else None)
    # every deck-pose estimate in the observation (a Dict with "valid"), in observation order
    estimators = tuple(
        key for key, v in obs.items() if key != "ground_truth" and isinstance(v, Mapping) and "valid" in v
    )
    obs_key = {"gt": "ground_truth", **{e: e for e in estimators}}
    t = np.zeros(n)
    pos = {k: np.zeros((n, 3)) for k in obs_key}
    eul = {k: np.zeros((n, 3)) for k in obs_key}
    valid = {k: np.zeros(n, dtype=bool) for k in estimators}
    ranges = np.zeros((n, 4))
    ranges_valid = np.zeros((n, 4), dtype=bool)
    command = np.zeros((n, 4))
    offset = np.zeros((n, 3))
    heading = np.zeros(n)
    ended_early = ""
    k = 0
    bar = Progress(n, "rollout", unit="step") if progress else None
    t0 = time.perf_counter()
    try:
        for k in range(n):
            action = np.zeros(4) if policy is None else np.asarray(policy(obs), dtype=np.float64)
            obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
            t[k] = info["time"]
            for src, key in obs_key.items():
                pos[src][k] = obs[key]["position"]
                eul[src][k] = obs[key]["euler"]
            for src in estimators:
                valid[src][k] = bool(obs[src]["valid"])
            ranges[k] = obs["ranges"]
            ranges_valid[k] = np.asarray(obs["ranges_valid"]).astype(bool)
            command[k] = action * max_velocity
            offset[k] = np.asarray(info["drone_position_world"]) - np.asarray(info["deck_position_world"])
            yaw_error = _yaw(info["drone_quaternion_world"]) - _yaw(info["deck_quaternion_world"])
            heading[k] = float(wrap_angle(yaw_error))
            if bar is not None:
                wall = time.perf_counter() - t0
                rtf = t[k] / wall if wall > 0 else math.nan
                bar.update(k + 1, f"sim {t[k]:.1f}/{n / hz:.1f} s, {rtf:.2f}x real time")
            if terminated or truncated:
                if k + 1 < n:
                    ended_early = (
                        "truncated" if truncated else f"{info.get('outcome')}: {info.get('crash_reason')}"
                    )
                break
        wall_time = time.perf_counter() - t0
    finally:
        if bar is not None:
            bar.close()
    m = k + 1
    return Recording(
        time=t[:m],
        position={s: a[:m] for s, a in pos.items()},
        euler={s: a[:m] for s, a in eul.items()},
        valid={s: a[:m] for s, a in valid.items()},
        ranges=ranges[:m],
        ranges_valid=ranges_valid[:m],
        command=command[:m],
        drone_minus_deck=offset[:m],
        heading_error=heading[:m],
        wall_time=wall_time,
        settings={"control_hz": int(hz), "seed": seed},
        ended_early=ended_early,
        estimators=estimators,
    )


__all__ = [
    "Policy",
    "Recording",
    "rollout",
]
