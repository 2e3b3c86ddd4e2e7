"""The forecast figure's frames and error figures (the episode itself is flown by the CLI)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix
from ihrcf_env.experiments.forecast_figure import ForecastTrace, errors, save_figure, true_motion


def test_true_motion_turns_the_deck_normal_into_the_heading_frame() -> None:
    deck = quat_from_matrix(matrix_from_euler(0.05, 0.0, 0.0))  # rolled about the world x
    drone = quat_from_matrix(matrix_from_euler(0.0, 0.0, math.pi / 2))  # heading along world y
    m = true_motion(
        {"deck_quaternion_world": deck, "drone_quaternion_world": drone, "deck_position_world": [0, 0, 0.3]}
    )
    assert m[0] == pytest.approx(0.3)
    # world x is the heading frame's -y: a roll about world x is a pitch of -0.05 about heading y
    assert m[2] == pytest.approx(0.0, abs=1e-12) and m[3] == pytest.approx(-0.05, abs=1e-9)


def _trace(forecast_lag: float) -> ForecastTrace:
    t = np.arange(0.0, 20.0, 0.05)
    truth = np.zeros((t.size, 4))
    truth[:, 2] = 0.02 * np.sin(2 * math.pi * t / 1.5)
    mean = np.full((t.size, 4), np.nan)
    ok = t >= 5.0
    mean[ok, 2] = 0.02 * np.sin(2 * math.pi * (t[ok] + 1.0 - forecast_lag) / 1.5)
    mean[np.ix_(ok, [0, 3])] = 0.0
    zero = np.zeros(t.size)
    return ForecastTrace(t, truth, mean, np.full_like(mean, 0.01), 1.0, "timeout", zero, zero)


def test_errors_score_a_perfect_forecast_at_zero_and_persistence_above_it() -> None:
    f, p, n = errors(_trace(0.0))["roll"]
    assert f == pytest.approx(0.0, abs=1e-3) and p > 0.01 and n > 200
    f_bad, _, _ = errors(_trace(0.4))["roll"]
    assert f_bad > 0.01


def test_the_figure_is_written(tmp_path) -> None:  # type: ignore[no-untyped-def]
    pytest.importorskip("matplotlib")
    out = save_figure(_trace(0.0), tmp_path / "f.png", "test")
    assert out.exists() and out.stat().st_size > 10_000
