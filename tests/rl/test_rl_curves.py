"""The torch-free parts of ``ihrcf_env.rl``: curve CSVs, their plot, the env factory's success flag.

These run in the default (lean) test run; the learning smoke tests beside them carry the ``rl``
marker and need the ``[rl]`` extra.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from ihrcf_env.rl.curves import (
    EVAL_FIELDS,
    TRAIN_FIELDS,
    CsvLog,
    plot_curves,
    read_csv,
    rolling_mean,
    summary,
)
from ihrcf_env.rl.envs import SuccessInfo, make_env


def _row(t: int, r: float = 1.0, s: int = 0) -> dict[str, float | int]:
    return {"timesteps": t, "return": r, "length": 10, "is_success": s}


def test_csv_log_appends_and_resume_drops_rows_after_the_checkpoint(tmp_path: Path) -> None:
    path = tmp_path / "train.csv"
    log = CsvLog(path, TRAIN_FIELDS)
    for t in (100, 200, 300):
        log.write(_row(t))
    assert [r["timesteps"] for r in read_csv(path)] == ["100", "200", "300"]
    resumed = CsvLog(path, TRAIN_FIELDS, keep_until=200)  # the checkpoint was at 200 steps
    resumed.write(_row(250, 5.0, 1))
    rows = read_csv(path)
    assert [r["timesteps"] for r in rows] == ["100", "200", "250"]
    assert rows[-1]["return"] == "5.0" and rows[-1]["is_success"] == "1"
    CsvLog(path, TRAIN_FIELDS)  # a new run overwrites
    assert read_csv(path) == []


def test_csv_log_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="timesteps"):
        CsvLog(tmp_path / "a.csv", ("return",))
    with pytest.raises(TypeError, match="keep_until"):
        CsvLog(tmp_path / "a.csv", TRAIN_FIELDS, keep_until=1.5)  # type: ignore[arg-type]
    log = CsvLog(tmp_path / "a.csv", TRAIN_FIELDS)
    with pytest.raises(ValueError, match="row keys"):
        log.write({"timesteps": 1})


def test_rolling_mean() -> None:
    np.testing.assert_allclose(rolling_mean([1, 2, 3, 4], 2), [1.0, 1.5, 2.5, 3.5])
    np.testing.assert_allclose(rolling_mean([0, 1, 1, 0], 10), [0.0, 0.5, 2 / 3, 0.5])
    with pytest.raises(ValueError, match="window"):
        rolling_mean([1.0], 0)


def test_plot_curves_and_summary(tmp_path: Path) -> None:
    train = CsvLog(tmp_path / "train.csv", TRAIN_FIELDS)
    for i in range(30):
        train.write(_row(100 * (i + 1), float(i), int(i > 20)))
    ev = CsvLog(tmp_path / "eval.csv", EVAL_FIELDS)
    for t, sr in ((1000, 0.0), (2000, 0.5), (3000, 0.25)):
        ev.write(
            {
                "timesteps": t,
                "wall_s": 1.0,
                "mean_return": 1.0,
                "std_return": 0.5,
                "success_rate": sr,
                "mean_length": 10.0,
            }
        )
    png = plot_curves(tmp_path / "train.csv", tmp_path / "eval.csv", tmp_path / "c.png", window=5)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert summary(tmp_path / "eval.csv") == {
        "last_success_rate": 0.25,
        "best_success_rate": 0.5,
        "timesteps": 3000,
    }
    assert plot_curves(None, tmp_path / "missing.csv", tmp_path / "empty.png").exists()  # nothing to draw yet


class _Outcome(gym.Env[np.ndarray, np.ndarray]):
    """Ends every episode after two steps with ``info["outcome"]`` as given."""

    observation_space = gym.spaces.Box(-1, 1, (1,), np.float32)
    action_space = gym.spaces.Box(-1, 1, (1,), np.float32)

    def __init__(self, outcome: str, own: bool | None = None):
        self.outcome, self.own, self.n = outcome, own, 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        self.n = 0
        return np.zeros(1, np.float32), {}

    def step(self, action: np.ndarray) -> Any:
        self.n += 1
        info: dict[str, Any] = {"outcome": "flying" if self.n < 2 else self.outcome}
        if self.own is not None and self.n == 2:
            info["is_success"] = self.own
        return np.zeros(1, np.float32), 0.0, self.n == 2, False, info


@pytest.mark.parametrize(
    ("outcome", "own", "expected"), [("success", None, True), ("crash", None, False), ("crash", True, True)]
)
def test_success_info_at_episode_end(outcome: str, own: bool | None, expected: bool) -> None:
    env = SuccessInfo(_Outcome(outcome, own))
    env.reset(seed=0)
    assert "is_success" not in env.step(np.zeros(1, np.float32))[4]
    assert env.step(np.zeros(1, np.float32))[4]["is_success"] is expected


def test_make_env_rejects_an_unknown_id() -> None:
    with pytest.raises(ValueError, match="env_id"):
        make_env("ihrcf_env/NoSuchEnv-v9")


def test_importing_the_package_and_its_torch_free_rl_modules_loads_no_learning_library() -> None:
    code = (
        "import sys, ihrcf_env, ihrcf_env.rl, ihrcf_env.rl.curves, ihrcf_env.rl.envs, ihrcf_env.rl.rllib\n"
        "print(sorted(m for m in ('torch', 'stable_baselines3', 'ray') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
