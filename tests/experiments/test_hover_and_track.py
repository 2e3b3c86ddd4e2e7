"""The hover-and-track run end to end (headless): recording, Table 2, CSV and figures."""

from __future__ import annotations

import contextlib
import csv
import io
from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.core.metrics import table2_text
from ihrcf_env.experiments.hover_and_track import csv_header, run, save_csv, tracking_summary
from ihrcf_env.experiments.rollout import Recording

FIGURES = (
    "fig14_euler_angles.png",
    "fig15_translations.png",
    "fig16_trajectories.png",
    "fig17_ihrcf_translation_error.png",
    "fig18_ihrcf_angle_error.png",
    "fig19_atda_translation_error.png",
    "fig20_atda_angle_error.png",
)
SECONDS, HZ = 4.0, 20


@pytest.fixture(scope="module")
def short_run() -> tuple[Recording, str]:
    """A 4 s run over the paper deck (seed 1) and what it wrote to stderr."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        rec = run(SECONDS, seed=1)
    return rec, err.getvalue()


def test_short_run_records_every_step_and_tracks(short_run: tuple[Recording, str]) -> None:
    rec, err = short_run
    # stderr is not a terminal here: plain progress lines (no bar redrawn with carriage returns)
    assert "\r" not in err and err.splitlines()[-1].startswith(f"rollout: {int(SECONDS * HZ)}/"), err
    assert rec.n == int(SECONDS * HZ) and rec.ended_early == ""
    assert rec.settings["control_hz"] == HZ and rec.settings["seed"] == 1
    stats = rec.error_stats()
    table = table2_text(stats)
    assert f"ATDA {stats['atda'].invalid}/{rec.n}" in table
    assert "Tracking with IHRCF" in tracking_summary(rec)


def test_csv_and_figures(short_run: tuple[Recording, str], tmp_path: Path) -> None:
    rec, _ = short_run
    path = save_csv(rec, tmp_path / "sub" / "timeseries.csv")
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert header == csv_header(rec.estimators)
    assert header[:8] == [
        "time_s",
        "gt_x_m",
        "gt_y_m",
        "gt_z_m",
        "gt_roll_rad",
        "gt_pitch_rad",
        "gt_yaw_rad",
        "ihrcf_x_m",
    ]
    assert len(body) == int(SECONDS * HZ)
    data = np.array(body, dtype=float)
    assert np.all(np.isfinite(data))
    t = data[:, header.index("time_s")]
    assert np.allclose(np.diff(t), 1.0 / HZ) and t[-1] == pytest.approx(SECONDS)
    # hovering ~1 m above the deck: ground-truth deck z in the body frame near -1 m
    assert np.all(np.abs(data[:, header.index("gt_z_m")] + 1.0) < 0.15)
    # IHRCF valid in most frames and close to ground truth when valid
    valid = data[:, header.index("ihrcf_valid")] == 1
    assert valid.mean() > 0.9
    err = data[valid, header.index("ihrcf_z_m")] - data[valid, header.index("gt_z_m")]
    assert np.abs(err).mean() < 0.01

    from ihrcf_env.experiments.figures import save_figures

    paths = save_figures(rec, tmp_path / "figs")
    assert [p.name for p in paths] == list(FIGURES)
    for p in paths:
        assert p.is_file() and p.stat().st_size > 0, p.name
