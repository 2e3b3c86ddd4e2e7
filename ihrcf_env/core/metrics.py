"""Metrics and their reports: deck-pose estimation errors (the paper's Table 2) and landing outcomes.

Pure numpy, so it scores recorded flights as well as simulated ones. Pose errors are estimate minus
ground truth of the deck pose in the drone body frame (FLU): X, Y, Z in metres, then roll, pitch,
yaw (Z-Y-X Euler angles) in degrees wrapped to (-180, 180].
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import wrap_angle

#: The two estimators of the paper's Table 2, in the table's column order.
ESTIMATORS: tuple[str, ...] = ("atda", "ihrcf")
#: Column order of estimators in the tables (others follow in the order given).
TABLE_ORDER: tuple[str, ...] = ("atda", "ihrcf", "fused")
#: Printed names of the estimators and of ground truth.
LABELS: dict[str, str] = {"gt": "GT", "ihrcf": "IHRCF", "atda": "ATDA", "fused": "fused"}
#: Columns of a pose-error row (m, m, m, deg, deg, deg).
POSE_AXES: tuple[str, ...] = ("X", "Y", "Z", "roll", "pitch", "yaw")

#: The paper's Table 2 (mean absolute errors): X, Y, Z in m, then roll, pitch, yaw in degrees.
PAPER_TABLE2: dict[str, NDArray[np.float64]] = {
    "atda": np.array([0.0162, 0.0134, 0.0697, 2.9843, 1.657, 1.7743]),
    "ihrcf": np.array([0.0035, 0.0039, 0.0041, 0.98, 1.3731, 1.180]),
}


# -- pose estimation errors ---------------------------------------------------------------------
def pose_errors(
    position: ArrayLike,
    euler: ArrayLike,
    gt_position: ArrayLike,
    gt_euler: ArrayLike,
    valid: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Estimate minus ground truth, one row per frame.

    Args:
        position, gt_position: (n, 3) deck positions (m), body frame.
        euler, gt_euler: (n, 3) deck roll, pitch, yaw (rad), body frame.
        valid: (n,) bool, frames where the estimate is valid (default all).

    Returns:
        (n, 6): X, Y, Z (m), roll, pitch, yaw (deg, wrapped to (-180, 180]); NaN rows where invalid.
    """
    d_pos = np.asarray(position, dtype=np.float64) - np.asarray(gt_position, dtype=np.float64)
    d_ang = wrap_angle(np.asarray(euler, dtype=np.float64) - np.asarray(gt_euler, dtype=np.float64))
    e = np.hstack([np.atleast_2d(d_pos), np.degrees(np.atleast_2d(d_ang))])
    if valid is not None:
        e[~np.asarray(valid, dtype=bool)] = np.nan
    return e


@dataclass(frozen=True)
class ErrorStats:
    """Statistics of one estimator's pose errors over a run (see :func:`error_stats`)."""

    mae: NDArray[np.float64]  # (6,) mean absolute error over valid frames: m, m, m, deg, deg, deg
    peak: NDArray[np.float64]  # (6,) largest absolute error over valid frames
    invalid: int  # frames without a valid estimate (excluded from mae and peak)
    frames: int  # all frames

    @property
    def valid(self) -> int:
        """Frames with a valid estimate."""
        return self.frames - self.invalid


def error_stats(errors: ArrayLike) -> ErrorStats:
    """MAE, peak absolute error and invalid-frame count of :func:`pose_errors` rows.

    Rows containing NaN are the invalid frames; with no valid frame, ``mae`` and ``peak`` are NaN.
    """
    e = np.atleast_2d(np.asarray(errors, dtype=np.float64))
    ok = np.all(np.isfinite(e), axis=1)
    a = np.abs(e[ok])
    if a.shape[0]:
        mae, peak = a.mean(axis=0), a.max(axis=0)
    else:
        mae = peak = np.full(e.shape[1], np.nan)
    return ErrorStats(mae=mae, peak=peak, invalid=int(e.shape[0] - ok.sum()), frames=int(e.shape[0]))


def table_columns(stats: Mapping[str, ErrorStats]) -> tuple[str, ...]:
    """Estimators of ``stats`` in table order (:data:`TABLE_ORDER` first, then the rest)."""
    known = [k for k in TABLE_ORDER if k in stats]
    return tuple(known + [k for k in stats if k not in known])


def _label(key: str) -> str:
    return LABELS.get(key, key)


def table2_text(stats: Mapping[str, ErrorStats]) -> str:
    """Table 2 as plain text in the paper's layout (a row per axis): MAE over valid frames, peaks,
    the paper's values (ATDA, IHRCF) and the invalid-frame counts, for every estimator in ``stats``."""
    cols = table_columns(stats)
    w = 9
    groups_cols = (cols, cols, ESTIMATORS)
    titles = ("Mean absolute error", "Peak absolute error", "Paper Table 2 (MAE)")
    head1 = f"{'':<22}" + "   ".join(f"{t:^{len(g) * w}}" for t, g in zip(titles, groups_cols, strict=True))
    head2 = f"{'':<22}" + "   ".join("".join(f"{_label(c):>{w}}" for c in g) for g in groups_cols)
    lines = [head1, head2, "-" * len(head2)]
    for i, name in enumerate(POSE_AXES):
        group = "Translations (m)" if i == 0 else ("Angles (degree)" if i == 3 else "")
        groups = (
            [stats[k].mae[i] for k in cols],
            [stats[k].peak[i] for k in cols],
            [PAPER_TABLE2[k][i] for k in ESTIMATORS],
        )
        cells = "   ".join("".join(f"{v:>{w}.4f}" for v in g) for g in groups)
        lines.append(f"{group:<16}{name:>6}{cells}")
    lines.append("-" * len(head2))
    inv = "   ".join(f"{_label(k)} {stats[k].invalid}/{stats[k].frames}" for k in cols)
    lines.append(f"Invalid frames (excluded from the statistics): {inv}")
    return "\n".join(lines)


def table2_markdown(stats: Mapping[str, ErrorStats], title: str) -> str:
    """Table 2 as a Markdown table in the paper's layout (a row per axis; MAE with the peak in
    brackets for every estimator in ``stats``, then the paper's ATDA and IHRCF MAE); ``title`` heads
    it in bold. Translations in m, angles in degrees."""
    cols = table_columns(stats)
    frames = max(s.frames for s in stats.values())
    head = [_label(c) for c in cols] + [f"paper {_label(c)}" for c in ESTIMATORS]
    lines = [
        f"**{title}** ({frames} frames, mean absolute error; peak in brackets)",
        "",
        "| | " + " | ".join(head) + " |",
        "|---|" + "---|" * len(head),
    ]
    for i, name in enumerate(POSE_AXES):
        unit, fmt = ("m", "{:.4f}") if i < 3 else ("deg", "{:.3f}")
        cells = [f"{fmt.format(stats[k].mae[i])} ({fmt.format(stats[k].peak[i])})" for k in cols]
        cells += [fmt.format(PAPER_TABLE2[k][i]) for k in ESTIMATORS]
        lines.append(f"| {name} ({unit}) | " + " | ".join(cells) + " |")
    lines.append("| invalid frames | " + " | ".join(str(stats[k].invalid) for k in cols) + " | | |")
    return "\n".join(lines)


# -- landing outcomes ---------------------------------------------------------------------------
#: How an episode can end.
OUTCOMES = ("success", "crash", "timeout")


@dataclass(frozen=True)
class EpisodeResult:
    """How one landing episode ended (read from the env's ``info`` after the fact).

    ``speed``, ``tilt`` and ``offset`` are None when the drone never touched down.
    """

    seed: int
    outcome: str  # "success", "crash" or "timeout" (one of OUTCOMES)
    reason: str = ""  # the crash reason ("" unless outcome == "crash")
    time: float = 0.0  # simulated s at the end
    steps: int = 0  # control steps flown
    ret: float = 0.0  # undiscounted return
    speed: float | None = None  # |relative vertical speed| at touchdown (m/s)
    tilt: float | None = None  # relative tilt at touchdown (rad)
    offset: float | None = None  # drone centre to tag centre, horizontal, at touchdown (m)
    commit_time: float | None = None  # simulated s when the policy committed to the drop, if it says
    profile: str = ""  # deck motion profile, when the caller names it

    @property
    def touched_down(self) -> bool:
        """Whether the episode has touchdown figures."""
        return self.speed is not None


@dataclass(frozen=True)
class LandingSummary:
    """Statistics of a set of landing episodes (see :func:`summarize_landings`); NaN where empty."""

    episodes: int
    successes: int
    success_rate: float  # in [0, 1]
    speed_mean: float  # touchdown |relative vertical speed| (m/s), over episodes that touched down
    speed_max: float
    tilt_mean_deg: float  # touchdown relative tilt (deg), over episodes that touched down
    tilt_max_deg: float
    time_mean: float  # simulated s to land, over successes
    time_max: float
    reasons: dict[str, int] = field(default_factory=dict)  # failure reason -> count


def _failure_key(r: EpisodeResult) -> str:
    """Failure reason with the numbers removed, so that alike failures group together."""
    key = r.reason or r.outcome
    if key.startswith("vertical speed"):
        return "vertical speed >= 0.5 m/s at touchdown"
    if key.startswith("tilt") and key.endswith("at touchdown"):
        return "tilt >= 10 deg at touchdown"
    return key


_NUMBER = re.compile(r"-?\d+(?:\.\d+)?")


def failure_groups(episodes: Sequence[EpisodeResult]) -> list[tuple[str, int]]:
    """The failures grouped by kind (crash reasons alike but for their numbers, or the outcome),
    most frequent first; each shown with its real figures: a number that differs between the
    episodes of a group reads ``lowest..highest``."""
    groups: dict[str, list[str]] = {}
    for e in episodes:
        if e.outcome == "success":
            continue
        text = e.reason if e.outcome == "crash" and e.reason else e.outcome
        groups.setdefault(_NUMBER.sub("\0", text), []).append(text)
    out = []
    for key, texts in groups.items():
        numbers = [_NUMBER.findall(t) for t in texts]
        parts = iter(key.split("\0"))
        shown = next(parts)
        for i, rest in enumerate(parts):
            column = [row[i] for row in numbers]
            lo, hi = min(column, key=float), max(column, key=float)
            shown += (lo if float(lo) == float(hi) else f"{lo}..{hi}") + rest
        out.append((shown, len(texts)))
    return sorted(out, key=lambda item: -item[1])


def _mean_max(values: Sequence[float]) -> tuple[float, float]:
    if not values:
        return float("nan"), float("nan")
    return float(np.mean(values)), float(np.max(values))


def summarize_landings(results: Sequence[EpisodeResult]) -> LandingSummary:
    """Success rate, touchdown speed/tilt statistics, time to land and failure reasons."""
    n = len(results)
    ok = [r for r in results if r.outcome == "success"]
    reasons: dict[str, int] = {}
    for r in results:
        if r.outcome != "success":
            key = _failure_key(r)
            reasons[key] = reasons.get(key, 0) + 1
    speed = _mean_max([r.speed for r in results if r.speed is not None])
    tilt = _mean_max([math.degrees(r.tilt) for r in results if r.speed is not None and r.tilt is not None])
    t_land = _mean_max([r.time for r in ok])
    return LandingSummary(
        episodes=n,
        successes=len(ok),
        success_rate=len(ok) / n if n else 0.0,
        speed_mean=speed[0],
        speed_max=speed[1],
        tilt_mean_deg=tilt[0],
        tilt_max_deg=tilt[1],
        time_mean=t_land[0],
        time_max=t_land[1],
        reasons=reasons,
    )


def format_episode(r: EpisodeResult) -> str:
    """One line per episode: outcome, end time, commit time, touchdown speed and tilt, reason."""
    spd = "-" if r.speed is None else f"{r.speed:.2f}"
    tilt = "-" if r.tilt is None else f"{math.degrees(r.tilt):.1f}"
    commit = "-" if r.commit_time is None else f"{r.commit_time:.1f}"
    return (
        f"  {r.profile:9s} seed {r.seed:3d}: {r.outcome:7s} t={r.time:5.1f} s "
        f"commit={commit:>5s} s speed={spd:>4s} m/s tilt={tilt:>4s} deg {r.reason}"
    )


def format_landing_summary(profile: str, s: LandingSummary) -> str:
    """The report block of one deck profile."""
    reasons = ", ".join(f"{k}: {v}" for k, v in sorted(s.reasons.items())) or "none"
    return (
        f"{profile}: success {s.successes}/{s.episodes} ({100 * s.success_rate:.0f} %)\n"
        f"  touchdown |relative vertical speed| mean {s.speed_mean:.3f} max {s.speed_max:.3f} m/s\n"
        f"  touchdown relative tilt mean {s.tilt_mean_deg:.2f} max {s.tilt_max_deg:.2f} deg\n"
        f"  time to land (successes) mean {s.time_mean:.1f} max {s.time_max:.1f} s\n"
        f"  failures: {reasons}"
    )


def wilson_interval(successes: int, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The Wilson score interval (low, high) of a success rate ``successes / n`` (default 95 %):
    well behaved at 0 and n successes, unlike the normal approximation."""
    if n <= 0 or not 0 <= successes <= n:
        raise ValueError(f"need 0 <= successes <= n and n > 0, got {successes}/{n}")
    p = successes / n
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z / (1 + z2 / n) * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


__all__ = [
    "ESTIMATORS",
    "LABELS",
    "OUTCOMES",
    "PAPER_TABLE2",
    "POSE_AXES",
    "TABLE_ORDER",
    "EpisodeResult",
    "ErrorStats",
    "LandingSummary",
    "error_stats",
    "failure_groups",
    "format_episode",
    "format_landing_summary",
    "pose_errors",
    "summarize_landings",
    "table2_markdown",
    "table2_text",
    "table_columns",
    "wilson_interval",
]
