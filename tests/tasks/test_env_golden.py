"""The envs' rewards, terminations and outcomes, bit for bit, against figures recorded before the
task rules were written as pure functions (``ihrcf_env.tasks``): the same seeds and actions give
the same episodes (camera-less raw envs and a projected camera, so the test stays fast)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

GOLDEN = json.loads((Path(__file__).parent / "env_golden.json").read_text())
TERMS_V1 = ("reward_progress", "reward_time", "reward_action", "reward_terminal")
TERMS_HOVER = ("reward_position", "reward_velocity", "reward_attitude", "reward_action", "reward_terminal")


def _action(policy: str, rng: np.random.Generator) -> np.ndarray:
    if policy == "dive":
        return np.array([0.0, 0.0, -1.0, 0.0], np.float32)
    if policy == "side":
        return np.array([1.0, 0.0, 0.3, 0.0], np.float32)
    if policy == "slow":
        return np.array([0.05, -0.02, -0.3, 0.0], np.float32)
    return rng.uniform(-1, 1, 4).astype(np.float32)


def _id(case: dict[str, Any]) -> str:
    return f"{case['env_id'].split('/')[1]}-{case['policy']}-{case['seed']}"


@pytest.mark.parametrize("case", GOLDEN, ids=_id)
def test_episode_matches_the_recording(make_env: Any, case: dict[str, Any]) -> None:
    env: gym.Env = make_env(case["env_id"], **case["options"])
    rng = np.random.default_rng(100 + case["seed"])
    env.reset(seed=case["seed"])
    rewards, terms = [], []
    for _ in range(case["steps"]):
        _, reward, terminated, truncated, info = env.step(_action(case["policy"], rng))
        names = TERMS_V1 if "reward_progress" in info else TERMS_HOVER
        rewards.append(reward)
        terms.append([info[k] for k in names])
        if terminated or truncated:
            break
    assert len(rewards) == case["steps"]
    assert (terminated, truncated) == (case["terminated"], case["truncated"])
    assert (info["outcome"], info["crash_reason"]) == (case["outcome"], case["crash_reason"])
    assert info.get("is_success") == case["is_success"]
    assert float(reward).hex() == case["last_reward"]
    assert {k: float(info[k]).hex() for k in case["last_terms"]} == case["last_terms"]
    assert hashlib.sha256(np.array(rewards, np.float64).tobytes()).hexdigest() == case["rewards_sha256"]
    assert hashlib.sha256(np.array(terms, np.float64).tobytes()).hexdigest() == case["terms_sha256"]
