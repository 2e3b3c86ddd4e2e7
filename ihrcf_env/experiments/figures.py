"""Figures of a hover-and-track run: PNG lookalikes of the paper's Figs. 14-20.

matplotlib is an optional dependency (the ``[plots]`` and ``[test]`` extras): it is imported inside
:func:`save_figures`, which raises ImportError without it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.metrics import LABELS
from ihrcf_env.experiments.rollout import Recording

#: Paper-like colours: IHRCF blue, ground truth green, ATDA red (Figs. 14-16).
COLORS = {"ihrcf": "tab:blue", "gt": "tab:green", "atda": "tab:red"}
#: Drawing order and line styles: ground truth wide underneath, ATDA, then IHRCF on top (it sits on GT).
STYLE: dict[str, dict[str, Any]] = {
    "gt": {"lw": 2.4, "alpha": 0.6, "zorder": 1},
    "atda": {"lw": 0.9, "alpha": 0.9, "zorder": 2},
    "ihrcf": {"lw": 1.0, "alpha": 1.0, "zorder": 3},
}
#: Error plots (Figs. 17-20): X blue, Y red, Z yellow (MATLAB's default colour order, as in the paper).
AXIS_COLORS = ("#0072BD", "#D95319", "#EDB120")


def _legend(ax: Any) -> None:
    """Legend in the order IHRCF, GT, ATDA (the paper's)."""
    handles, labels = ax.get_legend_handles_labels()
    by_label = dict(zip(labels, handles, strict=True))
    order = [LABELS[k] for k in ("ihrcf", "gt", "atda")]
    ax.legend([by_label[k] for k in order], order, loc="upper right", ncol=3, fontsize="small")


def save_figures(rec: Recording, out: Path) -> list[Path]:
    """Save PNG lookalikes of the paper's Figs. 14-20 into ``out``; returns the paths.

    Draws on :class:`matplotlib.figure.Figure` objects directly (no pyplot, so the caller's backend
    is left alone). Raises ImportError without matplotlib.
    """
    from matplotlib.figure import Figure

    out.mkdir(parents=True, exist_ok=True)
    t = rec.time
    paths: list[Path] = []

    def series(src: str, what: str) -> NDArray[np.float64]:
        a = rec.position[src].copy() if what == "position" else np.degrees(rec.euler[src])
        if src != "gt":
            a[~rec.valid[src]] = np.nan  # gaps where the estimate is invalid
        return a

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=120)
        paths.append(path)

    # Figs. 14 and 15: Euler angles and translations vs time
    for what, names, unit, fname, title in (
        ("euler", ("Roll", "Pitch", "Yaw"), "deg", "fig14_euler_angles.png", "Euler angles of the deck"),
        ("position", ("X", "Y", "Z"), "m", "fig15_translations.png", "Translations of the deck"),
    ):
        fig = Figure(figsize=(9, 8))
        axes = fig.subplots(3, 1, sharex=True)
        for i, ax in enumerate(axes):
            for src in ("gt", "atda", "ihrcf"):
                ax.plot(t, series(src, what)[:, i], color=COLORS[src], label=LABELS[src], **STYLE[src])
            ax.set_ylabel(f"{names[i]} ({unit})")
            ax.grid(alpha=0.3)
        _legend(axes[0])
        axes[0].set_title(f"{title} in the drone body frame: IHRCF, GT and ATDA")
        axes[-1].set_xlabel("time (s)")
        save(fig, fname)

    # Fig. 16: trajectories, X-Z, Y-Z, X-Y and 3-D
    fig = Figure(figsize=(11, 9))
    views = ((0, 2, "X-Z view"), (1, 2, "Y-Z view"), (0, 1, "X-Y view"))
    for j, (a, b, title) in enumerate(views):
        ax = fig.add_subplot(2, 2, j + 1)
        for src in ("gt", "atda", "ihrcf"):
            p = series(src, "position")
            ax.plot(p[:, a], p[:, b], color=COLORS[src], label=LABELS[src], **STYLE[src])
        ax.set_xlabel(f"{'XYZ'[a]} (m)")
        ax.set_ylabel(f"{'XYZ'[b]} (m)")
        ax.set_title(f"({'abc'[j]}) {title}")
        ax.grid(alpha=0.3)
    ax3 = fig.add_subplot(2, 2, 4, projection="3d")
    for src in ("gt", "atda", "ihrcf"):
        p = series(src, "position")
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], color=COLORS[src], label=LABELS[src], **STYLE[src])
    ax3.set_xlabel("X (m)")
    ax3.set_ylabel("Y (m)")
    ax3.set_zlabel("Z (m)")
    ax3.set_title("(d) 3-D trajectory")
    ax3.zaxis.labelpad = 12
    _legend(ax3)
    save(fig, "fig16_trajectories.png")

    # Figs. 17-20: errors of each estimator
    for num, key in ((17, "ihrcf"), (19, "atda")):
        e = rec.pose_errors(key)
        for k, (sl, unit, kind, names) in enumerate(
            (
                (slice(0, 3), "m", "translation", ("X", "Y", "Z")),
                (slice(3, 6), "deg", "angle", ("roll", "pitch", "yaw")),
            )
        ):
            fig = Figure(figsize=(9, 4))
            ax = fig.subplots()
            for i, color in enumerate(AXIS_COLORS):
                ax.plot(t, e[:, sl][:, i], color=color, lw=1.0, label=names[i])
            ax.axhline(0.0, color="k", lw=0.5)
            ax.set_xlabel("time (s)")
            ax.set_ylabel(f"error ({unit})")
            ax.set_title(f"{LABELS[key]} {kind} estimation error (estimate minus ground truth)")
            ax.legend(loc="upper right", ncol=3)
            ax.grid(alpha=0.3)
            save(fig, f"fig{num + k}_{key}_{kind}_error.png")
    return paths


__all__ = [
    "AXIS_COLORS",
    "COLORS",
    "STYLE",
    "save_figures",
]
