"""DAgger warm start (``ihrcf_env.rl.imitation``, ``rl`` marker): the expert's labels, the policy
fit, the critic warm-up's frozen actor and the train_ppo options that use them."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.rl

V1 = "ihrcf_env/DeckLanding-v1"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _venv(steps: int = 40) -> Any:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ihrcf_env.rl.envs import make_env

    return DummyVecEnv([lambda: make_env(V1, "projected", max_episode_steps=steps)])


def _model(venv: Any) -> Any:
    from stable_baselines3 import PPO

    from ihrcf_env.rl.sb3 import RunningNormExtractor

    kw = {"features_extractor_class": RunningNormExtractor, "net_arch": [32, 32], "log_std_init": -2.0}
    return PPO(
        "MlpPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu", policy_kwargs=kw
    )


def test_collect_labels_every_step_with_the_expert(closing) -> None:
    from ihrcf_env.control.policies import BlindDescent
    from ihrcf_env.rl.imitation import collect

    venv = closing(_venv())
    expert = BlindDescent(0.3)
    obs, act, landed, flown = collect(venv, [expert], episodes=2, seed=30_000)
    assert flown == 2 and landed == 0 and obs.shape == (80, *venv.observation_space.shape)
    np.testing.assert_allclose(act, np.tile([0.0, 0.0, -0.3, 0.0], (80, 1)), atol=1e-7)
    assert np.isfinite(obs).all()
    again, _, _, _ = collect(venv, [expert], episodes=2, seed=30_000)
    np.testing.assert_array_equal(again, obs)  # seeded
    # the learner flies (here: an untrained policy), the expert still labels every step
    model = _model(venv)
    o2, a2, _, _ = collect(venv, [expert], 1, 30_001, model, noise=0.1, rng=np.random.default_rng(0))
    assert len(o2) == 40 and np.allclose(a2[:, 2], -0.3)
    for kwargs, match in (
        ({"experts": []}, "one expert per env"),
        ({"episodes": 0}, "episodes"),
        ({"noise": -1.0}, "noise"),
        ({"noise": 0.1}, "noise"),  # no rng
    ):
        args = {"venv": venv, "experts": [expert], "episodes": 1, "seed": 0} | kwargs
        with pytest.raises(ValueError, match=match):
            collect(**args)


def test_fit_policy_regresses_the_mean_and_sets_the_normaliser(closing) -> None:
    from ihrcf_env.control.policies import BlindDescent
    from ihrcf_env.rl.imitation import dagger, fit_policy
    from ihrcf_env.rl.sb3 import norm_extractors

    venv = closing(_venv())
    model = _model(venv)
    rng = np.random.default_rng(0)
    n, d = 2000, venv.observation_space.shape[0]
    obs = rng.normal(0.3, 0.2, size=(n, d)).astype(np.float32)
    target = np.clip(obs[:, :4] - 0.3, -1, 1).astype(np.float32)  # a function of the observation
    before = float(np.mean((model.predict(obs, deterministic=True)[0] - target) ** 2))
    loss = fit_policy(model, obs, target, epochs=30)
    after = float(np.mean((model.predict(obs, deterministic=True)[0] - target) ** 2))
    assert loss < 0.2 * before and after < 0.2 * before
    (ext,) = norm_extractors(model)
    np.testing.assert_allclose(ext.mean.numpy(), obs.mean(axis=0), rtol=1e-5, atol=1e-6)
    assert float(ext.count) == n
    with pytest.raises(ValueError, match="matching"):
        fit_policy(model, obs[:10], target[:9])
    with pytest.raises(ValueError, match="rounds"):
        dagger(model, venv, lambda: BlindDescent(0.3), -1, 1, 0)


def test_dagger_with_the_scripted_expert_aggregates_rounds(closing) -> None:
    from ihrcf_env.control.policies import ScriptedLanding
    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.imitation import dagger

    venv = closing(_venv(steps=30))
    probe = closing(make_env(V1, "projected"))
    model = _model(venv)
    rounds = dagger(model, venv, lambda: ScriptedLanding.from_env(probe), 1, 1, 30_000, epochs=2)
    assert [r.pilot for r in rounds] == ["expert", "learner"]
    assert [r.samples for r in rounds] == [30, 60] and all(np.isfinite(r.loss) for r in rounds)


def test_critic_warmup_freezes_the_actor_then_releases_it(closing) -> None:
    import torch as th

    from ihrcf_env.rl.sb3 import CriticWarmupCallback

    venv = closing(_venv())
    model = _model(venv)
    p = model.policy
    actor = [*p.mlp_extractor.policy_net.parameters(), *p.action_net.parameters(), p.log_std]
    critic = [*p.mlp_extractor.value_net.parameters(), *p.value_net.parameters()]
    a0 = [t.detach().clone() for t in actor]
    c0 = [t.detach().clone() for t in critic]
    cb = CriticWarmupCallback(128)
    model.learn(128, callback=cb)  # two updates, both critic only
    assert all(th.equal(a, b) for a, b in zip(a0, actor, strict=True))
    assert not all(th.equal(a, b) for a, b in zip(c0, critic, strict=True))
    assert all(t.requires_grad for t in actor)  # released at the end of learn()
    model.learn(64, callback=cb, reset_num_timesteps=False)  # past the warm-up: the actor learns
    assert not all(th.equal(a, b) for a, b in zip(a0, actor, strict=True))
    with pytest.raises(ValueError, match="steps"):
        CriticWarmupCallback(-1)


def test_train_ppo_with_dagger_logs_rounds_and_evaluates_the_warm_start(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO

    from ihrcf_env.rl.curves import read_csv
    from ihrcf_env.rl.imitation import DAGGER_FIELDS
    from ihrcf_env.rl.sb3 import norm_extractors

    spec = importlib.util.spec_from_file_location("_example_train_ppo_dagger", EXAMPLES / "train_ppo.py")
    assert spec is not None and spec.loader is not None
    train_ppo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(train_ppo)
    out = tmp_path / "ppo"
    args = ["--total-steps", "128", "--out", str(out), "--n-steps", "64", "--batch-size", "64"]
    args += ["--n-epochs", "1", "--eval-every", "128", "--eval-episodes", "1", "--max-episode-steps", "30"]
    args += ["--n-envs", "2", "--dagger-rounds", "1", "--dagger-episodes", "2", "--critic-warmup-steps", "64"]
    assert train_ppo.main(args) == 0
    text = capsys.readouterr().out
    assert "DAgger round 0: expert landed" in text and "DAgger round 1: learner landed" in text
    rows = read_csv(out / "dagger.csv")
    assert list(rows[0]) == list(DAGGER_FIELDS) and [r["expert_flies"] for r in rows] == ["1", "0"]
    assert [int(r["timesteps"]) for r in read_csv(out / "eval.csv")] == [0, 128]
    model = PPO.load(out / "final.zip", device="cpu")
    (ext,) = norm_extractors(model)
    assert float(ext.count) == int(rows[-1]["samples"])  # the DAgger data's statistics, kept by PPO
    for bad in (["--dagger-episodes", "0"], ["--drop-inputs", "nonsense"]):
        with pytest.raises(SystemExit):
            train_ppo.main([*bad, "--out", str(out)])
        assert bad[0] in capsys.readouterr().err  # argparse names the option


def test_a_frame_stacked_policy_runs_on_the_flat_env(closing, tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import DummyVecEnv

    from ihrcf_env.control.policies import BlindDescent
    from ihrcf_env.experiments.policies import make_policy
    from ihrcf_env.rl.envs import make_env
    from ihrcf_env.rl.imitation import collect

    venv = closing(DummyVecEnv([lambda: make_env(V1, "projected", 3, max_episode_steps=20)]))
    obs, act, _, flown = collect(venv, [BlindDescent(0.3)], episodes=1, seed=30_000)
    assert flown == 1 and obs.shape[1:] == (3, venv.observation_space.shape[1]) and len(act) == len(obs)
    model = _model(venv)
    model.save(tmp_path / "stacked.zip")
    flat = closing(make_env(V1, "projected", max_episode_steps=20))
    stacked = closing(make_env(V1, "projected", 3, max_episode_steps=20))
    policy = make_policy(str(tmp_path / "stacked.zip"), flat)  # keeps its own stack of flat observations
    o, _ = flat.reset(seed=5)
    s, _ = stacked.reset(seed=5)
    policy.reset()
    for _ in range(5):
        a = policy.act(o)
        np.testing.assert_array_equal(a, model.predict(s, deterministic=True)[0])
        o, *_ = flat.step(a)
        s, *_ = stacked.step(a)
