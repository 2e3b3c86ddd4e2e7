"""The hover-and-track example runs headless end to end: table, figures and CSV."""

from __future__ import annotations

import csv
from collections.abc import Iterator
from types import ModuleType

import numpy as np
import pytest
from example_loader import imported_example

from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix

FIGURES = (
    "fig14_euler_angles.png",
    "fig15_translations.png",
    "fig16_trajectories.png",
    "fig17_ihrcf_translation_error.png",
    "fig18_ihrcf_angle_error.png",
    "fig19_atda_translation_error.png",
    "fig20_atda_angle_error.png",
)


@pytest.fixture(scope="module")
def example() -> Iterator[ModuleType]:
    """The example script imported as a module."""
    with imported_example("hover_and_track.py", "hover_and_track") as module:
        yield module


def test_short_run_prints_the_table_and_saves_figures_and_csv(example, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    out = tmp_path / "hover"
    seconds, hz = 4.0, 20
    assert example.main(["--seconds", str(seconds), "--seed", "1", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    text = captured.out
    for needle in ("Translations (m)", "Angles (degree)", "ATDA", "IHRCF", "Paper Table 2", "Invalid frames"):
        assert needle in text, needle
    for row in ("X", "Y", "Z", "roll", "pitch", "yaw"):
        assert any(line.split()[-7:-6] == [row] for line in text.splitlines()), row
    assert "0.0697" in text and "1.3731" in text  # the paper's values for comparison
    assert "Wall time" in text
    assert "100%" in captured.err  # the progress bar went to stderr

    for name in (*FIGURES, "timeseries.csv", "table2.txt"):
        path = out / name
        assert path.is_file() and path.stat().st_size > 0, name

    with open(out / "timeseries.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert header == example.csv_header()
    assert len(body) == int(seconds * hz)
    data = np.array(body, dtype=float)
    assert np.all(np.isfinite(data))
    t = data[:, header.index("time_s")]
    assert np.allclose(np.diff(t), 1.0 / hz) and t[-1] == pytest.approx(seconds)
    # hovering ~1 m above the deck: ground-truth deck z in the body frame near -1 m
    assert np.all(np.abs(data[:, header.index("gt_z_m")] + 1.0) < 0.15)
    # IHRCF valid in most frames and close to ground truth when valid
    valid = data[:, header.index("ihrcf_valid")] == 1
    assert valid.mean() > 0.9
    err = data[valid, header.index("ihrcf_z_m")] - data[valid, header.index("gt_z_m")]
    assert np.abs(err).mean() < 0.01


def test_no_plots_writes_only_the_csv_and_table(example, tmp_path, capsys):
    out = tmp_path / "quick"
    assert example.main(["--seconds", "1", "--profile", "static", "--no-plots", "--out", str(out)]) == 0
    assert "Translations (m)" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["table2.txt", "timeseries.csv"]


def test_tracking_action_follows_the_estimate_and_holds_when_invalid(example):
    level = np.array([0.0, 0.0, 0.0, 1.0])
    mv = np.ones(4)
    est = {"position": np.array([0.1, -0.2, -1.1]), "euler": np.array([0.0, 0.0, 0.3]), "valid": 1}
    a = example.tracking_action(est, level, 1.0, mv)
    assert a[0] > 0 and a[1] < 0 and a[2] < 0 and a[3] > 0  # towards the deck, down to 1 m, turn with it
    assert np.all(np.abs(a) <= 1.0)
    assert np.all(example.tracking_action({**est, "valid": 0}, level, 1.0, mv) == 0.0)
    # a tilted drone straight over the deck, 1 m up: the tilt must not read as an offset
    R = matrix_from_euler(0.1, -0.15, 0.7)
    est_tilted = {"position": R.T @ np.array([0.0, 0.0, -1.0]), "euler": np.zeros(3), "valid": 1}
    a = example.tracking_action(est_tilted, quat_from_matrix(R), 1.0, mv)
    assert np.allclose(a, 0.0, atol=1e-9)


def test_mae_skips_invalid_frames_and_wraps_angles(example):
    n = 4
    gt_pos = np.tile([0.0, 0.0, -1.0], (n, 1))
    gt_eul = np.tile([0.0, 0.0, np.pi - 0.01], (n, 1))
    est_pos = gt_pos + np.array([0.01, 0.0, 0.0])
    est_eul = np.tile([0.0, 0.0, -np.pi + 0.01], (n, 1))  # 0.02 rad from gt across the wrap
    bad = gt_pos.copy()
    bad[0] = 9.0  # an invalid frame with a huge error must not count
    res = example.Results(
        time=np.arange(1, n + 1) / 20.0,
        position={"gt": gt_pos, "ihrcf": est_pos, "atda": bad},
        euler={"gt": gt_eul, "ihrcf": est_eul, "atda": gt_eul.copy()},
        valid={"ihrcf": np.ones(n, bool), "atda": np.array([False, True, True, True])},
        ranges=np.ones((n, 4)),
        ranges_valid=np.ones((n, 4), bool),
        command=np.zeros((n, 4)),
        drone_minus_deck=np.zeros((n, 3)),
        heading_error=np.zeros(n),
        wall_time=1.0,
    )
    stats = example.error_stats(res)
    mae_i, peak_i, inv_i = stats["ihrcf"]
    assert mae_i[0] == pytest.approx(0.01) and mae_i[5] == pytest.approx(np.degrees(0.02))
    assert inv_i == 0
    mae_a, _, inv_a = stats["atda"]
    assert np.allclose(mae_a, 0.0) and inv_a == 1
    table = example.mae_table(res)
    assert "ATDA 1/4" in table and "IHRCF 0/4" in table
