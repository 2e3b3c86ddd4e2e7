"""sensor_preset and the per-model options at gym.make: plumbing, ideal = the default bit for bit,
determinism with the realistic preset, finite observations and valid flags under every preset, and
the drift of the autopilot's estimated feedback (a deck-relative controller keeps the drone over
the deck)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import rollout, same_runs

import ihrcf_env  # noqa: F401  (registers the env)
from ihrcf_env.config.make import SENSOR_PRESETS, make_config
from ihrcf_env.config.sensors import VL53L1X, IMUNoise
from ihrcf_env.config.vehicle import NavigationErrors

RAW = "ihrcf_env/DeckHoverRaw-v0"
SMALL = {"camera_width": 96, "camera_height": 96}


def _models(**kwargs) -> tuple[str | None, VL53L1X | None, IMUNoise | None, NavigationErrors | None]:
    world = make_config(**kwargs).world
    quality = world.camera.quality if world.camera is not None else None
    return quality, world.tof.model, world.imu.model, world.navigation.errors


def test_presets_set_every_model_together() -> None:
    assert set(SENSOR_PRESETS) == {"ideal", "realistic"}
    q, tof, imu, nav = _models()
    assert (tof, imu, nav) == (None, None, None)
    q, tof, imu, nav = _models(sensor_preset="realistic")
    assert tof == VL53L1X() and imu == IMUNoise() and nav == NavigationErrors()
    assert q == "realistic"
    assert _models()[0] == "ideal"


@pytest.mark.parametrize(
    "kwargs, expected",
    [
        ({"sensor_preset": "realistic", "tof_noise": "ideal"}, (False, True, True)),
        ({"sensor_preset": "realistic", "imu_noise": "ideal"}, (True, False, True)),
        ({"sensor_preset": "realistic", "autopilot_feedback": "truth"}, (True, True, False)),
        ({"tof_noise": "realistic"}, (True, False, False)),
        ({"imu_noise": "realistic"}, (False, True, False)),
        ({"autopilot_feedback": "estimated"}, (False, False, True)),
    ],
)
def test_each_option_overrides_its_preset(kwargs, expected) -> None:
    _, tof, imu, nav = _models(**kwargs)
    assert (tof is not None, imu is not None, nav is not None) == expected


def test_camera_quality_overrides_the_preset() -> None:
    assert _models(sensor_preset="realistic", camera_quality="ideal")[0] == "ideal"
    assert _models(camera_quality="realistic")[0] == "realistic"
    assert make_config(sensor_preset="realistic", camera=False, raw=True).world.camera is None  # fine


def test_parameter_dicts_and_dataclasses() -> None:
    _, tof, imu, nav = _models(
        tof_noise={"ambient": 0.5, "rays": 24},
        imu_noise=IMUNoise(tilt_sigma=0.0),
        autopilot_feedback={"horizontal_sigma": 1.5},
    )
    assert tof == VL53L1X(ambient=0.5, rays=24)
    assert imu == IMUNoise(tilt_sigma=0.0)
    assert nav == NavigationErrors(horizontal_sigma=1.5)
    # a dict means the realistic model with those parameters, whatever the preset
    assert _models(sensor_preset="ideal", imu_noise={})[2] == IMUNoise()


def test_explicit_ideal_is_the_default(make_env) -> None:
    explicit = {
        "sensor_preset": "ideal",
        "tof_noise": "ideal",
        "imu_noise": "ideal",
        "autopilot_feedback": "truth",
        "camera_quality": "ideal",
    }
    assert make_config(raw=True, **explicit) == make_config(raw=True)
    envs = [make_env(RAW, **SMALL), make_env(RAW, **SMALL, **explicit)]
    runs = [rollout(e, seed=3, steps=20) for e in envs]
    assert same_runs(*runs)


def test_realistic_preset_is_bitwise_deterministic(make_env) -> None:
    kw = dict(sensor_preset="realistic", deck_profile="sea_state", **SMALL)
    e1, e2 = make_env(RAW, **kw), make_env(RAW, **kw)
    s1, s2 = rollout(e1, 21, 30), rollout(e2, 21, 30)
    assert same_runs(s1, s2)
    s3 = rollout(e1, 21, 30)  # the same env, reset with the same seed
    assert same_runs(s1, s3)
    s4 = rollout(e2, 22, 30)
    assert not same_runs(s1, s4)


PRESETS = [
    {"sensor_preset": "ideal"},
    {"sensor_preset": "realistic"},
    {"tof_noise": "realistic"},
    {"imu_noise": "realistic"},
    {"autopilot_feedback": "estimated"},
    {"sensor_preset": "realistic", "tof_noise": {"ambient": 0.05}, "deck_profile": "sea_state"},
]


@pytest.mark.parametrize("kwargs", PRESETS, ids=[str(k) for k in PRESETS])
def test_observations_are_finite_in_space_and_flagged(make_env, kwargs) -> None:
    env = make_env(RAW, camera=False, **kwargs)
    obs, _ = env.reset(seed=5)
    rng = np.random.default_rng(1)
    max_range = np.float32(env.unwrapped.config.world.tof.max_range)
    valid_count = steps = 0
    for _ in range(60):
        obs, _, term, _, _ = env.step(rng.uniform(-0.5, 0.5, 4))
        assert env.observation_space.contains(obs)
        for v in (obs["ranges"], *obs["imu"].values()):
            assert np.all(np.isfinite(v))
        ok = obs["ranges_valid"]
        assert set(np.unique(ok)) <= {0, 1}
        assert np.all(obs["ranges"][ok == 0] == max_range)
        assert np.all(obs["ranges"][ok == 1] < max_range)
        valid_count += int(ok.sum())
        steps += 1
        if term:
            break
    assert valid_count >= 0.8 * 4 * steps  # hovering ~1 m over the deck: the ranges are seen


def test_realistic_camera_observation_is_finite(make_env) -> None:
    env = make_env(RAW, sensor_preset="realistic", **SMALL)
    obs, _ = env.reset(seed=2)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(4))
        assert env.observation_space.contains(obs)
        assert obs["image"].dtype == np.uint8


def test_strong_ambient_light_leaves_no_valid_range_at_1_m(make_env) -> None:
    env = make_env(RAW, camera=False, tof_noise={"ambient": 1.0})
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        assert not obs["ranges_valid"].any()
        assert np.all(obs["ranges"] == np.float32(4.0))
        obs, *_ = env.step(np.zeros(4))


def test_estimated_feedback_drifts_and_a_deck_relative_controller_stays_over_the_deck(make_env) -> None:
    """Zero command: the drone drifts with its GNSS/INS estimate (tens of cm in 30 s); steering on
    the deck's position in the body frame (here the ground truth, standing in for an onboard deck
    estimate) keeps it over the deck."""
    seeds, steps = (1, 2), 600  # 30 s
    env = make_env(
        RAW, camera=False, deck_profile="static", autopilot_feedback="estimated", max_episode_steps=None
    )
    drift, held = [], []
    for seed in seeds:
        _, info = env.reset(seed=seed, options={"offset": (0.0, 0.0)})
        p0 = info["drone_position_world"].copy()
        for _ in range(steps):
            _, _, term, _, info = env.step(np.zeros(4))
            assert not term
        drift.append(math.hypot(*(info["drone_position_world"] - p0)[:2]))
        _, info = env.reset(seed=seed, options={"offset": (0.0, 0.0)})
        errors = []
        for _ in range(steps):
            rel = info["deck_position_body"]
            action = np.array([rel[0], rel[1], 0.0, 0.0])  # 1 m/s per m of offset
            _, _, term, _, info = env.step(np.clip(action, -1, 1))
            assert not term
            errors.append(math.hypot(*(info["drone_position_world"] - info["deck_position_world"])[:2]))
        held.append(max(errors[steps // 3 :]))
    assert min(drift) > 0.05 and max(drift) < 2.0, drift
    assert max(held) < 0.1, held  # the 0.8 m deck's edge is 0.4 m away
