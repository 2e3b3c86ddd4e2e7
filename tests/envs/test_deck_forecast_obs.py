"""The deck-motion forecast in the landing observation (``deck_forecast``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.config.make import make_config
from ihrcf_env.core.estimators import PoseEstimate
from ihrcf_env.core.forecast import ForecastOptions
from ihrcf_env.wrappers.forecast_feed import FORECAST
from ihrcf_env.wrappers.landing_obs import landing_obs_fields

V1, V2 = ihrcf_env.LANDING_V1_ID, ihrcf_env.LANDING_V2_ID
FIELDS = ("heave", "heave_rate", "roll", "pitch")
HOLD_STEPS = 300  # 15 s at 20 Hz: the forecaster fits after 10 s of samples


def test_the_option_is_off_by_default_and_typed_when_on() -> None:
    assert make_config(task="landing-v2").observation.deck_forecast is None
    assert make_config(task="landing-v2", deck_forecast=False).observation.deck_forecast is None
    assert make_config(task="landing-v1", deck_forecast=True).observation.deck_forecast == ForecastOptions()
    got = make_config(task="landing-v2", deck_forecast={"horizons": (0.5, 1.0), "order": 12})
    assert got.observation.deck_forecast == ForecastOptions(horizons=(0.5, 1.0), order=12)
    opts = ForecastOptions(window=30.0)
    assert make_config(task="landing-v2", deck_forecast=opts).observation.deck_forecast is opts


@pytest.mark.parametrize(
    ("options", "error", "match"),
    [
        ({"deck_forecast": {"order": 1}}, ValueError, r"deck_forecast: .*forecast\.order"),
        ({"deck_forecast": {"order": 1000}}, ValueError, r"deck_forecast: .*forecast\.order"),
        ({"deck_forecast": {"horizons": (0.5, 50.0)}}, ValueError, r"deck_forecast: .*horizons\[1\]"),
        ({"deck_forecast": {"horizons": ()}}, TypeError, r"deck_forecast: .*forecast\.horizons"),
        ({"deck_forecast": {"window": 1.0}}, ValueError, r"deck_forecast: .*forecast\.window"),
        ({"deck_forecast": {"max_gap": -1.0}}, ValueError, r"deck_forecast: .*forecast\.max_gap"),
        ({"deck_forecast": {"colour": 1}}, (TypeError, ValueError), r"deck_forecast.*colour"),
        ({"deck_forecast": "yes"}, TypeError, r"deck_forecast must be"),
        ({"deck_forecast": 1.5}, TypeError, r"deck_forecast must be"),
        (
            {"deck_forecast": True, "estimators": ("ihrcf", "atda")},
            ValueError,
            r"deck_forecast needs the fused",
        ),
        ({"deck_forecast": True, "raw": True}, ValueError, r"deck_forecast.*raw=True"),
    ],
)
def test_bad_forecast_options_are_named(options: dict[str, Any], error: Any, match: str) -> None:
    with pytest.raises(error, match=match):
        make_config(task="landing-v2", **options)


@pytest.mark.parametrize("options", [{"raw": True}, {"flatten": True}])
def test_the_hover_task_refuses_it_without_its_dict_observation(options: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="deck_forecast"):
        make_config(task="hover", deck_forecast=True, **options)
    with pytest.raises(ValueError, match="deck_forecast"):
        gym.make(ihrcf_env.HOVER_ID, deck_forecast={"order": 8}, **options)


def test_the_hover_task_offers_it_beside_the_estimates(make_env: Any) -> None:
    env = make_env(ihrcf_env.HOVER_ID, camera_model="projected", deck_forecast={"horizons": (0.5, 1.0)})
    obs, info = env.reset(seed=4)
    assert env.observation_space.contains(obs)
    assert obs[FORECAST]["valid"] == 0 and not np.any(obs[FORECAST]["mean"])
    assert obs[FORECAST]["mean"].shape == (2, 4)
    for _ in range(HOLD_STEPS):
        obs, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        assert env.observation_space.contains(obs)
        if terminated or truncated:
            break
    fc = info[FORECAST]
    assert fc["samples"] > 100 and obs[FORECAST]["valid"] == 1
    np.testing.assert_allclose(obs[FORECAST]["mean"], fc["mean"], rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(obs[FORECAST]["std"], fc["std"], rtol=1e-6, atol=1e-7)
    assert make_env(ihrcf_env.HOVER_ID, camera_model="projected").observation_space.get(FORECAST) is None


def test_the_layout_appends_the_forecast_block_only_when_asked() -> None:
    base, _, low0, _ = landing_obs_fields()
    assert base["all"].stop == 50 and not any(k.startswith(FORECAST) for k in base)
    slices, scales, low, high = landing_obs_fields(forecast_horizons=3)
    assert slices["all"].stop == 50 + 8 * 3 + 2
    assert np.array_equal(low[:50], low0)
    for name in FIELDS:
        assert slices[f"forecast.{name}"].stop - slices[f"forecast.{name}"].start == 3
        assert np.all(low[slices[f"forecast.{name}_std"]] == 0.0)
    assert slices["forecast.valid"].stop == slices["all"].stop
    assert scales["forecast.heave"] == pytest.approx(0.1)


@pytest.fixture(scope="module")
def held_episode() -> Iterator[tuple[gym.Env, list[np.ndarray], list[dict[str, Any]]]]:
    """A ``moderate`` episode holding position (zero velocity action) for HOLD_STEPS steps."""
    env = gym.make(V2, camera_model="projected", level="moderate", deck_forecast=True)
    try:
        obs, info = env.reset(seed=11)
        observations, infos = [obs], [info]
        for _ in range(HOLD_STEPS):
            obs, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
            observations.append(obs)
            infos.append(info)
            assert not (terminated or truncated)
        yield env, observations, infos
    finally:
        env.close()


def test_fields_are_named_finite_inside_the_box_and_zero_at_reset(held_episode: Any) -> None:
    env, observations, infos = held_episode
    sl = env.get_wrapper_attr("obs_slices")
    for name in (*FIELDS, *(f"{n}_std" for n in FIELDS)):
        assert sl[f"forecast.{name}"].stop - sl[f"forecast.{name}"].start == 5
    space = env.observation_space
    for obs in observations:
        assert np.all(np.isfinite(obs)) and space.contains(obs)
    first = observations[0][sl[FORECAST]]
    assert np.all(first == 0.0)
    assert infos[0][FORECAST]["valid"] is False and infos[0][FORECAST]["samples"] == 0


def test_the_forecast_becomes_valid_after_a_few_seconds(held_episode: Any) -> None:
    env, observations, infos = held_episode
    sl = env.get_wrapper_attr("obs_slices")
    assert infos[-1][FORECAST]["samples"] > 100
    assert observations[-1][sl["forecast.valid"]][0] == 1.0
    valid = [bool(o[sl["forecast.valid"]][0]) for o in observations]
    first = valid.index(True)
    assert all(valid[first:])
    last = observations[-1]
    assert np.all(last[sl["forecast.heave_std"]] > 0.0) and np.all(last[sl["forecast.pitch_std"]] > 0.0)
    # the deck moves on moderate: the forecast is not constant over the horizons or in time
    heave = np.array([o[sl["forecast.heave"]] for o in observations[first:]])
    assert np.ptp(heave[:, 0]) > 0.0
    assert 0.0 <= last[sl["forecast.quiet"]][0] <= 1.0


def test_info_carries_the_unscaled_fields(held_episode: Any) -> None:
    env, observations, infos = held_episode
    sl, sc = env.get_wrapper_attr("obs_slices"), env.get_wrapper_attr("obs_scales")
    for obs, info in zip(observations[::10], infos[::10], strict=True):
        fc = info[FORECAST]
        assert fc["outputs"] == FIELDS
        np.testing.assert_allclose(fc["horizons"], ForecastOptions().horizons)
        for k, name in enumerate(FIELDS):
            scale = sc[f"forecast.{name}"]
            np.testing.assert_allclose(
                obs[sl[f"forecast.{name}"]] * scale, fc["mean"][:, k], rtol=1e-6, atol=1e-7
            )
            np.testing.assert_allclose(
                obs[sl[f"forecast.{name}_std"]] * scale, fc["std"][:, k], rtol=1e-6, atol=1e-7
            )
        assert obs[sl["forecast.quiet"]][0] == pytest.approx(fc["quiet_probability"], abs=1e-6)
        assert obs[sl["forecast.valid"]][0] == float(fc["valid"])


def _invalid_fused(update: Callable[..., dict[str, PoseEstimate]]) -> Callable[..., dict[str, PoseEstimate]]:
    def patched(frame: Any) -> dict[str, PoseEstimate]:
        out = dict(update(frame))
        out["fused"] = PoseEstimate.invalid("made invalid")
        return out

    return patched


@pytest.mark.parametrize("invalid", [False, True])
def test_the_forecaster_is_fed_only_by_the_valid_fused_estimate(make_env: Any, invalid: bool) -> None:
    env = make_env(V1, camera_model="projected", deck_forecast={"horizons": (0.5, 1.0)})
    stage = env.get_wrapper_attr("stage")
    if invalid:
        stage.estimator.update = _invalid_fused(stage.estimator.update)
    env.reset(seed=2)
    for _ in range(60):
        _, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        assert not (terminated or truncated)
    samples = info[FORECAST]["samples"]
    assert (samples == 0) if invalid else (samples > 10)


def test_the_forecast_does_not_read_the_truth(make_env: Any) -> None:
    """Perturbing the truth the env reports in ``info`` changes nothing in the forecast."""
    runs = []
    for perturb in (False, True):
        env = make_env(V2, camera_model="projected", level="calm", deck_forecast={"horizons": (0.5,)})
        base = env.unwrapped
        if perturb:
            info_of = base._get_info

            def noisy(*a: Any, _f: Any = info_of, **k: Any) -> dict[str, Any]:
                info = _f(*a, **k)
                for key in ("deck_position_world", "deck_position_body", "deck_rotation_body"):
                    info[key] = np.asarray(info[key]) + 0.3
                return info

            base._get_info = noisy
        env.reset(seed=5)
        feed = env.get_wrapper_attr("forecast")
        for _ in range(60):
            env.step(np.zeros(4, np.float32))
        runs.append(feed.forecaster.sums.copy())
    assert runs[0].any() and np.array_equal(runs[0], runs[1])


def test_the_spec_rebuilds_the_env(make_env: Any) -> None:
    env = make_env(V2, camera_model="projected", deck_forecast={"order": 12, "horizons": (1.0,)})
    again = make_env(env.spec)
    assert again.get_wrapper_attr("observation_config").deck_forecast == dataclasses.replace(
        ForecastOptions(), order=12, horizons=(1.0,)
    )
    assert again.observation_space == env.observation_space


def test_the_documented_options_table_is_the_envs_layout(make_env: Any) -> None:
    from ihrcf_env.wrappers.obs_tables import tables

    env = make_env(V2, camera_model="projected", deck_motion=True, deck_forecast=True, privileged=True)
    sl = env.get_wrapper_attr("obs_slices")
    table = tables()["landing-options"]
    for name in ("forecast.heave", "forecast.pitch_std", "forecast.valid", "ground_truth.wind"):
        assert f"| `{name}` | {sl[name].start}:{sl[name].stop} |" in table
    assert env.observation_space.shape == (sl["all"].stop,) == (112,)


def test_a_vector_env_reproduces_the_single_envs_forecast(make_env: Any) -> None:
    from ihrcf_env.vector import DeckLandingVectorEnv

    options: dict[str, Any] = {
        "camera_model": "projected",
        "level": "calm",
        "deck_forecast": {"horizons": (0.5,)},
    }
    v = DeckLandingVectorEnv(V2, 2, **options)
    try:
        singles = [make_env(V2, **options) for _ in range(2)]
        sl = singles[0].get_wrapper_attr("obs_slices")
        assert v.single_observation_space == singles[0].observation_space
        obs, _ = v.reset(seed=21)
        s_obs = [e.reset(seed=21 + i)[0] for i, e in enumerate(singles)]
        zero = np.zeros((2, 4), np.float32)
        for _ in range(HOLD_STEPS - 40):
            for i in range(2):
                np.testing.assert_array_equal(obs[i], s_obs[i])
            obs, _, terminated, truncated, _ = v.step(zero)
            assert not (terminated.any() or truncated.any())
            s_obs = [e.step(zero[i])[0] for i, e in enumerate(singles)]
        assert np.all(obs[:, sl["forecast.valid"]] == 1.0)
    finally:
        v.close()


def test_the_rest_of_the_observation_is_unchanged_bit_for_bit(make_env: Any) -> None:
    """The default observation, and the first values of the observation with the forecast on, are
    those of the env without the option, step for step (paired seeds)."""
    plain = make_env(V2, camera_model="projected", level="moderate")
    off = make_env(V2, camera_model="projected", level="moderate", deck_forecast=False)
    on = make_env(V2, camera_model="projected", level="moderate", deck_forecast=True)
    size = plain.observation_space.shape[0]
    assert off.observation_space == plain.observation_space
    outs = [e.reset(seed=9)[0] for e in (plain, off, on)]
    action = np.array([0.1, -0.1, -0.3, 0.0], np.float32)
    for _ in range(40):
        np.testing.assert_array_equal(outs[0], outs[1])
        np.testing.assert_array_equal(outs[0], outs[2][:size])
        outs = [e.step(action)[0] for e in (plain, off, on)]
