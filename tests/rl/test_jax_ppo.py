"""PPO on a functional JAX env: its checkpoints, resumption, time budget and the exported numpy
policy; the learner's pieces (advantages, statistics)."""

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
    export_policy,
    load_checkpoint,
    load_policy,
    main,
    make_learner,
    mean_action_fn,
    train,
)
from ihrcf_env.rl.ppo_learner import RunningStats, Trajectory, gae, update_stats  # noqa: E402

SETTINGS = PPOSettings(num_envs=16, num_steps=16, num_minibatches=4, hidden=(16, 16))


def test_train_runs_resumes_and_exports(tmp_path: Path) -> None:
    fenv = Drop()
    lines: list[str] = []
    learner, ts, curve = train(fenv, tmp_path, 6144, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert [r["steps"] for r in curve] == [2048, 4096, 6144]
    assert all(np.isfinite(r["return"]) and 0.0 <= r["train_success"] <= 1.0 for r in curve)
    assert int(ts.global_step) == 6144
    table = (tmp_path / "curve.csv").read_text().splitlines()
    assert table[0] == "steps,wall_s,success,return,length,train_success"
    assert [int(line.split(",")[0]) for line in table[1:]] == [2048, 4096, 6144]
    # a second call resumes from the folder and trains on
    _, ts2, curve2 = train(fenv, tmp_path, 8192, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert len(curve2) == 4 and any("resumed" in line for line in lines)
    # the exported policy acts as the trained actor's mean
    pol = export_policy(learner, ts2, tmp_path / "p.npz", trained="toy")
    back = MlpPolicy.load(tmp_path / "p.npz")
    act = mean_action_fn(learner, ts2)
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


def test_the_toy_is_learned() -> None:
    """PPO learns to slow the falling body: a random policy's return is about -0.4 (it never lands
    slowly); the trained mean action lands at least a third of the bodies slower than 1 m/s."""
    settings = PPOSettings(
        num_envs=32,
        num_steps=16,
        num_minibatches=4,
        hidden=(32, 32),
        learning_rate=3e-3,
        gamma=0.99,
        init_log_std=0.0,
        # the toy's own settings (its rewards are of order 1; the recipe's are the landing task's)
        reward_scale=1.0,
        clip_value=True,
        init_output_scale=1.0,
    )
    _, _, curve = train(Drop(), _tmp(), 60_000, 40, settings, chunk_timesteps=20_000, log=lambda _: None)
    assert curve[-1]["success"] >= 0.33 and curve[-1]["return"] > 2.0, curve


def _tmp() -> Path:
    import tempfile

    return Path(tempfile.mkdtemp())


def test_a_time_budget_stops_the_run_in_time(tmp_path: Path) -> None:
    import time

    started = time.monotonic()
    _, _, curve = train(
        Drop(), tmp_path, 10**9, 40, SETTINGS, chunk_timesteps=2048, log=lambda _: None, time_budget_s=25.0,
        started=started,
    )  # fmt: skip
    assert time.monotonic() - started < 25.0
    assert curve and curve[-1]["steps"] < 10**9


def test_a_new_run_starts_from_an_exported_policy(tmp_path: Path) -> None:
    fenv = Drop()
    learner, ts, _ = train(fenv, tmp_path / "a", 2048, 40, SETTINGS, chunk_timesteps=2048, log=lambda _: None)
    pol = export_policy(learner, ts, tmp_path / "p.npz")
    with jax.enable_x64(False):
        fresh = make_learner(fenv, SETTINGS)
        ts0 = fresh.init(jax.random.PRNGKey(7))
        loaded = load_policy(ts0, pol, -1.5)
        act = mean_action_fn(fresh, loaded)
        for obs in np.random.default_rng(1).normal(size=(5, 2)).astype(np.float32):
            np.testing.assert_allclose(np.asarray(act(obs)), pol.act(obs), atol=2e-5)
        np.testing.assert_allclose(np.asarray(loaded.actor_ts.params["params"]["action_log_std"]), -1.5)
        small = export_policy(learner, ts, tmp_path / "q.npz")
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


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"total_timesteps": 0}, "total_timesteps"),
        ({"chunk_timesteps": -5}, "chunk_timesteps"),
        ({"time_budget_s": 0}, "time_budget_s"),
        ({"settings": PPOSettings(num_envs=0)}, "num_envs"),
        ({"settings": PPOSettings(num_envs=16, num_steps=3, num_minibatches=5)}, "num_minibatches"),
        ({"settings": PPOSettings(num_envs=16, devices=64)}, "devices"),
        ({"settings": PPOSettings(num_envs=16, reward_scale=0.0)}, "reward_scale"),
        ({"settings": PPOSettings(num_envs=16, init_output_scale=2.0)}, "init_output_scale"),
        ({"settings": PPOSettings(num_envs=16, init_action_mean=(3.0,))}, "init_action_mean"),
        ({"settings": PPOSettings(num_envs=16, init_action_mean=(0.1, 0.2))}, "init_action_mean"),
    ],
)
def test_bad_arguments_are_named_before_anything_compiles(tmp_path: Path, kwargs: dict, name: str) -> None:
    args = {"total_timesteps": 2048, "settings": SETTINGS, "chunk_timesteps": 2048, **kwargs}
    with pytest.raises(ValueError, match=name):
        train(Drop(), tmp_path, args.pop("total_timesteps"), 40, log=lambda _: None, **args)


@pytest.mark.parametrize(
    "argv, text",
    [
        (["--time-budget", "0"], "--time-budget"),
        (["--time-budget", "-3"], "--time-budget"),
        (["--timesteps", "0"], "--timesteps"),
        (["--num-envs", "0"], "--num-envs"),
        (["--num-envs", "abc"], "--num-envs"),
        (["--devices", "4096"], "--devices"),
        (["--learning-rate", "2"], "--learning-rate"),
        (["--reward-scale", "0"], "--reward-scale"),
        (["--gamma", "1.5"], "--gamma"),
        (["--ent-coef", "-1"], "--ent-coef"),
        (["--num-epochs", "0"], "--num-epochs"),
    ],
)
def test_the_command_names_a_bad_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], text: str
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(tmp_path), *argv])
    assert exc.value.code == 2
    assert text in capsys.readouterr().err


def test_advantages_follow_the_recursion() -> None:
    T, N = 5, 3
    rng = np.random.default_rng(0)
    reward, value = rng.normal(size=(T, N)), rng.normal(size=(T, N))
    done = rng.random((T, N)) < 0.3
    last = rng.normal(size=N)
    z = np.zeros((T, N))
    traj = Trajectory(z, z, z, jax.numpy.asarray(reward), jax.numpy.asarray(value), jax.numpy.asarray(done))
    adv, targets = gae(traj, jax.numpy.asarray(last), 0.9, 0.8)
    want = np.zeros((T, N))
    a, nxt = np.zeros(N), last
    for t in reversed(range(T)):
        live = 1.0 - done[t]
        delta = reward[t] + 0.9 * nxt * live - value[t]
        a = delta + 0.9 * 0.8 * live * a
        want[t], nxt = a, value[t]
    np.testing.assert_allclose(np.asarray(adv), want, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(np.asarray(targets), want + value, rtol=1e-5, atol=1e-6)


def test_running_statistics_are_those_of_all_rows() -> None:
    rng = np.random.default_rng(1)
    rows = rng.normal(3.0, 2.0, size=(300, 4))
    stats = RunningStats(jax.numpy.zeros(4), jax.numpy.ones(4), jax.numpy.asarray(1e-4))
    for part in np.split(rows, 3):
        stats = update_stats(stats, jax.numpy.asarray(part))
    np.testing.assert_allclose(np.asarray(stats.mean), rows.mean(0), rtol=1e-3)
    np.testing.assert_allclose(np.asarray(stats.var), rows.var(0), rtol=1e-3)


_INTERRUPTED_RUN = """
import sys
sys.path.insert(0, {tests!r})
from functional_toy import Drop
from ihrcf_env.rl.jax_ppo import PPOSettings, train
settings = PPOSettings(num_envs=16, num_steps=16, num_minibatches=4, hidden=(16, 16))
try:
    train(Drop(), {out!r}, 10**9, 40, settings, chunk_timesteps=2048,
          log=lambda line: print(line, flush=True))
except KeyboardInterrupt:
    sys.exit(130)
"""


def test_ctrl_c_leaves_a_resumable_folder(tmp_path: Path) -> None:
    """SIGINT during training: exit 130, a checkpoint that loads, and a new call resumes from its
    step count (the iterations after the last curve row included)."""
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    code = _INTERRUPTED_RUN.format(tests=str(Path(__file__).parents[1]), out=str(out))
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 240
        rows = 0
        assert proc.stdout is not None
        for line in proc.stdout:  # wait for two evaluated chunks, then interrupt mid-chunk
            rows += " steps " in line
            if rows >= 2 or time.monotonic() > deadline:
                break
        assert rows >= 2
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=60) == 130
    finally:
        proc.kill()
    assert not list(out.glob("*.tmp"))
    learner = make_learner(Drop(), SETTINGS)
    with jax.enable_x64(False):
        saved = load_checkpoint(learner.init(jax.random.PRNGKey(0)), out / "checkpoint.msgpack")
    steps = int(saved.global_step)
    assert steps >= 4096 and steps % 256 == 0
    lines: list[str] = []
    _, ts, curve = train(Drop(), out, steps + 512, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert any("resumed" in line for line in lines)
    assert int(ts.global_step) == steps + 512 and curve[-1]["steps"] == steps + 512


def test_a_new_actor_starts_near_its_initial_action_mean(tmp_path: Path) -> None:
    """``init_output_scale`` shrinks the output layer and ``init_action_mean`` sets its bias: the
    first policy's mean action is about that mean for any observation."""
    settings = PPOSettings(num_envs=16, num_steps=16, num_minibatches=4, hidden=(16, 16),
                           init_output_scale=0.01, init_action_mean=(-0.3,))  # fmt: skip
    learner, ts, _ = train(Drop(), tmp_path, 256, 40, settings, chunk_timesteps=256, log=lambda _: None)
    fresh = make_learner(Drop(), settings)
    from ihrcf_env.rl.jax_ppo import _with_output_layer

    with jax.enable_x64(False):
        ts0 = _with_output_layer(fresh.init(jax.random.PRNGKey(3)), 0.01, (-0.3,))
        act = mean_action_fn(fresh, ts0)
        for obs in np.random.default_rng(2).normal(size=(5, 2)).astype(np.float32):
            assert abs(float(np.asarray(act(obs))[0]) + 0.3) < 0.05
    assert int(ts.global_step) == 256


def test_the_reward_scale_scales_the_critic_targets_only() -> None:
    """An update on rewards ``r`` with ``reward_scale`` k equals one on ``k r`` with scale 1 (the
    critic learns the scaled returns; the actor's advantages are normalised)."""
    import dataclasses

    with jax.enable_x64(False):
        base = make_learner(Drop(), SETTINGS)
        ts = base.init(jax.random.PRNGKey(0))
        rng = np.random.default_rng(0)
        t, n = 8, 16
        traj = Trajectory(
            obs=jax.numpy.asarray(rng.normal(size=(t, n, base.inputs)), jax.numpy.float32),
            action=jax.numpy.asarray(rng.normal(size=(t, n, base.action_dim)), jax.numpy.float32),
            log_prob=jax.numpy.asarray(rng.normal(size=(t, n)), jax.numpy.float32),
            reward=jax.numpy.asarray(rng.normal(size=(t, n)) * 50, jax.numpy.float32),
            value=jax.numpy.zeros((t, n), jax.numpy.float32),
            done=jax.numpy.asarray(rng.random((t, n)) < 0.1),
        )
        last = jax.numpy.asarray(rng.normal(size=(n, base.inputs)), jax.numpy.float32)
        none = jax.numpy.zeros(n, bool)
        scaled = dataclasses.replace(base, reward_scale=0.05, num_minibatches=4)
        plain = dataclasses.replace(base, reward_scale=1.0, num_minibatches=4)
        a = scaled.update(ts, traj, last, none)
        b = plain.update(ts, traj.replace(reward=traj.reward * 0.05), last, none)
        c = plain.update(ts, traj, last, none)
        leaves = [jax.tree_util.tree_leaves(u.critic_ts.params) for u in (a, b, c)]
        for x, y in zip(leaves[0], leaves[1], strict=True):
            np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=1e-5, atol=1e-6)
        moved = [
            float(np.max(np.abs(np.asarray(x) - np.asarray(y))))
            for x, y in zip(leaves[0], leaves[2], strict=True)
        ]
        assert max(moved) > 1e-4  # the scale changes what the critic learns
