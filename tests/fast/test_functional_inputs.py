"""The functional API's edges: ``make_params`` takes float32 or float64 only; bad keys, actions and
states are refused at trace time with errors naming them; a non-finite action ends the episode
with a finite state (float64)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.config.make import make_config
from ihrcf_env.fast import step as fs
from ihrcf_env.fast.params import MAX_STEPS, make_params
from ihrcf_env.tasks import is_crash

CONFIG = make_config(
    task="landing-v2", level="moderate", camera_model="projected", camera_output="corners", raw=True
)
PARAMS = make_params(CONFIG)
KEY = jax.random.PRNGKey(0)


@pytest.mark.parametrize("dtype", [jnp.float16, np.int32, bool, None, "float16", "complex64", object])
def test_make_params_takes_float32_or_float64_only(dtype: object) -> None:
    with pytest.raises(TypeError, match="dtype must be float32 or float64"):
        make_params(CONFIG, dtype=dtype)


@pytest.mark.parametrize("dtype", [jnp.float32, np.float64, "float32", np.dtype("float64")])
def test_the_float_types_in_any_spelling(dtype: object) -> None:
    assert make_params(CONFIG, dtype=dtype).dtype == np.dtype(dtype)


def test_max_steps_is_bounded() -> None:
    with pytest.raises(ValueError, match=f"max_steps must be an int in \\[1, {MAX_STEPS}\\]"):
        make_params(CONFIG, max_steps=10**12)


def _state(params: object) -> object:
    return jax.eval_shape(lambda k: fs.reset(k, params)[1], KEY)  # type: ignore[arg-type]


def _step(key: object, state: object, action: object, params: object = PARAMS) -> object:
    """``fs.step`` traced (not compiled) with ``state`` given as shapes."""
    return jax.eval_shape(lambda s: fs.step(key, s, action, params), state)  # type: ignore[arg-type]


def test_keys_actions_and_states_are_named_at_trace_time() -> None:
    state = _state(PARAMS)
    _step(KEY, state, jnp.zeros(4))  # the good call traces
    for key in (None, "k", 3):
        with pytest.raises(TypeError, match="key must be a jax.random key"):
            _step(key, state, jnp.zeros(4))
    for action in (None, "up", object()):
        with pytest.raises(TypeError, match="action must be 4 real numbers"):
            _step(KEY, state, action)
    with pytest.raises(
        ValueError, match=r"state\.flight.*float32.*expected float64.*params' dtype is float64"
    ):
        _step(KEY, _state(make_params(CONFIG, dtype=jnp.float32)), jnp.zeros(4))
    other = make_params(make_config(task="landing-v2", level="moderate", camera_model="projected",
                                    camera_output="corners", raw=True, camera_latency=0.1))  # fmt: skip
    with pytest.raises(ValueError, match=r"state\.pipe"):
        _step(KEY, _state(other), jnp.zeros(4))


@pytest.fixture(scope="module")
def compiled() -> tuple[Any, Any]:
    """The reset's state and the compiled step (one compilation for the module)."""
    _, state = jax.jit(lambda k: fs.reset(k, PARAMS))(KEY)
    return state, jax.jit(lambda k, s, a: fs.step_env(k, s, a, PARAMS))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_action_ends_the_episode_with_a_finite_state(
    compiled: tuple[Any, Any], bad: float
) -> None:
    state, step = compiled
    action = jnp.array([0.0, bad, -0.5, 0.0])
    obs, new, reward, done, info = step(KEY, state, action)
    leaves = [np.asarray(x) for x in jax.tree_util.tree_leaves(new)]
    assert all(np.isfinite(x).all() for x in leaves if x.dtype.kind == "f")
    assert np.isfinite(np.asarray(obs)).all() and np.isfinite(float(reward))
    assert bool(done) and int(info.outcome) == fs.INVALID_ACTION and bool(is_crash(info.outcome))
    assert all(np.isfinite(float(t)) for t in info.terms)
    # the zero command was flown: the same step as a zero action, but ended
    _, new0, _, done0, info0 = step(KEY, state, jnp.zeros(4))
    np.testing.assert_allclose(np.asarray(new.flight.drone.position), np.asarray(new0.flight.drone.position))
    assert not bool(done0) and int(info0.outcome) == 0
