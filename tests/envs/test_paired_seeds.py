"""Paired seeds: one ``reset(seed=s)`` gives the same start, deck motion and wind whatever the camera
model, the sensor preset, the noise models or the estimators, because each subsystem draws from its
own stream (:mod:`ihrcf_env.core.seeding`)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.core.seeding import SeedStreams, stream_id

#: Truth-fed autopilot (ideal feedback), so the flight does not depend on the sensors.
BASE = {"horizon_s": 30.0, "autopilot_feedback": "truth"}
TRUTH_KEYS = ("drone_position_world", "drone_quaternion_world", "deck_position_world", "wind_velocity")


def _truth(env: gym.Env, seed: int, steps: int = 15) -> np.ndarray:
    """Ground truth (drone, deck, wind) at reset and over ``steps`` zero-command steps."""
    _, info = env.reset(seed=seed)
    rows = [np.concatenate([np.ravel(info[k]) for k in TRUTH_KEYS])]
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        rows.append(np.concatenate([np.ravel(info[k]) for k in TRUTH_KEYS]))
        if terminated or truncated:
            break
    return np.array(rows)


def _pair(make_env: Any, env_id: str, a: dict[str, Any], b: dict[str, Any], seed: int = 7) -> None:
    first = _truth(make_env(env_id, **{**BASE, **a}), seed)
    second = _truth(make_env(env_id, **{**BASE, **b}), seed)
    assert first.tobytes() == second.tobytes()  # bitwise the same start, deck, wind and flight
    other = _truth(make_env(env_id, **{**BASE, **a}), seed + 1)
    assert other[0].tobytes() != first[0].tobytes()  # and another seed is another episode


@pytest.mark.parametrize("env_id", [ihrcf_env.LANDING_V1_ID, ihrcf_env.HOVER_ID])
def test_camera_models_are_paired(make_env: Any, env_id: str) -> None:
    _pair(
        make_env,
        env_id,
        {"camera_model": "rendered", "camera_output": "corners"},
        {"camera_model": "projected"},
    )


def test_sensor_presets_are_paired(make_env: Any) -> None:
    """Realistic sensors draw noise from their own streams: the episode is the ideal one's."""
    _pair(
        make_env,
        ihrcf_env.LANDING_V1_ID,
        {"camera_model": "projected", "sensor_preset": "ideal"},
        {"camera_model": "projected", "sensor_preset": "realistic", "autopilot_feedback": "truth"},
    )


def test_noise_models_and_estimators_are_paired(make_env: Any) -> None:
    _pair(
        make_env,
        ihrcf_env.LANDING_V1_ID,
        {"camera_model": "projected"},
        {"camera_model": "projected", "tof_noise": {"ambient": 1.0}, "estimators": ("ihrcf",)},
    )


def test_user_disturbances_do_not_shift_the_wind(make_env: Any) -> None:
    from ihrcf_env.sim.disturbances import Wind

    env = make_env(ihrcf_env.LANDING_V1_ID, camera_model="projected", **BASE)
    pushed = make_env(ihrcf_env.LANDING_V1_ID, camera_model="projected", disturbances=[Wind()], **BASE)
    _, a = env.reset(seed=3)
    _, b = pushed.reset(seed=3)
    np.testing.assert_array_equal(a["wind_velocity"], b["wind_velocity"])
    np.testing.assert_array_equal(a["drone_position_world"], b["drone_position_world"])


def test_the_noise_of_a_sensor_differs_between_presets_but_not_between_runs(make_env: Any) -> None:
    """Pairing does not freeze the noise: realistic ranges differ from ideal ones, and repeat
    exactly for the same seed."""
    real = make_env(
        ihrcf_env.HOVER_RAW_ID, camera=False, sensor_preset="realistic", autopilot_feedback="truth"
    )
    ideal = make_env(ihrcf_env.HOVER_RAW_ID, camera=False)
    a, _ = real.reset(seed=1)
    b, _ = real.reset(seed=1)
    c, _ = ideal.reset(seed=1)
    np.testing.assert_array_equal(a["ranges"], b["ranges"])
    assert not np.array_equal(a["ranges"], c["ranges"])


def test_streams_are_named_and_independent() -> None:
    s = SeedStreams(12345)
    a = s.generator("wind").random(4)
    np.testing.assert_array_equal(a, SeedStreams(12345).generator("wind").random(4))
    assert not np.array_equal(a, s.generator("deck").random(4))
    assert not np.array_equal(a, SeedStreams(12346).generator("wind").random(4))
    assert stream_id("wind") == stream_id("wind") != stream_id("deck")
    with pytest.raises((TypeError, ValueError), match="key"):
        SeedStreams(-1)
