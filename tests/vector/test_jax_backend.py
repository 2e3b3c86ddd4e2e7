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


@pytest.mark.parametrize("mode", ["human", "rgb_array", "anything"])
def test_render_mode_is_refused_as_on_the_pybullet_vector_env(mode: str) -> None:
    with pytest.raises(ValueError, match="render_mode: not supported by the vector env"):
        make(backend="jax", render_mode=mode)
    with pytest.raises(ValueError, match="render_mode: not supported by the vector env"):
        make(render_mode=mode)


def test_max_episode_steps_is_bounded_by_the_episode_draws() -> None:
    with pytest.raises(ValueError, match=r"max_episode_steps=1000000000000: .* at most 100000 steps"):
        make(backend="jax", max_episode_steps=10**12)
    # the gusts of all envs within MAX_DRAW_BYTES: fewer steps for more envs
    with pytest.raises(
        ValueError, match=r"max_episode_steps=20000: .*num_envs=65536 in float32 .* at most 2730 steps"
    ):
        make(65536, backend="jax", max_episode_steps=20_000, dtype="float32")


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_backend_needs_the_vector_entry_point(mode: str) -> None:
    with pytest.raises(ValueError, match='backend=.jax.: .*vectorization_mode="vector_entry_point"'):
        gym.make_vec(ID, num_envs=2, vectorization_mode=mode, backend="jax")
    with pytest.raises(ValueError, match="seeding=.paired.: an option of the native vector env only"):
        gym.make(ID, seeding="paired")


def test_a_state_of_another_env_is_named_at_trace_time() -> None:
    """A state of an env without the forecast stepped in one with ``deck_forecast`` (a bare
    AssertionError inside JAX before), and a float32 state in a float64 env: named, not compiled."""
    from ihrcf_env.vector.jax_make import make_functional

    quick = {"window": 8.0, "min_span": 4.0, "order": 8, "horizons": (0.5, 1.0)}
    with jax.enable_x64(True):
        plain = make_functional(ID, "float64", level="rough")
        forecast = make_functional(ID, "float64", level="rough", deck_forecast=quick)
        key = jax.random.PRNGKey(0)
        episode = plain.draw_host(np.random.default_rng(0))[1]
        state = jax.eval_shape(lambda e: plain.reset_from(e, key, ())[1], episode)
        with pytest.raises(
            TypeError, match=r"state\[1\]: not a state of these params \(this env's with deck_forecast\)"
        ):
            jax.eval_shape(lambda s: forecast.step(key, s, jax.numpy.zeros(4), ()), state)
        with pytest.raises(TypeError, match="state must be"):
            forecast.step(key, state[0], jax.numpy.zeros(4), ())
    single = make_functional(ID, "float32", level="rough")
    with jax.enable_x64(True):
        with pytest.raises(ValueError, match=r"state\[0\]\..*float64.*expected float32"):
            jax.eval_shape(lambda s: single.step(key, s, jax.numpy.zeros(4), ()), state)
