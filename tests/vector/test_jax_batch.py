"""map_envs: the vmapped function computed in chunks of envs; reset_ended and autoreset_step:
only the rows that ended are reset."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

jax = pytest.importorskip("jax")

from functional_toy import Drop  # noqa: E402

from ihrcf_env.vector.jax_batch import autoreset_step, map_envs, reset_ended  # noqa: E402


@pytest.mark.parametrize("n, chunk", [(5, 8), (16, 4), (19, 4)])
def test_chunks_give_the_vmapped_result(n: int, chunk: int) -> None:
    fenv = Drop()
    keys = jax.random.split(jax.random.PRNGKey(3), n)
    _, state = jax.vmap(lambda k: fenv.reset_from(fenv.draw(k, fenv.params), k, fenv.params))(keys)
    actions = jax.numpy.linspace(-1.0, 1.0, n)[:, None]
    step = lambda k, s, a: fenv.step(k, s, a, fenv.params)  # noqa: E731
    want = jax.vmap(step)(keys, state, actions)
    got = map_envs(step, keys, state, actions, chunk=chunk)
    for a, b in zip(jax.tree_util.tree_leaves(want), jax.tree_util.tree_leaves(got), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_bad_chunk_is_refused() -> None:
    with pytest.raises(ValueError, match="chunk"):
        map_envs(lambda x: x, jax.numpy.zeros(3), chunk=0)


def _reset_one(fenv: Drop, key: Any) -> Any:
    k1, k2 = jax.random.split(key)
    return fenv.reset_from(fenv.draw(k1, fenv.params), k2, fenv.params)


@pytest.mark.parametrize("n, block", [(7, 3), (16, 16), (16, 4), (5, 8)])
def test_reset_ended_replaces_exactly_the_ended_rows(n: int, block: int) -> None:
    fenv = Drop()
    batch = {"h": -jax.numpy.arange(n, dtype=jax.numpy.float32), "v": jax.numpy.ones(n)}
    ended = jax.numpy.asarray(np.arange(n) % 3 != 1)  # more ended rows than one block holds
    fresh = lambda k: _reset_one(fenv, k)[1]  # noqa: E731
    keys = jax.random.split(jax.random.PRNGKey(0), n)
    out = jax.jit(
        lambda k, b, e: reset_ended(
            lambda kk: {"h": fresh(kk)["h"], "v": fresh(kk)["v"]}, k, b, e, block=block
        )
    )(keys, batch, ended)
    h, v = np.asarray(out["h"]), np.asarray(out["v"])
    e = np.asarray(ended)
    np.testing.assert_array_equal(h[~e], np.asarray(batch["h"])[~e])
    np.testing.assert_array_equal(v[~e], 1.0)
    assert np.all((h[e] >= 1.0) & (h[e] <= 2.0)) and np.all(v[e] == 0.0)  # a new draw: height in [1, 2]
    assert len(np.unique(h[e])) == e.sum()  # every ended row its own draw
    # the row's own key, whether the ended rows fit one block or took several
    want = np.array([float(fresh(keys[i])["h"]) for i in np.flatnonzero(e)])
    np.testing.assert_allclose(h[e], want, rtol=1e-6)


def test_reset_ended_with_nothing_ended_is_the_identity() -> None:
    batch = jax.numpy.arange(6.0)
    keys = jax.random.split(jax.random.PRNGKey(1), 6)
    out = reset_ended(lambda k: jax.random.uniform(k), keys, batch, jax.numpy.zeros(6, bool))
    np.testing.assert_array_equal(np.asarray(out), np.arange(6.0))


def test_autoreset_step_resets_the_done_envs_in_the_same_step() -> None:
    fenv = Drop()
    n = 9
    keys = jax.random.split(jax.random.PRNGKey(2), n)
    _, state = jax.vmap(lambda k: _reset_one(fenv, k))(keys)
    state = {**state, "h": state["h"].at[::2].set(0.01)}  # these fall through the floor this step
    actions = jax.numpy.zeros((n, 1))
    step = lambda k, s, a: fenv.step(k, s, a, fenv.params)  # noqa: E731
    obs, new, reward, done, info = jax.jit(
        lambda k, s, a: autoreset_step(step, lambda kk: _reset_one(fenv, kk), k, s, a, chunk=4, block=2)
    )(keys, state, actions)
    d = np.asarray(done)
    np.testing.assert_array_equal(d, np.arange(n) % 2 == 0)
    _, plain, want_reward, _, _ = jax.vmap(step)(jax.vmap(jax.random.split)(keys)[:, 0], state, actions)
    np.testing.assert_allclose(
        np.asarray(reward), np.asarray(want_reward)
    )  # the step's reward, also when done
    np.testing.assert_allclose(np.asarray(new["h"])[~d], np.asarray(plain["h"])[~d])
    assert np.all(np.asarray(new["h"])[d] >= 1.0) and np.all(np.asarray(new["v"])[d] == 0.0)
    np.testing.assert_allclose(np.asarray(obs)[d, 0], np.asarray(new["h"])[d])  # first obs of the new episode


def test_bad_block_is_refused() -> None:
    with pytest.raises(ValueError, match="block"):
        reset_ended(
            lambda k: k,
            jax.random.split(jax.random.PRNGKey(0), 3),
            jax.numpy.zeros(3),
            jax.numpy.zeros(3, bool),
            block=0,
        )


def test_reset_ended_traces_the_reset_once() -> None:
    """One traced copy of the reset however many blocks the batch has: compiling a batched step
    costs one reset."""
    calls = []

    def reset_one(k: Any) -> Any:
        calls.append(1)
        return jax.random.uniform(k)

    keys = jax.random.split(jax.random.PRNGKey(1), 40)
    jax.jit(lambda k, b, e: reset_ended(reset_one, k, b, e, block=4)).lower(
        keys, jax.numpy.zeros(40), jax.numpy.ones(40, bool)
    )
    assert len(calls) <= 2  # eval_shape of the block's results, and the block itself


def test_force_reset_resets_every_env_and_finish_observes_after_the_resets() -> None:
    fenv = Drop()
    n = 6
    keys = jax.random.split(jax.random.PRNGKey(5), n)
    _, state = jax.vmap(lambda k: _reset_one(fenv, k))(keys)
    actions = jax.numpy.zeros((n, 1))
    step = lambda k, s, a: fenv.step(k, s, a, fenv.params)  # noqa: E731
    force = jax.numpy.asarray([True, False] * 3)

    def finish(obs: Any, s: Any) -> Any:
        return obs * 2.0, s

    obs, new, _, done, _ = jax.jit(
        lambda k, s, a, f: autoreset_step(
            step, lambda kk: _reset_one(fenv, kk), k, s, a, force_reset=f, finish=finish, chunk=4, block=2
        )
    )(keys, state, actions, force)
    f = np.asarray(force)
    reset_keys = jax.vmap(jax.random.split)(keys)[:, 1]
    for i in np.flatnonzero(f):  # a forced env starts the episode of its own reset key
        want_obs, want_state = _reset_one(fenv, reset_keys[i])
        np.testing.assert_allclose(np.asarray(new["h"])[i], float(want_state["h"]), rtol=1e-6)
        np.testing.assert_allclose(np.asarray(obs)[i], 2.0 * np.asarray(want_obs), rtol=1e-6)
    _, plain, _, _, _ = jax.vmap(step)(jax.vmap(jax.random.split)(keys)[:, 0], state, actions)
    np.testing.assert_allclose(np.asarray(new["h"])[~f], np.asarray(plain["h"])[~f], rtol=1e-6)
