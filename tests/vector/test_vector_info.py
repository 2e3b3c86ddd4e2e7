"""``stack_infos`` builds the same vector ``info`` as Gymnasium's per-env ``VectorEnv._add_info``."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import VectorEnv

import ihrcf_env
from ihrcf_env.vector.info import stack_infos


class _Ref(VectorEnv):
    def __init__(self, n: int) -> None:
        self.num_envs = n


def reference(infos: list[dict[str, Any] | None]) -> dict[str, Any]:
    ref = _Ref(len(infos))
    out: dict[str, Any] = {}
    for i, info in enumerate(infos):
        if info:
            out = ref._add_info(out, info, i)
    return out


def assert_same(a: dict[str, Any], b: dict[str, Any]) -> None:
    assert list(a) == list(b)
    for key in a:
        x, y = a[key], b[key]
        if isinstance(x, dict):
            assert isinstance(y, dict)
            assert_same(x, y)
            continue
        assert isinstance(y, np.ndarray) and x.dtype == y.dtype and x.shape == y.shape, key
        if x.dtype.kind == "O":
            for u, v in zip(x.tolist(), y.tolist(), strict=True):
                if isinstance(u, np.ndarray):
                    assert np.array_equal(u, v)
                else:
                    assert u == v, key
        else:
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), key


def test_mixed_keys_types_and_missing_envs() -> None:
    infos: list[dict[str, Any] | None] = [
        {"a": 1.5, "b": True, "s": "x", "v": np.arange(3.0), "nest": {"k": 2, "t": (1, 2)}},
        None,
        {"b": False, "c": np.float32(0.25), "a": 2, "nest": {"k": 7}},
        {"final_obs": np.ones(2), "final_info": {"a": 0.5}, "s": None, "v": np.ones(3), "n": np.int64(4)},
        {},
    ]
    got, want = stack_infos(infos), reference(infos)
    assert_same(got, want)
    assert got["a"].dtype == np.float64 and got["_a"].tolist() == [True, False, True, False, False]
    assert got["final_obs"].dtype == object


def test_trailing_envs_and_bad_length() -> None:
    assert_same(stack_infos([{"a": 1.0}], 3), reference([{"a": 1.0}, None, None]))
    with pytest.raises(ValueError, match="infos"):
        stack_infos([{}, {}], 1)


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
def test_the_landing_vector_env_info_equals_the_reference(mode: str) -> None:
    n = 3
    env = gym.make_vec(ihrcf_env.LANDING_V1_ID, num_envs=n, camera_model="projected", autoreset_mode=mode)
    singles = [gym.make(ihrcf_env.LANDING_V1_ID, camera_model="projected") for _ in range(n)]
    try:
        _, info = env.reset(seed=5)
        per_env = [s.reset(seed=5 + i)[1] for i, s in enumerate(singles)]
        assert_same(info, reference(per_env))
        action = np.zeros((n, *env.single_action_space.shape))  # type: ignore[misc]
        for _ in range(3):
            _, _, _, _, info = env.step(action)
            per_env = [s.step(action[i])[4] for i, s in enumerate(singles)]
            assert_same(info, reference(per_env))
    finally:
        env.close()
        for s in singles:
            s.close()
