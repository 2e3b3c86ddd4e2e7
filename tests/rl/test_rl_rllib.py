"""RLlib smoke test (``rl`` marker): ``examples/train_rllib.py`` runs one PPO training iteration on
v1 with 2 env runners on a local Ray instance, logs it and saves a checkpoint."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

pytestmark = pytest.mark.rl

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CAMERA = "projected"


def test_train_rllib_one_iteration_with_two_env_runners(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("ray.rllib")
    pytest.importorskip("torch")
    from ihrcf_env.rl.curves import read_csv
    from ihrcf_env.rl.rllib import env_creator

    env = env_creator({"camera_model": CAMERA, "max_episode_steps": 50})  # what the runners make
    assert (
        env.spec is not None
        and env.spec.id == "ihrcf_env/DeckLanding-v1"
        and env.spec.max_episode_steps == 50
    )
    env.close()

    spec = importlib.util.spec_from_file_location("_example_train_rllib", EXAMPLES / "train_rllib.py")
    assert spec is not None and spec.loader is not None
    train_rllib = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(train_rllib)
    out = tmp_path / "rllib"
    argv = [
        "--iterations",
        "1",
        "--num-env-runners",
        "2",
        "--train-batch-size",
        "200",
        "--minibatch-size",
        "50",
        "--num-epochs",
        "1",
        "--max-episode-steps",
        "50",
        "--camera-model",
        CAMERA,
        "--out",
        str(out),
    ]
    assert train_rllib.main(argv) == 0
    text = capsys.readouterr().out
    assert "2 env runners" in text and "iter 1: " in text
    (row,) = read_csv(out / "progress.csv")
    assert row["iteration"] == "1" and int(row["timesteps"]) >= 200
    assert int(row["episodes"]) >= 2 and float(row["episode_len_mean"]) <= 50  # 200 steps, episodes <= 50
    assert math.isfinite(float(row["episode_return_mean"])) and 0 <= float(row["success_rate"]) <= 1
    assert (out / "checkpoint" / "rllib_checkpoint.json").is_file()


def test_train_rllib_on_the_native_vector_env(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("ray.rllib")
    pytest.importorskip("torch")
    from ihrcf_env.rl.curves import read_csv
    from ihrcf_env.rl.rllib import env_creator
    from ihrcf_env.vector import DeckLandingVectorEnv

    # what RLlib's runners call with gym_env_vectorize_mode=VECTOR_ENTRY_POINT: the config + num_envs
    venv = env_creator({"camera_model": CAMERA, "max_episode_steps": 50, "num_envs": 2})
    assert isinstance(venv, DeckLandingVectorEnv) and venv.num_envs == 2
    assert venv.max_episode_steps == 50
    venv.close()
    with pytest.raises(ValueError, match="env_id"):
        env_creator({"env_id": "ihrcf_env/DeckHover-v0", "num_envs": 2})

    spec = importlib.util.spec_from_file_location("_example_train_rllib", EXAMPLES / "train_rllib.py")
    assert spec is not None and spec.loader is not None
    train_rllib = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(train_rllib)
    out = tmp_path / "rllib"
    argv = ["--iterations", "1", "--num-env-runners", "0", "--num-envs-per-env-runner", "2", "--vector-env"]
    argv += ["--train-batch-size", "120", "--minibatch-size", "40", "--num-epochs", "1"]
    argv += ["--max-episode-steps", "30", "--camera-model", CAMERA, "--num-cpus", "1", "--out", str(out)]
    assert train_rllib.main(argv) == 0
    assert "0 env runners, 2 envs each (native vector env)" in capsys.readouterr().out
    (row,) = read_csv(out / "progress.csv")
    assert int(row["timesteps"]) >= 120 and int(row["episodes"]) >= 2
    assert float(row["episode_len_mean"]) <= 30 and 0 <= float(row["success_rate"]) <= 1
