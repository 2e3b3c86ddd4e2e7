"""A figure of the deck-motion forecast against the truth over one landing episode.

``python -m ihrcf_env.experiments.forecast_figure --level rough --seed 100001 --out FILE.png``
flies the forecast-gated scripted landing
(:class:`~ihrcf_env.control.forecast_landing.ForecastLanding`) on ``ihrcf_env/DeckLanding-v2``
with ``deck_forecast`` and the projected camera, and plots, per channel (heave, roll, pitch): the
true deck motion, the forecast made ``--horizon`` s earlier (plotted at the time it forecasts,
with its +-1 std band) and persistence (the true motion ``--horizon`` s earlier, held: what a
controller that knew the deck's motion now would assume). Frames as the forecast's
(``info["forecast"]``): roll and pitch of the deck normal about the drone's heading frame's x and
y; heave about the mean of the plotted span (the forecast's is about its window mean). It prints
the RMS error of both over the span where the forecast is valid, and the drone's and the deck's
tilt from the vertical over the episode (mean, 95th percentile). matplotlib is needed (the
``[plots]`` and ``[test]`` extras).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.forecast_landing import FORECAST_POLICY_OPTIONS, ForecastLanding
from ihrcf_env.core.frames import matrix_from_quat

__all__ = ["ForecastTrace", "fly", "main", "save_figure", "true_motion"]

ENV_ID = "ihrcf_env/DeckLanding-v2"
_CHANNELS = (
    ("heave", 0, "m", 1.0),
    ("roll", 2, "deg", 180.0 / math.pi),
    ("pitch", 3, "deg", 180.0 / math.pi),
)


@dataclass(frozen=True)
class ForecastTrace:
    """One episode's record: ``time`` (n,) s; ``truth`` (n, 4) heave m, heave rate m/s (0: not
        recorded), roll, pitch rad in the heading frame; ``mean``, ``std`` (n, 4) the forecast at
        ``horizon`` s made at each time (NaN where not valid); ``outcome`` of the episode; the true
    tilts of the drone and the deck from the vertical (rad) at each time."""

    time: NDArray[np.float64]
    truth: NDArray[np.float64]
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    horizon: float
    outcome: str
    drone_tilt: NDArray[np.float64]  # (n,) rad, the drone's up axis from the vertical
    deck_tilt: NDArray[np.float64]  # (n,) rad, the deck normal from the vertical


def true_motion(info: dict[str, Any]) -> NDArray[np.float64]:
    """(4,) the true deck heave (m, world z of the deck origin), 0, roll and pitch (rad) of the deck
    normal about the drone's heading frame's x and y, from a step's ``info``."""
    R_wd = matrix_from_quat(np.asarray(info["deck_quaternion_world"], dtype=np.float64))
    R_wb = matrix_from_quat(np.asarray(info["drone_quaternion_world"], dtype=np.float64))
    yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
    c, s = math.cos(yaw), math.sin(yaw)
    n = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ R_wd[:, 2]
    z = float(np.asarray(info["deck_position_world"])[2])
    return np.array([z, 0.0, math.atan2(-n[1], n[2]), math.atan2(n[0], n[2])])


def _tilt(quaternion: Any) -> float:
    """Angle (rad) of a body's z axis from the world's vertical."""
    R = matrix_from_quat(np.asarray(quaternion, dtype=np.float64))
    return math.acos(max(-1.0, min(1.0, float(R[2, 2]))))


def fly(level: str, seed: int, horizon: float = 1.0) -> ForecastTrace:
    """One episode of the forecast-gated landing from ``reset(seed=seed)``; ``horizon`` (s) must be
    one of the policy's forecast horizons."""
    env = gym.make(
        ENV_ID,
        level=level,
        camera_model="projected",
        camera_output="corners",
        deck_forecast=FORECAST_POLICY_OPTIONS,
    )
    try:
        policy = ForecastLanding.from_env(env)
        obs, info = env.reset(seed=seed)
        policy.reset()
        times, truth, mean, std, tilts = [], [], [], [], []
        outcome = "timeout"
        while True:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            fc = info["forecast"]
            k = int(np.argmin(np.abs(np.asarray(fc["horizons"]) - horizon)))
            if abs(float(fc["horizons"][k]) - horizon) > 1e-9:
                raise ValueError(f"horizon must be one of {list(fc['horizons'])}, got {horizon}")
            times.append(float(info["time"]))
            truth.append(true_motion(info))
            tilts.append([_tilt(info["drone_quaternion_world"]), _tilt(info["deck_quaternion_world"])])
            ok = bool(fc["valid"])
            mean.append(np.asarray(fc["mean"][k]) if ok else np.full(4, np.nan))
            std.append(np.asarray(fc["std"][k]) if ok else np.full(4, np.nan))
            if terminated or truncated:
                outcome = str(info.get("outcome", "flying")) if terminated else "timeout"
                break
        tilt = np.asarray(tilts)
        return ForecastTrace(
            np.asarray(times),
            np.asarray(truth),
            np.asarray(mean),
            np.asarray(std),
            horizon,
            outcome,
            tilt[:, 0],
            tilt[:, 1],
        )
    finally:
        env.close()


def errors(trace: ForecastTrace) -> dict[str, tuple[float, float, int]]:
    """Per channel: (RMS error of the forecast, RMS error of persistence (the truth ``horizon`` s
    earlier), samples) over the times where a forecast made ``horizon`` s earlier is valid; heave
    about each series' mean over those times."""
    t = trace.time
    target = t + trace.horizon
    keep = np.isfinite(trace.mean[:, 0]) & (target <= t[-1])
    idx = np.searchsorted(t, target[keep])
    idx = np.clip(idx, 0, t.size - 1)
    out: dict[str, tuple[float, float, int]] = {}
    for name, col, _, _ in _CHANNELS:
        f = trace.mean[keep, col]
        truth_later = trace.truth[idx, col]
        persist = trace.truth[keep, col]
        if name == "heave":
            f, truth_later, persist = f - f.mean(), truth_later - truth_later.mean(), persist - persist.mean()
        rms_f = float(np.sqrt(np.mean((f - truth_later) ** 2))) if f.size else math.nan
        rms_p = float(np.sqrt(np.mean((persist - truth_later) ** 2))) if f.size else math.nan
        out[name] = (rms_f, rms_p, int(f.size))
    return out


def save_figure(trace: ForecastTrace, path: str | Path, title: str = "") -> Path:
    """Plot :class:`ForecastTrace` into a PNG at ``path``; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, h = trace.time, trace.horizon
    valid = np.isfinite(trace.mean[:, 0])
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for ax, (name, col, unit, k) in zip(axes, _CHANNELS, strict=True):
        truth = trace.truth[:, col].copy()
        fmean = trace.mean[:, col].copy()
        if name == "heave":
            ref = truth[valid].mean() if valid.any() else truth.mean()
            truth -= ref
            fmean -= np.nanmean(fmean) if valid.any() else 0.0
        ax.plot(t, k * truth, color="tab:green", lw=2.0, alpha=0.7, label="truth")
        ax.plot(
            t[valid] + h,
            k * truth[valid],
            color="tab:gray",
            lw=0.9,
            ls="--",
            label=f"truth {h:g} s earlier (persistence)",
        )
        ax.plot(t[valid] + h, k * fmean[valid], color="tab:blue", lw=1.1, label=f"forecast {h:g} s ahead")
        sd = k * trace.std[valid, col]
        ax.fill_between(
            t[valid] + h, k * fmean[valid] - sd, k * fmean[valid] + sd, color="tab:blue", alpha=0.2
        )
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", ncol=3, fontsize="small")
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    ap = argparse.ArgumentParser(prog="python -m ihrcf_env.experiments.forecast_figure", description=__doc__)
    ap.add_argument("--level", default="rough", choices=["calm", "moderate", "rough"])
    ap.add_argument("--seed", type=int, default=100000)
    ap.add_argument("--horizon", type=float, default=1.0, help="forecast horizon (s), one of the policy's")
    ap.add_argument("--out", required=True, help="PNG file")
    args = ap.parse_args(argv)
    import ihrcf_env  # noqa: F401  (registers the ids)

    trace = fly(args.level, args.seed, args.horizon)
    save_figure(
        trace,
        args.out,
        f"{args.level}, seed {args.seed}: forecast {args.horizon:g} s ahead ({trace.outcome})",
    )
    for name, (f, p, n) in errors(trace).items():
        k = 1.0 if name == "heave" else 180.0 / math.pi
        unit = "m" if name == "heave" else "deg"
        print(
            f"{name}: forecast RMS {k * f:.3g} {unit}, truth held {args.horizon:g} s "
            f"{k * p:.3g} {unit} ({n} steps)"
        )
    for what, tilt in (("drone", trace.drone_tilt), ("deck", trace.deck_tilt)):
        d = np.degrees(tilt)
        print(
            f"{what} tilt from the vertical: mean {d.mean():.1f} deg, "
            f"95th percentile {np.percentile(d, 95):.1f} deg"
        )
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
