"""The JAX vector env's front (autoreset, seeding, checks, masks) over a small functional env."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

jax = pytest.importorskip("jax")
jnp = jax.numpy

from functional_toy import Drop  # noqa: E402

from ihrcf_env.vector.jax_env import RESET_ROWS, JaxVectorEnv, reset_size  # noqa: E402

ID = "ihrcf_env/DeckLanding-v2"  # for its spec only (the step limit is overridden)


def make(n: int = 4, **kw: Any) -> JaxVectorEnv:
    return JaxVectorEnv(ID, Drop(), num_envs=n, **kw)


def test_paired_seeds_give_the_host_draws() -> None:
    env = make(3)
    obs, _ = env.reset(seed=7)
    for i in range(3):
        rng = gym.utils.seeding.np_random(7 + i)[0]
        _, ep = Drop().draw_host(rng)
        assert obs[i, 0] == np.float32(ep["height"])


def test_deterministic_for_a_seed_and_independent_of_num_envs() -> None:
    a, b = make(2), make(5)
    oa, _ = a.reset(seed=3)
    ob, _ = b.reset(seed=3)
    np.testing.assert_array_equal(oa, ob[:2])
    for _ in range(4):
        ra = a.step(np.zeros((2, 1)))
        rb = b.step(np.zeros((5, 1)))
        np.testing.assert_array_equal(ra[0], rb[0][:2])
        np.testing.assert_array_equal(ra[4]["noise"], rb[4]["noise"][:2])


def test_next_step_autoreset() -> None:
    env = make(2, seeding="paired")
    env.reset(seed=0)
    ended = False
    for _ in range(40):
        obs, rew, term, trunc, info = env.step(-np.ones((2, 1)))
        if ended:  # the step after the end: a new episode, reward 0
            assert rew[0] == 0.0 and not term[0] and not info["_height"][0]
            assert 1.0 <= obs[0, 0] <= 2.0 and obs[0, 1] == 0.0
            break
        ended = bool(term[0])
    else:
        pytest.fail("env 0 never ended")


def test_same_step_autoreset_and_final_obs() -> None:
    env = make(2, autoreset_mode=AutoresetMode.SAME_STEP)
    env.reset(seed=0)
    for _ in range(40):
        obs, rew, term, trunc, info = env.step(-np.ones((2, 1)))
        if term[0]:
            assert info["_final_obs"][0] and info["final_obs"][0][0] < 0.0
            assert 1.0 <= obs[0, 0] <= 2.0
            return
    pytest.fail("env 0 never ended")


def test_truncation_by_the_step_limit() -> None:
    env = make(2, max_episode_steps=3)
    env.reset(seed=0)
    out = [env.step(np.ones((2, 1))) for _ in range(4)]
    assert [bool(o[3][0]) for o in out] == [False, False, True, False]
    assert out[3][1][0] == 0.0  # the reset step


def test_jax_seeding_draws_fresh_episodes_without_the_host() -> None:
    env = make(4, seeding="jax", max_episode_steps=2)
    env.reset(seed=0)
    assert env.fenv.host_draws == 0  # type: ignore[attr-defined]
    starts = set()
    for _ in range(9):
        obs, *_ = env.step(np.zeros((4, 1)))
        starts.update(np.round(obs[:, 0], 6)[obs[:, 1] == 0.0].tolist())
    assert len(starts) >= 8  # every reset a new draw, never a cached first state


def test_reset_mask_resets_only_the_marked_envs() -> None:
    env = make(3)
    o0, _ = env.reset(seed=0)
    env.step(np.zeros((3, 1)))
    o1, _ = env.reset(options={"reset_mask": np.array([False, True, False])})
    assert o1[1, 1] == 0.0 and o1[0, 1] != 0.0 and o1[2, 1] != 0.0


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match="num_envs"):
        make(0)
    with pytest.raises(ValueError, match="seeding"):
        make(2, seeding="x")
    with pytest.raises(ValueError, match="dtype"):
        make(2, dtype="float16")
    env = make(2)
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros((2, 1)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="actions"):
        env.step(np.zeros((3, 1)))
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.array([[0.0], [np.nan]]))
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"altitude": 1.0})
    env.close()
    with pytest.raises(RuntimeError, match="closed"):
        env.step(np.zeros((2, 1)))


def test_every_reset_shares_one_compiled_function() -> None:
    """The first reset, a masked reset, a later full reset and the autoresets: one trace (one
    compilation) of the reset when num_envs <= RESET_ROWS; the step traces once."""
    assert [reset_size(k, 4) for k in (1, 3, 4)] == [4, 4, 4]
    assert [reset_size(k, 64) for k in (1, RESET_ROWS, RESET_ROWS + 1, 64)] == [16, 16, 16, 16]
    env = make(4, max_episode_steps=2)
    env.reset(seed=0)
    env.step(np.zeros((4, 1)))
    env.reset(options={"reset_mask": np.array([False, True, False, False])})
    env.reset(seed=5)
    for _ in range(5):  # autoresets of every env
        env.step(np.zeros((4, 1)))
    assert env.reset_traces == 1
    assert env._reset_fn._cache_size() == 1  # type: ignore[attr-defined]
    assert env._step_fn._cache_size() == 1  # type: ignore[attr-defined]


def test_many_envs_reset_in_one_shape() -> None:
    """More envs than a block: every reset (the first, a masked one, the autoresets of all) runs
    the block of RESET_ROWS rows as often as it takes, and the rows get the episodes of their seeds."""
    n = 2 * RESET_ROWS + 4
    env = make(n, max_episode_steps=1)
    obs, info = env.reset(seed=0)
    env.reset(options={"reset_mask": np.arange(n) < 3})
    for _ in range(3):
        env.step(np.zeros((n, 1)))
    assert env.reset_traces == 1
    assert env._reset_fn._cache_size() == 1  # type: ignore[attr-defined]
    # the rows of the last block get their own seeds' episodes, as with one env each
    for i in (0, RESET_ROWS, n - 1):
        one = make(1, max_episode_steps=1)
        first, _ = one.reset(seed=i)
        np.testing.assert_array_equal(first[0], obs[i])
        one.close()
