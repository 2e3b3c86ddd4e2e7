"""Each example script's ``main`` runs with tiny arguments and prints what the README documents.

The examples are thin command lines over the package (tested in tests/control, tests/experiments,
tests/core); here only their wiring. ``examples/learning_loop.py`` runs as a script in
tests/envs/test_vector.py.
"""

from __future__ import annotations

import gc
import importlib.util
import re
import warnings
from pathlib import Path

import pytest
from conftest import EXAMPLES, example


def test_hover_and_track_prints_table2_and_saves(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "quick"
    argv = ["--seconds", "1", "--profile", "static", "--no-plots", "--out", str(out)]
    assert example("hover_and_track").main(argv) == 0
    captured = capsys.readouterr()
    text = captured.out
    # not a terminal: plain progress lines, not nothing and not a carriage-return bar
    assert "rollout: 20/20 (100 %)" in captured.err and "\r" not in captured.err, captured.err
    for needle in ("Translations (m)", "Angles (degree)", "ATDA", "IHRCF", "Paper Table 2", "Invalid frames"):
        assert needle in text, needle
    for row in ("X", "Y", "Z", "roll", "pitch", "yaw"):
        assert any(row in line.split()[:3] and "0.0" in line for line in text.splitlines()), row
    assert "0.0697" in text and "1.3731" in text  # the paper's values for comparison
    assert "20 frames at 20 Hz" in text and "Tracking with IHRCF" in text and "Wall time" in text
    assert sorted(p.name for p in out.iterdir()) == ["table2.txt", "timeseries.csv"]
    assert (out / "table2.txt").read_text().strip() in text  # the printed table, saved


def test_land_prints_the_report(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--episodes", "1", "--profiles", "static", "--max-seconds", "0.5"]
    assert example("land").main(argv) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  static    seed   0: timeout t=  0\.5 s commit=    - s", out, re.M), out
    assert (
        "landing report (1 episodes per profile, sensor_preset=ideal, tof_noise=preset, estimator=ihrcf, "
        "deck start random" in out
    )
    assert re.search(r"static: success 0/1 \(0 %\)", out), out
    assert "touchdown |relative vertical speed|" in out and "failures: timeout: 1" in out


def test_quickstart_saves_frames(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ResourceWarning)
        assert example("quickstart").main(["--seconds", "0.1", "--out", str(tmp_path)]) == 0
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)]
    assert "deck x" in capsys.readouterr().out
    assert (tmp_path / "camera.png").stat().st_size > 0 and (tmp_path / "chase.png").stat().st_size > 0


def test_examples_are_thin() -> None:
    for path in EXAMPLES.glob("*.py"):
        assert len(path.read_text().splitlines()) <= 150, path.name


@pytest.mark.parametrize(
    ("name", "module"),
    [("train_ppo", "stable_baselines3"), ("train_rllib", "ray"), ("train_recurrent", "torch")],
)
def test_training_without_the_rl_extra_says_how_to_install_it(
    capsys: pytest.CaptureFixture[str], name: str, module: str
) -> None:
    if importlib.util.find_spec(module) is not None:
        pytest.skip(f"{module} is installed")
    assert example(name).main([]) == 2
    out = capsys.readouterr().out.strip()
    assert len(out.splitlines()) == 1 and 'pip install ".[rl]"' in out, out


@pytest.mark.parametrize("flag", ["--episodes", "--workers", "--epochs", "--rounds"])
def test_recurrent_training_names_a_bad_count(capsys: pytest.CaptureFixture[str], flag: str) -> None:
    with pytest.raises(SystemExit) as e:
        example("train_recurrent").main([flag, "-1"])
    assert e.value.code == 2 and flag in capsys.readouterr().err
