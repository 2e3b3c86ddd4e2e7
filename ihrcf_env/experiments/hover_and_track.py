"""Hover above the moving deck tracking it with the IHRCF estimate (the paper's Section 4 run).

The drone flies in velocity mode with :class:`ihrcf_env.control.hover.HoverTracker` on
``obs["ihrcf"]`` only; ground truth is recorded for the error statistics, never used to fly. The
run's :class:`~ihrcf_env.experiments.rollout.Recording` gives Table 2
(:func:`ihrcf_env.core.metrics.table2_text` of :meth:`Recording.error_stats`), a tracking summary,
a CSV time series (:func:`save_csv`) and the figures (:func:`ihrcf_env.experiments.figures.save_figures`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.hover import HoverTracker
from ihrcf_env.experiments.rollout import Recording, rollout

#: Agent/camera rate of the run (Hz), the env's default.
CONTROL_HZ = 20


def run(
    seconds: float = 130.0,
    seed: int = 0,
    profile: str = "paper",
    tof_noise: str = "ideal",
    height: float = 1.0,
    progress: bool = True,
) -> Recording:
    """Fly the IHRCF tracking hover for ``seconds`` of simulated time and record every step.

    Args:
        seconds: simulated duration (s); the paper's run lasts 130 s.
        seed: seeds the start (offset up to 0.1 m, yaw up to 0.2 rad), ToF noise and sea state.
        profile: deck motion, ``"paper"``, ``"sea_state"`` or ``"static"``.
        tof_noise: ``"ideal"`` or ``"realistic"`` ToF ranges.
        height: hover height above the deck (m); also the start altitude.
        progress: draw a progress bar on stderr.
    """
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be positive, got {seconds!r}")
    n = max(int(round(seconds * CONTROL_HZ)), 1)
    env = gym.make(
        "ihrcf_env/DeckHover-v0",
        deck_profile=profile,
        tof_noise=tof_noise,
        keep_image=False,
        # gym.make keeps the registered 600-step (30 s) TimeLimit when given None: set it explicitly
        max_episode_steps=n,
        control_hz=CONTROL_HZ,
    )
    try:
        tracker = HoverTracker(height, env.unwrapped.max_velocity)  # type: ignore[attr-defined]
        rec = rollout(env, n, tracker.act, seed=seed, options={"altitude": height}, progress=progress)
    finally:
        env.close()
    rec.settings.update(seconds=seconds, profile=profile, tof_noise=tof_noise, height=height)
    return rec


def tracking_summary(rec: Recording) -> str:
    """How well the drone tracked the deck (scored on ground truth, after the first 10 s or the
    first half of the run, whichever is shorter)."""
    settled = rec.time >= min(10.0, rec.time[-1] / 2)
    d = rec.drone_minus_deck[settled]
    xy_mm = 1e3 * np.hypot(d[:, 0], d[:, 1])
    h_mm = 1e3 * d[:, 2]
    hdg = np.degrees(np.abs(rec.heading_error[settled]))
    return "\n".join(
        (
            f"Tracking with IHRCF (scored on ground truth, from t = {rec.time[settled][0]:.0f} s):",
            f"  horizontal offset drone-deck  mean {xy_mm.mean():5.1f} mm   max {xy_mm.max():5.1f} mm",
            f"  height above the deck         mean {h_mm.mean():5.0f} mm   std {h_mm.std():5.1f} mm",
            f"  heading error                 mean {hdg.mean():5.2f} deg  max {hdg.max():5.2f} deg",
        )
    )


def csv_header(estimators: Sequence[str] = ("ihrcf", "atda")) -> list[str]:
    """Column names of :func:`save_csv` for a recording of ``estimators`` (units in the names; angles
    in radians)."""
    cols = ["time_s"]
    for src in ("gt", *estimators):
        cols += [f"{src}_{a}_m" for a in "xyz"] + [f"{src}_{a}_rad" for a in ("roll", "pitch", "yaw")]
        if src != "gt":
            cols.append(f"{src}_valid")
    cols += [f"range{i}_m" for i in range(1, 5)] + [f"range{i}_valid" for i in range(1, 5)]
    cols += ["cmd_vx_mps", "cmd_vy_mps", "cmd_vz_mps", "cmd_yaw_rate_radps"]
    return cols


def save_csv(rec: Recording, path: Path) -> Path:
    """Write the time series to ``path``, one row per control step (columns: :func:`csv_header`).

    Deck pose in the body frame (FLU), ground truth first, then IHRCF and ATDA as reported by the env
    (zeros with ``valid = 0`` when invalid), the ranges and the velocity command.
    """
    blocks: list[NDArray[np.float64]] = [rec.time[:, None]]
    for src in rec.sources:
        blocks += [rec.position[src], rec.euler[src]]
        if src != "gt":
            blocks.append(rec.valid[src][:, None].astype(float))
    blocks += [rec.ranges, rec.ranges_valid.astype(float), rec.command]
    data = np.hstack(blocks)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(
        path, data, delimiter=",", header=",".join(csv_header(rec.estimators)), comments="", fmt="%.6g"
    )
    return path


__all__ = [
    "CONTROL_HZ",
    "csv_header",
    "run",
    "save_csv",
    "tracking_summary",
]
