"""gym.make_vec(landing id, backend="jax"): options refused before compiling; the compiled env
steps with paired seeds (slow: its compile takes minutes)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

jax = pytest.importorskip("jax")

import ihrcf_env  # noqa: E402,F401

ID = "ihrcf_env/DeckLanding-v2"


def make(n: int = 2, **options: object) -> gym.vector.VectorEnv:
    return gym.make_vec(ID, num_envs=n, vectorization_mode="vector_entry_point", **options)


def test_options_the_backend_cannot_honour_are_named() -> None:
    with pytest.raises(ValueError, match="camera_model='rendered'"):
        make(backend="jax", camera_model="rendered")
    with pytest.raises(ValueError, match="camera_output"):
        make(backend="jax", camera_output="image")
    with pytest.raises(ValueError, match="backend"):
        make(backend="torch")
    with pytest.raises(ValueError, match="workers"):
        make(backend="jax", workers=2)
    with pytest.raises(ValueError, match="dtype"):
        make(backend="jax", dtype="float16")
    with pytest.raises(ValueError, match="deck_forecast"):
        make(backend="jax", deck_forecast=True)


@pytest.mark.slow
def test_the_compiled_env_pairs_seeds_with_the_pybullet_env() -> None:
    env = make(2, backend="jax", level="moderate")
    ref = gym.make(ID, level="moderate", camera_model="projected", camera_output="corners")
    try:
        assert env.single_observation_space == ref.observation_space
        assert env.obs_slices == ref.get_wrapper_attr("obs_slices")  # type: ignore[attr-defined]
        obs, _ = env.reset(seed=11)
        ref_obs, _ = ref.reset(seed=12)
        sl = env.obs_slices  # type: ignore[attr-defined]
        # the same start and deck: the first estimates of the deck agree (the sensor noise differs)
        np.testing.assert_allclose(obs[1, sl["imu.up"]], ref_obs[sl["imu.up"]], atol=0.02)
        for _ in range(3):
            obs, reward, term, trunc, info = env.step(np.zeros((2, 4)))
            assert np.isfinite(obs).all() and np.isfinite(reward).all()
        assert "outcome" in info and info["_outcome"].all()
    finally:
        env.close()
        ref.close()
