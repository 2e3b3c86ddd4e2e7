"""The JAX landing step's functional API (ihrcf_env.fast.step): compiled once for new values,
deterministic for a key, an auto-reset at the episode's end, and bad arguments named at trace
time (float64)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.config.make import make_config
from ihrcf_env.fast import step as fs
from ihrcf_env.fast.params import make_params

N = 2
PARAMS = make_params(
    make_config(
        task="landing-v2", level="moderate", camera_model="projected", camera_output="corners", raw=True
    )
)


class _Traced:
    def __init__(self) -> None:
        self.traces = 0

        def reset(keys: Any) -> Any:
            return jax.vmap(lambda k: fs.reset(k, PARAMS))(keys)

        def step(keys: Any, state: Any, actions: Any) -> Any:
            self.traces += 1
            return jax.vmap(lambda k, s, a: fs.step(k, s, a, PARAMS))(keys, state, actions)

        self.reset = jax.jit(reset)
        self.step = jax.jit(step)


@pytest.fixture(scope="module")
def fns() -> _Traced:
    return _Traced()


def _run(fns: _Traced, seed: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    key = jax.random.PRNGKey(seed)
    obs, st = fns.reset(jax.random.split(key, N))
    rewards = []
    for k in range(steps):
        key, sub = jax.random.split(key)
        a = jnp.tile(jnp.array([0.1 * k % 1.0, -0.2, -0.4, 0.05]), (N, 1))
        obs, st, r, done, info = fns.step(jax.random.split(sub, N), st, a)
        rewards.append(np.asarray(r))
    return np.asarray(obs), np.array(rewards)


@pytest.mark.slow
def test_compiled_once_and_deterministic(fns: _Traced) -> None:
    obs_a, rew_a = _run(fns, 0, 3)
    obs_b, rew_b = _run(fns, 0, 3)
    obs_c, _ = _run(fns, 1, 3)
    assert fns.traces == 1  # new keys, states and actions: no retrace
    assert np.array_equal(obs_a, obs_b) and np.array_equal(rew_a, rew_b)
    assert not np.array_equal(obs_a, obs_c)
    assert np.isfinite(obs_a).all() and obs_a.shape == (N, 34)


def test_bad_arguments_are_named() -> None:
    key = jax.random.PRNGKey(0)
    with pytest.raises(TypeError, match="params"):
        fs.reset(key, object())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="key"):
        fs.reset(jnp.zeros(3), PARAMS)
    _, st = jax.jit(fs.reset, static_argnums=1)(key, PARAMS)
    with pytest.raises(ValueError, match="action"):
        jax.eval_shape(lambda s: fs.step(key, s, jnp.zeros(3), PARAMS), st)
    with pytest.raises(TypeError, match="state"):
        fs.step(key, (1, 2), jnp.zeros(4), PARAMS)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="camera_model"):
        make_params(make_config(task="landing-v2", raw=True))
    with pytest.raises(ValueError, match="max_steps"):
        make_params(PARAMS.config, max_steps=0)
