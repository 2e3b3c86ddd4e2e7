"""The vector envs' partial reset (``options["reset_mask"]``, Gymnasium 1.1+): only the marked envs
start a new episode, each as the single env of its seed; the others go on untouched."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "calm", "physics": "numpy"}


def _actions(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.uniform(-0.5, 0.5, (n, 4)).astype(np.float32)


@pytest.mark.parametrize(("workers", "batch"), [(None, False), (None, True), (2, True)])
def test_masked_envs_restart_as_the_single_env_of_their_seed(
    closing: Callable[[Any], Any], make_env: Callable[..., gym.Env], workers: int | None, batch: bool
) -> None:
    """3 envs; after 4 steps env 1 is reset with seed 77 (a sequence of seeds, the others None):
    env 1 then follows the single env of seed 77 and envs 0 and 2 their own episodes (seeds 10, 12),
    bit for bit; the reset's info covers env 1 only."""
    extra = {} if workers is None else {"workers": workers}
    v = closing(gym.make_vec(V2, num_envs=3, batch_estimators=batch, **OPTIONS, **extra))
    singles = [make_env(V2, batch_estimators=batch, **OPTIONS) for _ in range(4)]
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
    v = closing(gym.make_vec(V2, num_envs=2, max_episode_steps=3, **OPTIONS))
    v.reset(seed=0)
    zero = np.zeros((2, 4), np.float32)
    for _ in range(3):
        _, _, _, truncated, _ = v.step(zero)
    assert truncated.all()
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
