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
    with pytest.raises(ValueError, match="deck_forecast needs the fused estimator"):
        make(backend="jax", deck_forecast=True, estimators=("ihrcf", "atda"))
    with pytest.raises(ValueError, match="deck_forecast"):
        make(backend="jax", deck_forecast={"horizons": (0.5, -1.0)})


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


#: Forecast options that fit within a few seconds of flight (the default waits 10 s).
QUICK_FORECAST = {"window": 8.0, "min_span": 4.0, "order": 8, "horizons": (0.5, 1.0)}


@pytest.mark.slow
def test_the_deck_forecast_block_and_info() -> None:
    """``deck_forecast`` on the JAX backend: the PyBullet env's layout, the block filled once the
    forecaster fits (the drone holding over the deck), ``info["forecast"]`` as vector info."""
    env = make(2, backend="jax", level="rough", deck_forecast=QUICK_FORECAST)
    ref = gym.make(
        ID, level="rough", camera_model="projected", camera_output="corners", deck_forecast=QUICK_FORECAST
    )
    try:
        assert env.single_observation_space == ref.observation_space
        assert env.obs_slices == ref.get_wrapper_attr("obs_slices")  # type: ignore[attr-defined]
        sl = env.obs_slices  # type: ignore[attr-defined]
        env.reset(seed=3)
        valid = np.zeros(2, bool)
        for _ in range(200):
            obs, _, term, trunc, info = env.step(np.zeros((2, 4)))
            assert np.isfinite(obs).all()
            fc = info["forecast"]
            assert fc["mean"].shape == (2, 2, 4) and fc["_mean"].all()
            np.testing.assert_array_equal(obs[:, sl["forecast.valid"]][:, 0], fc["valid"].astype(np.float32))
            np.testing.assert_allclose(fc["horizons"][0], [0.5, 1.0])
            valid |= fc["valid"]
            if (term | trunc).any():
                break
        assert valid.any(), "the forecaster never fitted"
        shown = obs[:, sl["forecast.heave_std"]]
        assert np.all(shown[fc["valid"]] > 0.0)
    finally:
        env.close()
        ref.close()
