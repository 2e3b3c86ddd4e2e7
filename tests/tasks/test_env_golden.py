"""The envs' rewards, terminations and outcomes against an episode recording made before the task
rules were written as pure functions (``ihrcf_env.tasks``): the same seeds and actions give the
same episodes (camera-less raw envs and a projected camera, so the test stays fast). Outcomes and
step counts are compared exactly; rewards and reward terms within a tolerance, since a platform's
libm may round the last bit differently."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

RECORDING = Path(__file__).parent / "env_golden.json"
GOLDEN = json.loads(RECORDING.read_text())
TERMS_V1 = ("reward_progress", "reward_time", "reward_action", "reward_terminal")
TERMS_HOVER = ("reward_position", "reward_velocity", "reward_attitude", "reward_action", "reward_terminal")
RTOL, ATOL = 1e-7, 1e-9  # reward units; last-bit differences grow slowly over a closed loop


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


def _run(env: gym.Env, case: dict[str, Any], max_steps: int) -> dict[str, Any]:
    rng = np.random.default_rng(100 + case["seed"])
    env.reset(seed=case["seed"])
    rewards: list[float] = []
    terms: list[list[float]] = []
    for _ in range(max_steps):
        _, reward, terminated, truncated, info = env.step(_action(case["policy"], rng))
        names = TERMS_V1 if "reward_progress" in info else TERMS_HOVER
        rewards.append(float(reward))
        terms.append([float(info[k]) for k in names])
        if terminated or truncated:
            break
    return {
        "steps": len(rewards),
        "rewards": rewards,
        "terms": terms,
        "terminated": bool(terminated),
        "truncated": bool(truncated),
        "outcome": info["outcome"],
        "crash_reason": info["crash_reason"],
        "is_success": info.get("is_success"),
    }


@pytest.mark.parametrize("case", GOLDEN, ids=_id)
def test_episode_matches_the_recording(make_env: Any, case: dict[str, Any]) -> None:
    got = _run(make_env(case["env_id"], **case["options"]), case, case["steps"])
    assert got["steps"] == case["steps"]
    for key in ("terminated", "truncated", "outcome", "crash_reason", "is_success"):
        assert got[key] == case[key], key
    np.testing.assert_allclose(got["rewards"], case["rewards"], rtol=RTOL, atol=ATOL)
    np.testing.assert_allclose(got["terms"], case["terms"], rtol=RTOL, atol=ATOL)


if __name__ == "__main__":  # rewrite the recording's values from the current envs (same cases)
    sys.path.insert(0, str(Path(__file__).parents[2]))
    import ihrcf_env  # noqa: F401  (registers the ids)

    out = []
    for case in GOLDEN:
        env = gym.make(case["env_id"], **case["options"])
        try:
            got = _run(env, case, case["steps"] + 10)
        finally:
            env.close()
        out.append({"env_id": case["env_id"], "options": case["options"], "seed": case["seed"],
                    "policy": case["policy"], **got})  # fmt: skip
    RECORDING.write_text(json.dumps(out, indent=1) + "\n")
