"""The vector env over worker processes: the same envs, seeds and results as in one process."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import ihrcf_env
from ihrcf_env.vector.workers import WorkerVectorEnv, merge_infos

V2 = ihrcf_env.LANDING_V2_ID
OPTIONS: dict[str, Any] = {"camera_model": "projected", "level": "calm", "max_episode_steps": 8}


@pytest.fixture
def one_blas_thread() -> Iterator[None]:
    """This process's BLAS on one thread, as the workers' (the last bits of some BLAS products
    depend on the number of threads)."""
    with threadpool_limits(limits=1):
        yield


def test_workers_reproduce_the_one_process_vector_env(
    closing: Callable[[Any], Any], one_blas_thread: None
) -> None:
    """3 envs over 2 workers (2 + 1) against one DeckLandingVectorEnv of 3: observations, rewards,
    flags and info equal bit for bit, through a next-step autoreset."""
    w = closing(gym.make_vec(V2, num_envs=3, workers=2, **OPTIONS))
    v = closing(gym.make_vec(V2, num_envs=3, **OPTIONS))
    assert isinstance(w, WorkerVectorEnv) and w.sizes == [2, 1]
    assert w.observation_space == v.observation_space and w.action_space == v.action_space
    ow, iw = w.reset(seed=40)
    ov, iv = v.reset(seed=40)
    np.testing.assert_array_equal(ow, ov)
    np.testing.assert_array_equal(iw["time"], iv["time"])
    rng = np.random.default_rng(1)
    for _ in range(10):  # beyond the 8-step limit
        a = rng.uniform(-0.5, 0.5, (3, 4)).astype(np.float32)
        rw, rv = w.step(a), v.step(a)
        for x, y in zip(rw[:4], rv[:4], strict=True):
            np.testing.assert_array_equal(x, y)
        _assert_same_info(rw[4], rv[4])


def _assert_same_info(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert sorted(a) == sorted(b)
    for key, value in b.items():
        if isinstance(value, dict):
            _assert_same_info(a[key], value)
        elif value.dtype.kind != "O":
            np.testing.assert_array_equal(a[key], value)
        else:  # objects (strings, dicts): equal one by one
            assert [repr(x) for x in a[key]] == [repr(x) for x in value], key


def test_merging_infos_fills_what_a_part_lacks() -> None:
    a = {
        "x": np.array([1.0, 2.0]),
        "_x": np.array([True, True]),
        "d": {"y": np.array([3, 4]), "_y": np.array([True, False])},
    }
    b = {"z": np.array(["s"], dtype=object), "_z": np.array([True])}
    m = merge_infos([a, b], [2, 1])
    np.testing.assert_array_equal(m["x"], [1.0, 2.0, 0.0])
    np.testing.assert_array_equal(m["_x"], [True, True, False])
    assert list(m["z"]) == [None, None, "s"] and list(m["_z"]) == [False, False, True]
    np.testing.assert_array_equal(m["d"]["y"], [3, 4, 0])
    np.testing.assert_array_equal(m["d"]["_y"], [True, False, False])


def test_merging_infos_keeps_the_shape_of_per_env_arrays() -> None:
    """An episode that ends in one part only (``final_obs`` (n, D) there, absent in the other):
    the other part's envs hold zero rows of the same shape, before or after the part that has it."""
    obs = np.arange(6.0, dtype=np.float32).reshape(2, 3)
    part = {"final_obs": obs, "_final_obs": np.array([True, False])}
    for parts, sizes, rows in (([part, {}], [2, 1], slice(0, 2)), (([{}, part], [1, 2], slice(1, 3)))):
        m = merge_infos(parts, sizes)
        assert m["final_obs"].shape == (3, 3) and m["final_obs"].dtype == np.float32
        np.testing.assert_array_equal(m["final_obs"][rows], obs)
        assert m["_final_obs"].sum() == 1


@pytest.mark.parametrize(
    ("workers", "error"), [(0, ValueError), (5, ValueError), (1.5, TypeError), ("2", TypeError)]
)
def test_bad_workers_are_refused_by_name(workers: Any, error: type[Exception]) -> None:
    with pytest.raises(error, match="workers"):
        gym.make_vec(V2, num_envs=4, workers=workers, **OPTIONS)


def test_bad_actions_and_a_closed_env_are_named(closing: Callable[[Any], Any]) -> None:
    w = closing(gym.make_vec(V2, num_envs=2, workers=2, **OPTIONS))
    w.reset(seed=0)
    with pytest.raises(ValueError, match="actions"):
        w.step(np.zeros((3, 4)))
    w.close()
    with pytest.raises(RuntimeError, match="closed"):
        w.step(np.zeros((2, 4)))
