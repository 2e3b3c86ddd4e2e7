"""The vector envs' partial reset (``options["reset_mask"]``, Gymnasium 1.1+): only the marked envs
start a new episode, each as the single env of its seed; the others go on untouched. And their
partial step (``step_masked(actions, mask)``): the envs left out are paused (not stepped, not
autoreset) and go on afterwards as if they had not been, bit for bit."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "calm"}


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(-0.5, 0.5, (n, 4)).astype(np.float32)


def _both_ended(closing: Callable[[Any], Any]) -> tuple[Any, np.ndarray]:
    """A vector env of 2 envs (time limit 3) whose episodes have both just ended, and zero actions."""
    v = closing(gym.make_vec(V2, num_envs=2, max_episode_steps=3, **OPTIONS))
    v.reset(seed=0)
    zero = np.zeros((2, 4), np.float32)
    for _ in range(3):
        _, _, _, truncated, _ = v.step(zero)
    assert truncated.all()
    return v, zero


@pytest.mark.parametrize("workers", [None, 2])
def test_masked_envs_restart_as_the_single_env_of_their_seed(
    closing: Callable[[Any], Any], make_env: Callable[..., gym.Env], workers: int | None
) -> None:
    """3 envs; after 4 steps env 1 is reset with seed 77 (a sequence of seeds, the others None):
    env 1 then follows the single env of seed 77 and envs 0 and 2 their own episodes (seeds 10, 12),
    bit for bit; the reset's info covers env 1 only."""
    extra = {} if workers is None else {"workers": workers}
    v = closing(gym.make_vec(V2, num_envs=3, **OPTIONS, **extra))
    singles = [make_env(V2, **OPTIONS) for _ in range(4)]
    obs, _ = v.reset(seed=10)
    s_obs = [e.reset(seed=10 + i)[0] for i, e in enumerate(singles[:3])]
    rng = np.random.default_rng(0)
    for _ in range(4):
        a = _actions(rng, 3)
        obs, *_ = v.step(a)
        s_obs = [e.step(a[i])[0] for i, e in enumerate(singles[:3])]
    before = obs.copy()
    mask = np.array([False, True, False])
    obs, info = v.reset(seed=[None, 77, None], options={"reset_mask": mask})
    s_obs[1], s_info = singles[3].reset(seed=77)
    live = [singles[0], singles[3], singles[2]]
    np.testing.assert_array_equal(obs[[0, 2]], before[[0, 2]])
    np.testing.assert_array_equal(obs[1], s_obs[1])
    assert info["_time"].tolist() == [False, True, False] and info["time"][1] == s_info["time"]
    for _ in range(5):
        a = _actions(rng, 3)
        obs, reward, *_ = v.step(a)
        for i, e in enumerate(live):
            o, r, *_ = e.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert reward[i] == r


def test_an_ended_env_reset_by_mask_is_not_reset_again(closing: Callable[[Any], Any]) -> None:
    """Next-step autoreset: an env whose episode ended and is reset by mask steps normally at the
    next step (no second reset, a reward that is not the autoreset's 0)."""
    v, zero = _both_ended(closing)
    first, _ = v.reset(seed=[5, None], options={"reset_mask": np.array([True, False])})
    obs, reward, _, truncated, _ = v.step(zero)
    assert reward[0] != 0.0 and not truncated[0]
    assert reward[1] == 0.0  # env 1 takes its next-step autoreset
    assert not np.array_equal(obs[0], first[0])


@pytest.mark.parametrize(
    ("mask", "error"),
    [
        ([True, False], TypeError),  # a list, not an array
        (np.array([1, 0]), TypeError),  # not bool
        (np.array([True, False, True]), ValueError),  # the wrong length
        (np.array([False, False]), ValueError),  # marks nothing
    ],
)
def test_bad_masks_are_named(closing: Callable[[Any], Any], mask: Any, error: type[Exception]) -> None:
    v = closing(gym.make_vec(V2, num_envs=2, **OPTIONS))
    v.reset(seed=0)
    with pytest.raises(error, match=r"reset_mask"):
        v.reset(options={"reset_mask": mask})


def test_a_partial_reset_needs_a_full_one_first(closing: Callable[[Any], Any]) -> None:
    v = closing(gym.make_vec(V2, num_envs=2, **OPTIONS))
    with pytest.raises(gym.error.ResetNeeded, match="reset_mask"):
        v.reset(options={"reset_mask": np.array([True, False])})


@pytest.mark.parametrize("workers", [None, 2])
def test_a_paused_env_goes_on_as_the_single_env(
    closing: Callable[[Any], Any], make_env: Callable[..., gym.Env], workers: int | None
) -> None:
    """3 envs; env 1 is paused for 4 of 10 steps: meanwhile its row keeps its last observation,
    reward 0 and no info; every env then equals the single env of its seed stepped with the actions
    of the steps it took, bit for bit."""
    extra = {} if workers is None else {"workers": workers}
    v = closing(gym.make_vec(V2, num_envs=3, **OPTIONS, **extra))
    singles = [make_env(V2, **OPTIONS) for _ in range(3)]
    held = v.reset(seed=20)[0][1].copy()
    for i, e in enumerate(singles):
        e.reset(seed=20 + i)
    rng = np.random.default_rng(1)
    paused = np.array([True, False, True])
    for k in range(10):
        a = _actions(rng, 3)
        if 3 <= k < 7:
            obs, reward, terminated, truncated, info = v.step_masked(a, paused)
            assert reward[1] == 0.0 and not terminated[1] and not truncated[1]
            assert not info["_time"][1] and info["_time"][[0, 2]].all()
            np.testing.assert_array_equal(obs[1], held)
            live = [0, 2]
        else:
            obs, reward, *_ = v.step(a)
            live = [0, 1, 2]
        held = obs[1].copy()
        for i in live:
            o, r, *_ = singles[i].step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert reward[i] == r


def test_a_pending_autoreset_waits_for_the_env_s_next_step(closing: Callable[[Any], Any]) -> None:
    """Next-step autoreset: an env whose episode ended and is then paused is reset by the first step
    that includes it (reward 0), not by the masked steps."""
    v, zero = _both_ended(closing)
    last, *_ = v.step_masked(zero, np.array([False, True]))  # env 1 takes its autoreset
    obs, reward, _, truncated, _ = v.step_masked(zero, np.array([False, True]))
    assert reward[1] != 0.0 and not truncated[1]
    np.testing.assert_array_equal(obs[0], last[0])
    obs, reward, *_ = v.step(zero)
    assert reward[0] == 0.0  # env 0's autoreset, kept while it was paused
    assert reward[1] != 0.0


@pytest.mark.parametrize(
    ("mask", "error"),
    [
        ([True, False], TypeError),
        (np.array([1, 0]), TypeError),
        (np.array([True, False, True]), ValueError),
        (np.array([False, False]), ValueError),
    ],
)
def test_bad_step_masks_are_named(closing: Callable[[Any], Any], mask: Any, error: type[Exception]) -> None:
    v = closing(gym.make_vec(V2, num_envs=2, **OPTIONS))
    v.reset(seed=0)
    with pytest.raises(error, match=r"mask"):
        v.step_masked(np.zeros((2, 4), np.float32), mask)
