"""PPO smoke test (stable-baselines3, ``rl`` marker): ``examples/train_ppo.py`` trains a few hundred
steps on v1 with the projected camera over 2 processes, writes its curves and checkpoints, the
saved policy reloads and reproduces its last held-out evaluation, and ``--resume`` continues."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import example

pytestmark = pytest.mark.rl

CAMERA = "projected"
TINY = [
    "--n-steps",
    "64",
    "--batch-size",
    "64",
    "--n-epochs",
    "2",
    "--eval-every",
    "128",
    "--eval-episodes",
    "2",
    "--checkpoint-every",
    "128",
    "--max-episode-steps",
    "60",
    "--n-envs",
    "2",
    "--camera-model",
    CAMERA,
]


def test_running_norm_matches_numpy_and_clips() -> None:
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    import torch as th

    from ihrcf_env.rl.sb3 import RunningNormExtractor

    ext = RunningNormExtractor(gym.spaces.Box(-np.inf, np.inf, (3,), np.float32), clip=5.0)
    rng = np.random.default_rng(0)
    a = rng.normal([1.0, -2.0, 0.0], [0.5, 3.0, 1e-3], size=(40, 2, 3))
    b = rng.normal([1.5, -1.0, 0.0], [0.5, 3.0, 1e-3], size=(25, 3))
    ext.update(a)
    bad = np.full((1, 3), np.nan)
    ext.update(np.concatenate([b, bad]))  # the non-finite row is ignored
    both = np.concatenate([a.reshape(-1, 3), b])
    np.testing.assert_allclose(ext.mean.numpy(), both.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(ext.var.numpy(), both.var(axis=0), rtol=1e-10)
    assert float(ext.count) == 105
    x = th.as_tensor([[1.0, -2.0, 1.0]])
    y = ext(x).numpy()[0]
    np.testing.assert_allclose(
        y[:2], (x.numpy()[0, :2] - both.mean(0)[:2]) / np.sqrt(both.var(0)[:2] + 1e-4), rtol=1e-5
    )
    assert y[2] == 5.0  # 1 / sqrt(1e-6 + 1e-4) = 99.5, clipped


def test_running_norm_reads_only_its_inputs_and_saves_them(closing, tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    import torch as th
    from stable_baselines3 import PPO

    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.sb3 import RunningNormExtractor, norm_extractors

    space = gym.spaces.Box(-np.inf, np.inf, (4,), np.float32)
    ext = RunningNormExtractor(space, inputs=[3, 1])
    assert ext.features_dim == 2
    ext.update(np.array([[0.0, 1.0, 2.0, 3.0], [2.0, 3.0, 4.0, 7.0]]))  # statistics of all 4 entries
    y = ext(th.as_tensor([[9.0, 2.0, 9.0, 5.0]])).numpy()[0]
    np.testing.assert_allclose(y, [0.0, 0.0], atol=1e-6)  # entries 3 and 1, at their means
    for bad in ([], [4], [-1], [1, 1]):
        with pytest.raises(ValueError, match="inputs"):
            RunningNormExtractor(space, inputs=bad)
    env = closing(make_env("ihrcf_env/DeckLanding-v1", CAMERA))
    kw = {
        "features_extractor_class": RunningNormExtractor,
        "features_extractor_kwargs": {"inputs": [0, 5]},
    }
    PPO("MlpPolicy", env, seed=0, device="cpu", policy_kwargs=kw).save(tmp_path / "p.zip")
    (loaded,) = norm_extractors(PPO.load(tmp_path / "p.zip", device="cpu"))
    assert loaded.inputs.tolist() == [0, 5] and loaded.features_dim == 2


def test_train_ppo_saves_a_policy_that_reloads_and_resumes(
    closing, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from ihrcf_env.rl.curves import read_csv
    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.sb3 import RunningNormExtractor, evaluate_on_seeds, norm_extractors

    train_ppo = example("train_ppo")
    out = tmp_path / "ppo"
    assert train_ppo.main(["--total-steps", "256", "--out", str(out), *TINY]) == 0
    text = capsys.readouterr().out
    assert f"training PPO on ihrcf_env/DeckLanding-v1 (camera_model={CAMERA}, 2 envs)" in text
    assert "256 steps in" in text and "held-out success: last" in text
    for name in (
        "final.zip",
        "best.zip",
        "curves.png",
        "train.csv",
        "eval.csv",
        "checkpoints/latest.zip",
        "checkpoints/vecnormalize.pkl",
    ):
        assert (out / name).stat().st_size > 0, name
    assert (out / "final.zip").stat().st_size < 1_000_000  # a small policy file
    kept = sorted(p.name for p in (out / "checkpoints").glob("steps_*.zip"))
    assert kept == ["steps_128.zip", "steps_256.zip"]  # every checkpoint kept, for a later selection
    evals = read_csv(out / "eval.csv")
    assert [int(r["timesteps"]) for r in evals] == [128, 256]
    assert all(0 <= float(r["success_rate"]) <= 1 for r in evals)
    train_rows = read_csv(out / "train.csv")
    steps = [int(r["timesteps"]) for r in train_rows]
    assert train_rows and steps == sorted(steps) and all(0 < int(r["length"]) <= 60 for r in train_rows)

    model = PPO.load(out / "final.zip", device="cpu")
    (ext,) = norm_extractors(model)
    assert isinstance(ext, RunningNormExtractor) and float(ext.count) == 128  # one rollout (2 x 64) merged
    env = closing(make_env("ihrcf_env/DeckLanding-v1", CAMERA, max_episode_steps=60))
    assert model.observation_space == env.observation_space
    res = evaluate_on_seeds(model, env, [20_000, 20_001])  # the seeds of the run's evaluations
    assert res.mean_return == pytest.approx(float(evals[-1]["mean_return"]), rel=1e-6, abs=1e-9)
    assert res.success_rate == float(evals[-1]["success_rate"])

    more = ["--curriculum-steps", "1000", "--reward-weights", "time=2", "success=150"]  # training options
    assert train_ppo.main(["--total-steps", "384", "--out", str(out), "--resume", *more, *TINY]) == 0
    assert "resuming from" in capsys.readouterr().out
    evals2 = read_csv(out / "eval.csv")
    assert [int(r["timesteps"]) for r in evals2] == [128, 256, 384] and evals2[:2] == evals
    assert PPO.load(out / "final.zip", device="cpu").num_timesteps == 384

    # a wall-clock budget already spent (earlier segments count): stops at once, still saves
    args = ["--total-steps", "100000", "--out", str(out), "--resume", "--max-wall-min", "0.001", *TINY]
    assert train_ppo.main(args) == 0
    stopped = PPO.load(out / "final.zip", device="cpu").num_timesteps
    assert 384 < stopped < 384 + 128
    assert int(read_csv(out / "eval.csv")[-1]["timesteps"]) == stopped


def test_curriculum_callback_raises_the_level_with_the_steps(closing) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ihrcf_env.rl.curriculum import StartCurriculum
    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.sb3 import CurriculumCallback

    venv = closing(
        DummyVecEnv(
            [lambda: StartCurriculum(make_env("ihrcf_env/DeckLanding-v1", CAMERA, max_episode_steps=30))]
        )
    )
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    cb = CurriculumCallback(256)
    model.learn(192, callback=cb)  # rollouts start at 0, 64 and 128 steps
    assert cb.level == 0.5 and venv.get_attr("level") == [0.5]
    model.learn(128, callback=cb, reset_num_timesteps=False)  # 192, 256: then the task's start
    assert cb.level == 1.0 and venv.get_attr("level") == [1.0]
    with pytest.raises(ValueError, match="steps"):
        CurriculumCallback(0)


def test_initial_action_mean_sets_the_untrained_policys_mean(closing) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.sb3 import RunningNormExtractor, set_initial_action_mean

    env = closing(make_env("ihrcf_env/DeckLanding-v1", CAMERA))
    kw = {"features_extractor_class": RunningNormExtractor, "log_std_init": -1.0}
    model = PPO("MlpPolicy", env, seed=0, device="cpu", policy_kwargs=kw)
    set_initial_action_mean(model, [0.0, 0.0, -0.3, 0.0])
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    np.testing.assert_allclose(action, [0.0, 0.0, -0.3, 0.0], atol=0.05)  # the small weights' part
    for bad in ([0.0, 0.0], [0.0, 0.0, float("nan"), 0.0]):
        with pytest.raises(ValueError, match="mean"):
            set_initial_action_mean(model, bad)


def test_train_ppo_on_the_native_vector_env(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from ihrcf_env.rl.curves import read_csv

    train_ppo = example("train_ppo")
    out = tmp_path / "ppo"
    assert train_ppo.main(["--total-steps", "128", "--out", str(out), "--vector", *TINY]) == 0
    text = capsys.readouterr().out
    assert f"(camera_model={CAMERA}, 2 envs, vector env)" in text and "128 steps in" in text
    assert PPO.load(out / "final.zip", device="cpu").num_timesteps == 128
    assert [int(r["timesteps"]) for r in read_csv(out / "eval.csv")] == [128]
    for bad in (
        ["--curriculum-steps", "100"],
        ["--env-id", "ihrcf_env/DeckHover-v0"],
        ["--frame-stack", "2"],
    ):
        with pytest.raises(SystemExit) as e:
            train_ppo.main(["--vector", "--out", str(out), *bad])
        assert e.value.code == 2
        assert "--vector" in capsys.readouterr().err
    # the same envs over 2 worker processes
    out2 = tmp_path / "ppo-workers"
    argv = ["--total-steps", "128", "--out", str(out2), "--vector", "--workers", "2", *TINY]
    assert train_ppo.main(argv) == 0
    assert PPO.load(out2 / "final.zip", device="cpu").num_timesteps == 128
    with pytest.raises(SystemExit) as e:
        train_ppo.main(["--workers", "2", "--out", str(out2)])
    assert e.value.code == 2 and "--workers" in capsys.readouterr().err
    for frames in ("0", "65"):
        with pytest.raises(SystemExit) as e:
            train_ppo.main(["--frame-stack", frames, "--out", str(out2)])
        assert e.value.code == 2 and "--frame-stack" in capsys.readouterr().err
