"""Learning curves as CSV files (append-only, resumable) and their plot.

Two files per run: ``train.csv`` has one row per finished training episode (``timesteps`` = the
learner's environment steps when it ended, ``return``, ``length`` in steps, ``is_success`` 0/1);
``eval.csv`` one row per periodic evaluation on held-out seeds (``timesteps``, ``wall_s`` since the
run started, ``mean_return``, ``std_return``, ``success_rate`` in [0, 1], ``mean_length``).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

TRAIN_FIELDS = ("timesteps", "return", "length", "is_success")
EVAL_FIELDS = ("timesteps", "wall_s", "mean_return", "std_return", "success_rate", "mean_length")


class CsvLog:
    """An append-only CSV file with a fixed header, flushed on every row.

    ``keep_until`` (environment steps) resumes a run from a checkpoint: an existing file is kept but
    its rows with ``timesteps`` beyond the checkpoint (logged after it by the interrupted run) are
    dropped. With ``keep_until=None`` an existing file is overwritten."""

    def __init__(self, path: str | os.PathLike[str], fields: Sequence[str], keep_until: int | None = None):
        if "timesteps" not in fields:
            raise ValueError(f"fields must contain 'timesteps', got {list(fields)!r}")
        if keep_until is not None and (isinstance(keep_until, bool) or not isinstance(keep_until, int)):
            raise TypeError(f"keep_until must be an int or None, got {type(keep_until).__name__}")
        self.path = Path(path)
        self.fields = tuple(fields)
        kept: list[dict[str, str]] = []
        if keep_until is not None and self.path.exists():
            kept = [r for r in read_csv(self.path) if int(float(r["timesteps"])) <= keep_until]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=self.fields)
            writer.writeheader()
            writer.writerows({k: r.get(k, "") for k in self.fields} for r in kept)

    def write(self, row: Mapping[str, float | int | str]) -> None:
        """Append one row; ``row`` must have exactly the header's fields."""
        if set(row) != set(self.fields):
            raise ValueError(f"row keys {sorted(row)} differ from the fields {sorted(self.fields)}")
        with self.path.open("a", newline="") as f:
            csv.DictWriter(f, fieldnames=self.fields).writerow(dict(row))


def read_csv(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The rows of a CSV file with a header, as strings."""
    with Path(path).open(newline="") as f:
        return list(csv.DictReader(f))


def rolling_mean(values: Sequence[float], window: int) -> np.ndarray:
    """Mean of the last ``window`` values at each index (fewer at the start)."""
    if window < 1:
        raise ValueError(f"window must be >= 1, got {window!r}")
    x = np.asarray(values, dtype=float)
    c = np.concatenate([[0.0], np.cumsum(x)])
    idx = np.arange(1, len(x) + 1)
    lo = np.maximum(idx - window, 0)
    return (c[idx] - c[lo]) / (idx - lo)


def plot_curves(
    train_csv: str | os.PathLike[str] | None,
    eval_csv: str | os.PathLike[str] | None,
    png: str | os.PathLike[str],
    window: int = 50,
    title: str = "",
) -> Path:
    """Plot episode return (top) and success rate (bottom) against environment steps.

    Training episodes are drawn as a rolling mean over ``window`` episodes, evaluations on held-out
    seeds as markers. Either CSV may be missing or empty. Needs matplotlib; returns the PNG path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    train = read_csv(train_csv) if train_csv is not None and Path(train_csv).exists() else []
    evals = read_csv(eval_csv) if eval_csv is not None and Path(eval_csv).exists() else []
    fig, (ax_r, ax_s) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    if train:
        t = np.array([float(r["timesteps"]) for r in train])
        ax_r.plot(t, rolling_mean([float(r["return"]) for r in train], window), lw=1.2, label="training")
        succ = rolling_mean([float(r["is_success"]) for r in train], window)
        ax_s.plot(t, 100 * succ, lw=1.2, label=f"training (last {window} episodes)")
    if evals:
        t = np.array([float(r["timesteps"]) for r in evals])
        mean = np.array([float(r["mean_return"]) for r in evals])
        std = np.array([float(r["std_return"]) for r in evals])
        ax_r.errorbar(t, mean, yerr=std, fmt="o-", ms=4, capsize=2, label="evaluation (held-out seeds)")
        ax_s.plot(t, [100 * float(r["success_rate"]) for r in evals], "o-", ms=4, label="evaluation")
    ax_r.set_ylabel("episode return")
    ax_s.set_ylabel("success rate (%)")
    ax_s.set_xlabel("environment steps")
    ax_s.set_ylim(-2, 102)
    for ax in (ax_r, ax_s):
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
    if title:
        ax_r.set_title(title)
    fig.tight_layout()
    out = Path(png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def summary(eval_csv: str | os.PathLike[str]) -> dict[str, float]:
    """Last and best evaluation of a run (``nan`` when the file has no rows)."""
    rows = read_csv(eval_csv) if Path(eval_csv).exists() else []
    if not rows:
        return {"last_success_rate": math.nan, "best_success_rate": math.nan, "timesteps": math.nan}
    return {
        "last_success_rate": float(rows[-1]["success_rate"]),
        "best_success_rate": max(float(r["success_rate"]) for r in rows),
        "timesteps": float(rows[-1]["timesteps"]),
    }


__all__ = [
    "EVAL_FIELDS",
    "TRAIN_FIELDS",
    "CsvLog",
    "plot_curves",
    "read_csv",
    "rolling_mean",
    "summary",
]
