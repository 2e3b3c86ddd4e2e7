"""The env batch spread over devices: the same results as on one device, bit for bit; bad device
counts named."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("jax")

from ihrcf_env.vector.jax_devices import check_devices, host_cores  # noqa: E402

TESTS = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    from ihrcf_env.vector.jax_devices import env_mesh, request_host_devices
    assert request_host_devices(2) == 2
    import jax, jax.numpy as jnp, numpy as np
    from functional_toy import Drop
    from ihrcf_env.vector.jax_rollout import batch_step, placeholder_state

    fenv = Drop()
    n = 8
    one = jax.jit(batch_step(fenv, 30, chunk=2, block=2))
    two = jax.jit(batch_step(fenv, 30, mesh=env_mesh(2), chunk=2, block=2))
    outs = []
    ends = 0
    for step in (one, two):
        state = placeholder_state(fenv, n)
        key = jax.random.PRNGKey(4)
        force = jnp.ones(n, bool)
        trace = []
        for t in range(40):  # several episodes: ends and resets at different steps per env
            key, k1, k2 = jax.random.split(key, 3)
            actions = jax.random.uniform(k1, (n, 1), minval=-1.0, maxval=1.0)
            obs, state, reward, done, success = step(jax.random.split(k2, n), state, actions, force)
            force = jnp.zeros(n, bool)
            ends += int(np.asarray(done).sum())
            leaves = jax.tree_util.tree_leaves((obs, state, reward, done, success))
            trace.append([np.asarray(x) for x in leaves])
        outs.append(trace)
    sharded = two(jax.random.split(key, n), state, jnp.zeros((n, 1)), force)[0]
    assert len(sharded.sharding.device_set) == 2, sharded.sharding
    for a, b in zip(*outs):
        for x, y in zip(a, b):
            assert x.dtype == y.dtype and x.shape == y.shape
            assert x.tobytes() == y.tobytes()
    assert ends >= 8, ends  # counted over both runs
    print("identical", ends)
    """
)


def test_the_sharded_batch_steps_bit_identically_to_one_device() -> None:
    """Eight envs over two CPU devices (a fresh interpreter: the device count is fixed when JAX
    starts) against one device: every observation, state, reward and flag identical over 40 steps
    with episode ends and resets."""
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT.format(tests=str(TESTS))],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert "identical" in out.stdout


VECTOR_SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    from ihrcf_env.vector.jax_devices import request_host_devices
    assert request_host_devices(2) == 2
    import numpy as np
    from functional_toy import Drop
    from ihrcf_env.vector.jax_env import JaxVectorEnv

    runs = []
    for devices in (1, 2):
        env = JaxVectorEnv(
            "ihrcf_env/DeckLanding-v2", Drop(), num_envs=6, devices=devices, max_episode_steps=25
        )
        assert env.devices == devices
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(0)
        trace = [obs]
        for _ in range(30):
            obs, reward, term, trunc, _ = env.step(rng.uniform(-1, 1, (6, 1)))
            trace += [obs, reward, term, trunc]
        runs.append(trace)
        env.close()
    for a, b in zip(*runs):
        assert np.asarray(a).tobytes() == np.asarray(b).tobytes()
    print("identical")
    """
)


def test_the_vector_env_over_two_devices_steps_as_on_one() -> None:
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    code = VECTOR_SCRIPT.format(tests=str(TESTS))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "identical" in out.stdout


def test_device_counts_are_checked_by_name() -> None:
    import jax

    have = len(jax.devices())
    assert check_devices(None, 8 * have) == have
    assert check_devices(1, 7) == 1
    for bad in (0, -1, 2.0, True, "2"):
        with pytest.raises(ValueError, match="devices"):
            check_devices(bad, 8)
    with pytest.raises(ValueError, match=f"devices={have + 1}"):
        check_devices(have + 1, 8 * (have + 1))
    if have > 1:
        with pytest.raises(ValueError, match="does not split"):
            check_devices(have, have * 3 + 1)


def test_a_request_beyond_the_cores_is_refused() -> None:
    from ihrcf_env.vector.jax_devices import request_host_devices

    with pytest.raises(ValueError, match=f"devices={host_cores() + 1}"):
        request_host_devices(host_cores() + 1)


def test_host_cores_are_those_the_process_may_use() -> None:
    assert 1 <= host_cores() <= (os.cpu_count() or 1)
    if hasattr(os, "sched_getaffinity"):
        assert host_cores() == len(os.sched_getaffinity(0))


TRAINER_SCRIPT = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    from ihrcf_env.vector.jax_devices import request_host_devices
    assert request_host_devices(2) == 2
    import jax, jax.numpy as jnp, numpy as np
    from functional_toy import Drop
    from ihrcf_env.rl import jax_ppo as jp

    outs = []
    for devices in (1, 2):
        s = jp.PPOSettings(num_envs=8, num_steps=4, num_minibatches=2, hidden=(16, 16), devices=devices)
        fenv = Drop()
        learner = jp.make_learner(fenv, s)
        c, mesh = jp._compile(fenv, learner, s, 20)
        ts = jax.device_put(learner.init(jax.random.PRNGKey(0)), c.whole)
        ones = jax.device_put(jnp.ones(8, jnp.float32), c.rows)
        run = jp._reset(c, ts, 8, jax.device_put(jax.random.PRNGKey(1), c.whole), ones)
        force = jax.device_put(jnp.zeros(8, bool), c.rows)
        det = jax.device_put(jnp.asarray(False), c.whole)
        trace = []
        for t in range(30):
            k = jax.device_put(jax.random.PRNGKey(100 + t), c.whole)
            run, traj, ok = c.transition(ts, run, k, force, det, c.ids, ones)
            trace += [np.asarray(x) for x in jax.tree_util.tree_leaves((run, traj, ok))]
        outs.append(trace)
    for a, b in zip(*outs):
        assert a.dtype == b.dtype and a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    print("close")
    """
)


@pytest.mark.rl
def test_the_trainer_steps_its_envs_over_two_devices_as_on_one() -> None:
    """PPO's transition (the policy's actions, the envs' steps and resets) over two devices gives
    the one-device result to float32 rounding: the env step is the same bit for bit (above), but
    XLA's CPU matrix products (the networks) may round the last bit differently for another
    number of rows per device."""
    pytest.importorskip("rejax")
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    code = TRAINER_SCRIPT.format(tests=str(TESTS))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "close" in out.stdout
