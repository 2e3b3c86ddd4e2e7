"""``python -m ihrcf_env.evaluate``: the baselines through one CLI, and its bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.cli.evaluate import Episode, main, summary
from ihrcf_env.control.policies import BlindDescent, level_from_up


def _error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["--policy", "walk"], "--policy"),
        (["--policy", "blind:abc"], "--policy"),
        (["--policy", "blind:"], "--policy"),
        (["--policy", "blind:-0.3"], "--policy"),
        (["--policy", "blind:2.0"], "--policy"),  # beyond max_velocity[2]
        (["--policy", "missing_policy.zip"], "--policy"),
        (["--policy", "blind:0.3", "--episodes", "0"], "--episodes"),
        (["--policy", "blind:0.3", "--env-id", "ihrcf_env/Nothing-v9"], "--env-id"),
        (["--policy", "blind:0.3", "--camera-model", "painted"], "--camera-model"),
        (["--policy", "blind:0.3", "--sensor-preset", "perfect"], "--sensor-preset"),
        (["--policy", "scripted", "--env-id", "ihrcf_env/DeckHoverRaw-v0"], "--policy"),
        (["--policy", "blind:0.3", "--env-id", "ihrcf_env/DeckHover-v0", "--deck-motion"], "deck_motion"),
    ],
)
def test_bad_input_names_the_argument(
    capsys: pytest.CaptureFixture[str], argv: list[str], names: str
) -> None:
    err = _error(capsys, argv)
    assert names in err, err


def test_a_file_that_is_not_a_policy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    junk = tmp_path / "policy.zip"
    junk.write_bytes(b"not a zip")
    err = _error(capsys, ["--policy", str(junk), "--max-steps", "1"])
    assert "--policy" in err and str(junk) in err
    assert ("not installed" in err) or ("cannot be loaded" in err)


@pytest.mark.rl  # needs stable-baselines3: runs in the [rl] venv (`pytest -m rl`, .ci/run)
def test_an_incompatible_sb3_policy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A policy trained on another observation space is refused, naming --policy."""
    sb3 = pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    model = sb3.PPO("MlpPolicy", gym.make("Pendulum-v1"), n_steps=64, batch_size=64, device="cpu")
    path = tmp_path / "pendulum.zip"
    model.save(path)
    err = _error(capsys, ["--policy", str(path), "--max-steps", "1"])
    assert "--policy" in err and "observation space" in err


def test_blind_descent_reports_and_ends_with_the_count(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--policy", "blind:0.5", "--episodes", "2", "--seed", "3", "--max-steps", "20"]
    assert main([*argv, "--camera-model", "projected"]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-1] == "success 0/2"
    assert any("timeout" in line for line in out)
    assert any(line.startswith("episodes 2, success rate 0.0%") for line in out)


def test_scripted_lands_through_the_module_command() -> None:
    """The real entry point (python -m ihrcf_env.evaluate), two episodes of the scripted baseline."""
    args = "--policy scripted --episodes 2 --seed 1 --camera-model projected".split()
    run = subprocess.run(
        [sys.executable, "-m", "ihrcf_env.evaluate", *args],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    assert lines[-1] == "success 2/2", run.stdout
    assert "relative vertical speed" in run.stdout and "offset from the tag centre" in run.stdout


def test_summary_lines() -> None:
    eps = [
        Episode(0, "success", "", 9.0, 180, 110.0, 0.3, 0.05, 0.02),
        Episode(
            1, "crash", "touched down 0.23 m from the tag centre (> 0.15 m)", 12.0, 240, -90.0, 0.2, 0.1, 0.23
        ),
        Episode(
            2, "crash", "touched down 0.31 m from the tag centre (> 0.15 m)", 12.0, 240, -90.0, 0.2, 0.1, 0.31
        ),
        Episode(3, "timeout", "", 30.0, 600, -12.0),
    ]
    lines = summary(eps)
    assert lines[-1] == "success 1/4"
    assert "success rate 25.0%" in lines[0]
    assert "offset from the tag centre 0.187 / 0.310 m" in lines[1]
    assert "touched down N m from the tag centre (> N m) x2" in lines[-2] and "timeout x1" in lines[-2]


def test_policies_are_pure_and_checked() -> None:
    blind = BlindDescent(0.4, (1.0, 1.0, 0.8, 1.0))
    assert blind.act(np.zeros(50, np.float32)) == pytest.approx([0.0, 0.0, -0.5, 0.0])
    with pytest.raises(ValueError, match="vz"):
        BlindDescent(0.0)
    with pytest.raises(TypeError, match="vz"):
        BlindDescent("0.3")  # type: ignore[arg-type]
    # level frame from the up vector: roll/pitch only, the up vector maps back to world z
    roll, pitch = 0.1, -0.2
    up = np.array([-np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)])
    R = level_from_up(up)
    assert R @ up == pytest.approx([0.0, 0.0, 1.0])
    assert R @ R.T == pytest.approx(np.eye(3))
