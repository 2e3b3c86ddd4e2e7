"""PPO on a functional JAX env (rejax), its checkpoints and the exported numpy policy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.rl
jax = pytest.importorskip("jax")
pytest.importorskip("rejax")

from functional_toy import Drop  # noqa: E402

from ihrcf_env.control.mlp_policy import MlpPolicy  # noqa: E402
from ihrcf_env.rl.jax_ppo import (  # noqa: E402
    PPOSettings,
    _mean_action,
    export_policy,
    load_checkpoint,
    train,
)

SETTINGS = PPOSettings(num_envs=16, num_steps=16, num_minibatches=4, hidden=(16, 16))


def test_train_runs_resumes_and_exports(tmp_path: Path) -> None:
    fenv = Drop()
    lines: list[str] = []
    algo, ts, curve = train(fenv, tmp_path, 6144, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert [r["steps"] for r in curve] == [2048, 4096, 6144]
    assert all(np.isfinite(r["return"]) for r in curve)
    # a second call resumes from the folder and trains on
    _, ts2, curve2 = train(fenv, tmp_path, 8192, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert len(curve2) == 4 and any("resumed" in line for line in lines)
    # the exported policy acts as the trained actor's mean
    pol = export_policy(algo, ts2, tmp_path / "p.npz", trained="toy")
    back = MlpPolicy.load(tmp_path / "p.npz")
    act = _mean_action(algo, ts2)
    for obs in np.random.default_rng(0).normal(size=(5, 2)).astype(np.float32):
        np.testing.assert_allclose(back.act(obs), np.asarray(act(obs)), atol=2e-5)
    assert pol.meta == {"trained": "toy"}
    # best.msgpack holds the state of the first chunk with the highest evaluated success rate
    best = max(range(len(curve2)), key=lambda k: curve2[k]["success"])
    assert (tmp_path / "best.msgpack").exists()
    with jax.enable_x64(False):
        kept = load_checkpoint(ts2, tmp_path / "best.msgpack")
    if best == len(curve2) - 1:
        np.testing.assert_array_equal(np.asarray(kept.obs_rms_state.mean), np.asarray(ts2.obs_rms_state.mean))
    else:  # an earlier chunk's state: fewer observations counted than the last one's
        assert float(kept.obs_rms_state.count) < float(ts2.obs_rms_state.count)


def test_the_batched_step_resets_only_the_envs_that_ended() -> None:
    from ihrcf_env.rl.jax_ppo import LandingPPO, gymnax_env

    fenv = Drop()
    env, params = gymnax_env(fenv, 40)
    algo = LandingPPO.create(env=env, env_params=params, num_envs=8, num_steps=4, total_timesteps=32)
    keys = jax.random.split(jax.random.PRNGKey(0), 8)
    _, state = jax.vmap(env.reset_env, in_axes=(0, None))(keys, params)
    inner, t = state
    inner = {**inner, "h": inner["h"].at[:3].set(0.01)}  # three envs land this step
    actions = jax.numpy.zeros((8, 1))
    obs, (new, t2), reward, done, _ = jax.jit(algo.vmap_step)(keys, (inner, t), actions, params)
    d = np.asarray(done)
    np.testing.assert_array_equal(d, np.arange(8) < 3)
    np.testing.assert_array_equal(np.asarray(t2), np.where(d, 0, 1))  # new episodes start at t = 0
    assert np.all(np.asarray(new["h"])[d] >= 1.0) and np.all(np.asarray(new["h"])[~d] > 0.0)
    np.testing.assert_allclose(np.asarray(obs)[:, 0], np.asarray(new["h"]), rtol=1e-6)


def test_a_new_run_starts_from_an_exported_policy(tmp_path: Path) -> None:
    from ihrcf_env.rl.jax_ppo import load_policy, make_ppo

    fenv = Drop()
    algo, ts, _ = train(fenv, tmp_path / "a", 2048, 40, SETTINGS, chunk_timesteps=2048, log=lambda _: None)
    pol = export_policy(algo, ts, tmp_path / "p.npz")
    with jax.enable_x64(False):
        fresh = make_ppo(fenv, 40, SETTINGS, 2048)
        ts0 = fresh.init_state(jax.random.PRNGKey(7))
        loaded = load_policy(ts0, pol, -1.5)
        act = _mean_action(fresh, loaded)
        for obs in np.random.default_rng(1).normal(size=(5, 2)).astype(np.float32):
            np.testing.assert_allclose(np.asarray(act(obs)), pol.act(obs), atol=2e-5)
        np.testing.assert_allclose(np.asarray(loaded.actor_ts.params["params"]["action_log_std"]), -1.5)
        small = export_policy(algo, ts, tmp_path / "q.npz")
        small.weights[0] = small.weights[0][:8]
        small.biases[0] = small.biases[0][:8]
        with pytest.raises(ValueError, match="layer Dense_0"):
            load_policy(ts0, small, -1.0)
    # train(init_policy=) starts there; a run left in the folder resumes instead
    lines: list[str] = []
    train(fenv, tmp_path / "b", 2048, 40, SETTINGS, chunk_timesteps=2048, log=lines.append,
          init_policy=tmp_path / "p.npz")  # fmt: skip
    assert any("initialised from" in line for line in lines)
    with pytest.raises(ValueError, match="init_log_std"):
        train(fenv, tmp_path / "c", 2048, 40, SETTINGS, init_policy=tmp_path / "p.npz", init_log_std=9.0)
