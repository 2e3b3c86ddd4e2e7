"""How well the deck-motion forecaster forecasts: ``python -m ihrcf_env.experiments.forecast_quality``.

For each level (its sea state and Froude scale) and seed, a ship deck record
(:func:`ihrcf_env.core.ship.ship_profile`) is sampled like a camera: ``camera_hz`` frames with a
timing jitter, frames lost in bursts at the level's camera loss rate, and white Gaussian noise on
each channel like the fused estimate's error through a descent (heave ``noise_heave`` m, roll and
pitch ``noise_angle`` rad each). The frames feed :class:`~ihrcf_env.core.forecast.DeckForecaster`;
after ``warmup`` s, every ``every`` s, its forecast at each horizon is compared with the true deck
motion at that time, as is **persistence** (the latest valid frame, held). Reported per level and
horizon: the RMS error of the forecast and of persistence against the truth and their ratio
(heave, roll, pitch), the RMS error of the heave rate against the truth's standard deviation, and
the calibration (fraction of the truth inside the forecast's +-1 std; 0.68 for a calibrated
Gaussian forecast). The quiescence indicator (probability >= 0.5) is scored against the true
record's quiescent runs (:func:`~ihrcf_env.core.quiescence.quiescent_mask`, thresholds at the
level's scale): a window ``[t + lead, t + lead + min_duration]`` is truly quiet when all of it is
inside a run; precision and recall over the evaluation times, calling a window quiet at each
probability level of :data:`QUIET_LEVELS`. The update and forecast costs (microseconds, the
refits included) depend on the machine.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.levels import LEVELS
from ihrcf_env.core.forecast import DeckForecaster, ForecastOptions
from ihrcf_env.core.quiescence import QuiescenceThresholds, quiescent_mask
from ihrcf_env.core.ship import ship_profile

__all__ = [
    "LEVEL_NAMES",
    "QUIET_LEVELS",
    "LevelQuality",
    "Sampling",
    "evaluate",
    "level_sea",
    "main",
    "markdown",
]

LEVEL_NAMES = ("calm", "moderate", "rough")
#: Probabilities at or above which the quiescence indicator calls a window quiet, as scored.
QUIET_LEVELS = (0.5, 0.25, 0.1)


def level_sea(name: str) -> tuple[int, float, float]:
    """(sea state, length scale, camera frame loss rate) of the level ``name``."""
    levels = LEVELS
    if name not in levels:
        raise ValueError(f"level must be one of {tuple(levels)}, got {name!r}")
    lv = levels[name]
    loss = float(lv.faults.get("camera_dropout", {}).get("loss_rate", 0.0))
    return int(lv.sea_state), float(lv.length_scale), loss


@dataclass(frozen=True)
class Sampling:
    """How the record is observed: ``camera_hz`` (Hz) frames with a uniform timing jitter of
    +-``jitter`` s, lost in bursts of mean ``mean_burst`` frames, white noise ``noise_heave`` (m)
    and ``noise_angle`` (rad, roll and pitch each); records of ``duration`` s scored after
    ``warmup`` s every ``every`` s."""

    camera_hz: float = 30.0
    jitter: float = 0.004
    mean_burst: float = 3.0
    noise_heave: float = 0.015
    noise_angle: float = math.radians(0.9)
    duration: float = 90.0
    warmup: float = 25.0
    every: float = 0.2


@dataclass
class LevelQuality:
    """Scores of one level over its seeds: per horizon (rows) ``rms`` and ``persist`` (H, 4: heave m,
    heave rate m/s, roll rad, pitch rad; persistence's heave rate column is the truth's std),
    ``inside`` (H, 4) the calibration; the quiescence indicator's ``precision`` and ``recall`` per
    probability level of :data:`QUIET_LEVELS` (NaN when undefined), ``quiet_fraction`` of truly
    quiet windows; ``us_per_sample`` the mean cost of an update (with the refits) and
    ``us_per_forecast``."""

    level: str
    horizons: NDArray[np.float64]
    rms: NDArray[np.float64]
    persist: NDArray[np.float64]
    inside: NDArray[np.float64]
    precision: tuple[float, ...]
    recall: tuple[float, ...]
    quiet_fraction: float
    us_per_sample: float
    us_per_forecast: float
    n_forecasts: int


def _losses(rng: np.random.Generator, n: int, rate: float, burst: float) -> NDArray[np.bool_]:
    """(n,) True where a frame is lost: a two-state chain with loss ``rate`` and mean burst ``burst``."""
    lost = np.zeros(n, dtype=bool)
    if rate <= 0.0:
        return lost
    p_exit = 1.0 / burst
    p_enter = rate * p_exit / (1.0 - rate)
    u = rng.uniform(size=n)
    state = False
    for k in range(n):
        state = (u[k] >= p_exit) if state else (u[k] < p_enter)
        lost[k] = state
    return lost


def _truth(profile: Any, t: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 4) true heave (m), heave rate (m/s, central difference), roll, pitch (rad) at ``t``."""
    eps = 1e-3
    off, rpy = profile.sample(t)
    up, _ = profile.sample(t + eps)
    dn, _ = profile.sample(t - eps)
    return np.column_stack([off[:, 2], (up[:, 2] - dn[:, 2]) / (2 * eps), rpy[:, 0], rpy[:, 1]])


def evaluate(
    level: str,
    seeds: Sequence[int],
    options: ForecastOptions | None = None,
    sampling: Sampling | None = None,
    thresholds: QuiescenceThresholds | None = None,
) -> LevelQuality:
    """Score the forecaster on the level's deck records for ``seeds`` (see the module docstring)."""
    opts = options if options is not None else ForecastOptions()
    smp = sampling if sampling is not None else Sampling()
    sea_state, scale, loss = level_sea(level)
    th = (thresholds if thresholds is not None else QuiescenceThresholds()).scaled(scale)
    hs = np.asarray(opts.horizons)
    err: list[NDArray[np.float64]] = []
    per: list[NDArray[np.float64]] = []
    ins: list[NDArray[np.bool_]] = []
    rate_std: list[float] = []
    pred_q: list[float] = []
    true_q: list[bool] = []
    t_update = t_forecast = 0.0
    n_update = n_forecast = 0
    sigma = np.array([smp.noise_heave, smp.noise_angle, smp.noise_angle])
    for seed in seeds:
        rng = np.random.default_rng([int(seed), 4040])
        profile = ship_profile(rng, {"sea_state": sea_state, "length_scale": scale})
        n = int(smp.duration * smp.camera_hz)
        t = np.arange(n) / smp.camera_hz + rng.uniform(-smp.jitter, smp.jitter, n)
        t = np.sort(t - t[0])
        truth = _truth(profile, t)
        y = truth[:, [0, 2, 3]] + rng.normal(0.0, sigma, (n, 3))
        valid = ~_losses(rng, n, loss, smp.mean_burst)
        grid = np.arange(0.0, smp.duration + hs.max() + th.min_duration + 5.0, 0.01)
        g_truth = _truth(profile, grid)
        off = np.zeros((grid.size, 3))
        off[:, 2] = g_truth[:, 0]
        rpy = np.column_stack([g_truth[:, 2], g_truth[:, 3], np.zeros(grid.size)])
        quiet = quiescent_mask(grid, off, rpy, th)
        rate_std.append(float(np.std(g_truth[:, 1])))
        fc = DeckForecaster(opts)
        last = np.full(3, np.nan)
        next_eval = smp.warmup
        for k in range(n):
            c0 = time.perf_counter()
            fc.update(float(t[k]), y[k], bool(valid[k]))
            t_update += time.perf_counter() - c0
            n_update += 1
            if valid[k]:
                last = y[k]
            if t[k] < next_eval or t[k] > smp.duration - hs.max() - th.min_duration - opts.quiet_lead - 1.0:
                continue
            next_eval += smp.every
            if not np.isfinite(last).all():
                continue
            c0 = time.perf_counter()
            f = fc.forecast()
            p_quiet = fc.quiet_probability(th)
            t_forecast += time.perf_counter() - c0
            n_forecast += 1
            tr = _truth(profile, t[k] + hs)
            err.append(f.mean - tr)
            per.append(np.column_stack([last[0] - tr[:, 0], np.zeros(hs.size), last[1:] - tr[:, 2:]]))
            ins.append(np.abs(f.mean - tr) <= f.std)
            a, b = np.searchsorted(grid, [t[k] + opts.quiet_lead, t[k] + opts.quiet_lead + th.min_duration])
            true_q.append(bool(quiet[a : b + 1].all()))
            pred_q.append(p_quiet)
    e, pe, i = np.array(err), np.array(per), np.array(ins)
    rms = np.sqrt(np.mean(e**2, axis=0))
    persist = np.sqrt(np.mean(pe**2, axis=0))
    persist[:, 1] = float(np.mean(rate_std))
    prob, tq = np.array(pred_q), np.array(true_q)
    precision, recall = [], []
    for level_p in QUIET_LEVELS:
        pq = prob >= level_p
        tp = float(np.sum(pq & tq))
        precision.append(tp / float(pq.sum()) if pq.any() else math.nan)
        recall.append(tp / float(tq.sum()) if tq.any() else math.nan)
    return LevelQuality(
        level,
        hs,
        rms,
        persist,
        i.mean(axis=0),
        tuple(precision),
        tuple(recall),
        float(tq.mean()),
        1e6 * t_update / max(n_update, 1),
        1e6 * t_forecast / max(n_forecast, 1),
        int(e.shape[0]),
    )


def _pct(v: float) -> str:
    return "-" if math.isnan(v) else f"{100 * v:.0f} %"


def markdown(results: Sequence[LevelQuality], seeds: Sequence[int], sampling: Sampling) -> list[str]:
    """The tables (Markdown lines) of the results."""
    deg = math.degrees
    out = [
        f"Seeds {list(seeds)}; camera {sampling.camera_hz:g} Hz, "
        f"noise heave {1e3 * sampling.noise_heave:g} mm, "
        f"roll/pitch {deg(sampling.noise_angle):g} deg; scored after {sampling.warmup:g} s every "
        f"{sampling.every:g} s. RMS error against the truth: forecast / persistence (ratio).",
        "",
        "| level | horizon (s) | heave (mm) | roll (deg) | pitch (deg) "
        "| heave rate (mm/s): RMS / truth std |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        for j, h in enumerate(r.horizons):
            f, p = r.rms[j], r.persist[j]
            cells = [
                f"{1e3 * f[0]:.1f} / {1e3 * p[0]:.1f} ({f[0] / p[0]:.2f})",
                f"{deg(f[2]):.2f} / {deg(p[2]):.2f} ({f[2] / p[2]:.2f})",
                f"{deg(f[3]):.2f} / {deg(p[3]):.2f} ({f[3] / p[3]:.2f})",
                f"{1e3 * f[1]:.0f} / {1e3 * p[1]:.0f}",
            ]
            out.append(f"| {r.level} | {h:g} | " + " | ".join(cells) + " |")
    out += [
        "",
        "Calibration: fraction of the truth inside the forecast's +-1 std (0.68 when calibrated).",
        "",
        "| level | horizon (s) | heave | heave rate | roll | pitch |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        for j, h in enumerate(r.horizons):
            out.append(f"| {r.level} | {h:g} | " + " | ".join(f"{v:.2f}" for v in r.inside[j]) + " |")
    out += [
        "",
        "Quiescence indicator against the true quiescent windows: precision / recall when a window "
        "is called quiet at a probability >= " + ", ".join(f"{v:g}" for v in QUIET_LEVELS) + ".",
        "",
        "| level | truly quiet windows | "
        + " | ".join(f"p >= {v:g}" for v in QUIET_LEVELS)
        + " | forecasts | update (us) | forecast + quiet (us) |",
        "|---|---|" + "---|" * len(QUIET_LEVELS) + "---|---|---|",
    ]
    for r in results:
        scores = " | ".join(f"{_pct(a)} / {_pct(b)}" for a, b in zip(r.precision, r.recall, strict=True))
        out.append(
            f"| {r.level} | {_pct(r.quiet_fraction)} | {scores} | "
            f"{r.n_forecasts} | {r.us_per_sample:.0f} | {r.us_per_forecast:.0f} |"
        )
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    ap = argparse.ArgumentParser(prog="python -m ihrcf_env.experiments.forecast_quality", description=__doc__)
    ap.add_argument("--levels", nargs="+", default=list(LEVEL_NAMES), choices=LEVEL_NAMES)
    ap.add_argument("--seeds", type=int, default=6, help="seeds 0..N-1 per level (1..100)")
    ap.add_argument("--duration", type=float, default=90.0, help="record length (s, 40..600)")
    ap.add_argument("--window", type=float, default=None, help="forecast window (s)")
    ap.add_argument("--order", type=int, default=None, help="autoregressive order")
    ap.add_argument("--markdown", default=None, help="also write the tables to this file")
    args = ap.parse_args(argv)
    if not 1 <= args.seeds <= 100:
        ap.error(f"argument --seeds: 1..100, got {args.seeds}")
    if not 40.0 <= args.duration <= 600.0:
        ap.error(f"argument --duration: 40..600, got {args.duration}")
    fields: dict[str, Any] = {}
    if args.window is not None:
        fields["window"] = args.window
    if args.order is not None:
        fields["order"] = args.order
    try:
        options = ForecastOptions(**fields)
    except (TypeError, ValueError) as exc:
        ap.error(str(exc))
    sampling = Sampling(duration=args.duration)
    seeds = list(range(args.seeds))
    results = []
    for name in args.levels:
        results.append(evaluate(name, seeds, options, sampling))
        print(f"{name}: {results[-1].n_forecasts} forecasts", flush=True)
    lines = markdown(results, seeds, sampling)
    print("\n".join(lines), flush=True)
    if args.markdown:
        with open(args.markdown, "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
