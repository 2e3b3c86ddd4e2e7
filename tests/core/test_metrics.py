"""Pose-error statistics, the Table 2 formatters and the landing summaries (pure, no simulator)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.metrics import (
    PAPER_TABLE2,
    EpisodeResult,
    error_stats,
    failure_groups,
    format_episode,
    format_landing_summary,
    pose_errors,
    summarize_landings,
    table2_markdown,
    table2_text,
)


def _case() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = 4
    gt_pos = np.tile([0.0, 0.0, -1.0], (n, 1))
    gt_eul = np.tile([0.0, 0.0, np.pi - 0.01], (n, 1))
    est_pos = gt_pos + np.array([0.01, 0.0, 0.0])
    est_eul = np.tile([0.0, 0.0, -np.pi + 0.01], (n, 1))  # 0.02 rad from gt across the wrap
    bad = gt_pos.copy()
    bad[0] = 9.0  # an invalid frame with a huge error must not count
    return gt_pos, gt_eul, est_pos, est_eul, bad


def test_mae_skips_invalid_frames_and_wraps_angles() -> None:
    gt_pos, gt_eul, est_pos, est_eul, bad = _case()
    e_i = pose_errors(est_pos, est_eul, gt_pos, gt_eul)
    assert e_i[:, 5] == pytest.approx(np.degrees(0.02))  # estimate minus ground truth, wrapped
    stats_i = error_stats(e_i)
    assert stats_i.mae[0] == pytest.approx(0.01) and stats_i.mae[5] == pytest.approx(np.degrees(0.02))
    assert stats_i.invalid == 0 and stats_i.frames == 4
    e_a = pose_errors(bad, gt_eul, gt_pos, gt_eul, valid=[False, True, True, True])
    assert np.all(np.isnan(e_a[0])) and np.all(np.isfinite(e_a[1:]))
    stats_a = error_stats(e_a)
    assert np.allclose(stats_a.mae, 0.0) and stats_a.invalid == 1 and stats_a.valid == 3
    table = table2_text({"ihrcf": stats_i, "atda": stats_a})
    assert "ATDA 1/4" in table and "IHRCF 0/4" in table


def test_peak_and_no_valid_frame() -> None:
    e = np.array([[0.1, -0.3, 0, 0, 0, 1.0], [-0.2, 0.1, 0, 0, 0, -2.0]])
    s = error_stats(e)
    assert np.allclose(s.mae, [0.15, 0.2, 0, 0, 0, 1.5]) and np.allclose(s.peak, [0.2, 0.3, 0, 0, 0, 2.0])
    none = error_stats(np.full((3, 6), np.nan))
    assert none.invalid == 3 and np.all(np.isnan(none.mae)) and np.all(np.isnan(none.peak))


def test_table2_layouts_carry_the_papers_values() -> None:
    e = np.zeros((5, 6))
    e[:, 2] = 0.002
    stats = {"atda": error_stats(e), "ihrcf": error_stats(e)}
    text = table2_text(stats)
    for needle in ("Translations (m)", "Angles (degree)", "ATDA", "IHRCF", "Paper Table 2", "Invalid frames"):
        assert needle in text, needle
    for row in ("X", "Y", "Z", "roll", "pitch", "yaw"):
        assert any(line.split()[-7:-6] == [row] for line in text.splitlines()), row
    assert "0.0697" in text and "1.3731" in text
    md = table2_markdown(stats, "ToF ideal, no distortion")
    lines = md.splitlines()
    assert lines[0] == "**ToF ideal, no distortion** (5 frames, mean absolute error; peak in brackets)"
    assert lines[2] == "| | ATDA | IHRCF | paper ATDA | paper IHRCF |"
    assert lines[6] == "| Z (m) | 0.0020 (0.0020) | 0.0020 (0.0020) | 0.0697 | 0.0041 |"
    assert lines[8] == "| pitch (deg) | 0.000 (0.000) | 0.000 (0.000) | 1.657 | 1.373 |"
    assert lines[10] == "| invalid frames | 0 | 0 | | |"
    assert all(line.count("|") == 6 for line in lines[2:])
    # more estimators: each gets a column, in table order, in both layouts
    three = {"fused": error_stats(e), **stats}
    md3 = table2_markdown(three, "t").splitlines()
    assert md3[2] == "| | ATDA | IHRCF | fused | paper ATDA | paper IHRCF |"
    assert all(line.count("|") == 7 for line in md3[2:])
    assert "fused" in table2_text(three).splitlines()[1]
    assert PAPER_TABLE2["ihrcf"][2] == 0.0041


def test_landing_summary_groups_failures_and_formats() -> None:
    results = [
        EpisodeResult(
            0, "success", time=5.0, speed=0.25, tilt=math.radians(4.0), commit_time=2.0, profile="paper"
        ),
        EpisodeResult(1, "success", time=7.0, speed=0.29, tilt=math.radians(6.0), profile="paper"),
        EpisodeResult(
            2, "crash", "vertical speed 0.63 m/s at touchdown", 3.0, speed=0.63, tilt=0.0, profile="paper"
        ),
        EpisodeResult(
            3, "crash", "tilt 11.2 deg at touchdown", 4.0, speed=0.3, tilt=math.radians(11.2), profile="paper"
        ),
        EpisodeResult(4, "timeout", time=30.0, profile="paper"),
    ]
    s = summarize_landings(results)
    assert (s.episodes, s.successes, s.success_rate) == (5, 2, 0.4)
    assert s.speed_max == pytest.approx(0.63) and s.speed_mean == pytest.approx(
        np.mean([0.25, 0.29, 0.63, 0.3])
    )
    assert s.tilt_max_deg == pytest.approx(11.2)
    assert (s.time_mean, s.time_max) == (6.0, 7.0)
    assert s.reasons == {
        "vertical speed >= 0.5 m/s at touchdown": 1,
        "tilt >= 10 deg at touchdown": 1,
        "timeout": 1,
    }
    block = format_landing_summary("paper", s)
    assert block.startswith("paper: success 2/5 (40 %)\n")
    assert "touchdown |relative vertical speed| mean" in block and "failures: tilt >= 10 deg" in block
    line = format_episode(results[0])
    assert line == "  paper     seed   0: success t=  5.0 s commit=  2.0 s speed=0.25 m/s tilt= 4.0 deg "
    assert "commit=    - s speed=   - m/s tilt=   - deg" in format_episode(results[4])
    empty = summarize_landings([])
    assert empty.episodes == 0 and empty.success_rate == 0.0 and math.isnan(empty.speed_mean)


def test_failure_groups_keep_the_figures() -> None:
    """Alike crash reasons group with their figures as a range; other outcomes by name."""
    results = [
        EpisodeResult(0, "crash", "touched down 0.16 m from the tag centre (> 0.15 m)"),
        EpisodeResult(1, "crash", "touched down 0.31 m from the tag centre (> 0.15 m)"),
        EpisodeResult(2, "crash", "hit the ground"),
        EpisodeResult(3, "timeout"),
        EpisodeResult(4, "success"),
    ]
    assert failure_groups(results) == [
        ("touched down 0.16..0.31 m from the tag centre (> 0.15 m)", 2),
        ("hit the ground", 1),
        ("timeout", 1),
    ]
