"""AsyncVectorEnv over two processes steps and resets correctly."""

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401

ROOT = Path(__file__).resolve().parents[2]


def _thunk(steps: int):
    return lambda: gym.make("ihrcf_env/DeckHover-v0", flatten=True, max_episode_steps=steps)


def test_async_vector_env_steps_and_autoresets():
    envs = gym.vector.AsyncVectorEnv([_thunk(4), _thunk(6)])
    try:
        obs, _ = envs.reset(seed=[1, 2])
        n = envs.single_observation_space.shape[0]  # 39 + 7 per estimator beyond IHRCF and ATDA
        assert n >= 39 and obs.shape == (2, n) and obs.dtype == np.float32
        first = obs.copy()
        done_at = {0: None, 1: None}
        for k in range(8):
            obs, reward, terminated, truncated, info = envs.step(np.zeros((2, 4), dtype=np.float32))
            assert np.all(np.isfinite(obs)) and reward.shape == (2,)
            for i in (0, 1):
                if truncated[i] and done_at[i] is None:
                    done_at[i] = k
        assert done_at == {0: 3, 1: 5}
        # with the same seeds the sub-envs start like single envs do
        single = gym.make("ihrcf_env/DeckHover-v0", flatten=True)
        o, _ = single.reset(seed=1)
        single.close()
        np.testing.assert_array_equal(first[0], o)
    finally:
        envs.close()


def test_learning_loop_example_runs():
    out = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "learning_loop.py"), "--steps", "8", "--episode-steps", "5"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert "env steps/s" in out.stdout and "finished episodes: 2" in out.stdout
