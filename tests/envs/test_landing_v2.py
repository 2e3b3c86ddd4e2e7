"""DeckLanding-v2: graded levels of ship motion and wind, the wind-holding autopilot and ground
effect; v1 and the hover task keep theirs."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.config.levels import DEFAULT_LEVEL, LEVELS, TEST_SEEDS
from ihrcf_env.config.make import make_config

V2 = ihrcf_env.LANDING_V2_ID


@pytest.mark.parametrize("name", list(LEVELS))
def test_each_level_sets_its_bundle(name: str) -> None:
    level = LEVELS[name]
    cfg = make_config(task="landing-v2", level=name, raw=True)
    assert cfg.task.deck.profile == "ship"
    assert cfg.task.deck.ship is not None and cfg.task.deck.ship.length_scale == level.length_scale
    assert cfg.wind is not None
    assert (cfg.wind.mean_speed_min, cfg.wind.mean_speed_max) == (level.wind_min, level.wind_max)
    assert cfg.world.gains.wind_hold and cfg.world.ground_effect
    assert cfg.task.thresholds.success_tilt == pytest.approx(math.radians(20.0))
    assert cfg.world.camera is not None and cfg.world.camera.latency > 0  # a real pipeline's delay
    assert cfg.world.tof.rate_hz == 30.0  # the VL53L1X on its own clock


def test_levels_are_graded_and_the_default_is_moderate() -> None:
    calm, moderate, rough = (LEVELS[n] for n in ("calm", "moderate", "rough"))
    assert DEFAULT_LEVEL == "moderate"
    assert calm.sea_state < moderate.sea_state < rough.sea_state
    assert calm.wind_max <= moderate.wind_min and moderate.wind_max <= rough.wind_min
    assert (moderate.wind_min, moderate.wind_max) == (8.0, 12.0)  # a fresh breeze
    assert len(TEST_SEEDS) == 100


def test_options_override_the_level_and_earlier_tasks_are_unchanged() -> None:
    cfg = make_config(task="landing-v2", level="rough", raw=True, wind=False, autopilot="classic")
    assert cfg.wind is None and not cfg.world.gains.wind_hold
    for task in ("hover", "landing-v1"):
        old = make_config(task=task, raw=True)
        assert not old.world.gains.wind_hold and not old.world.ground_effect
        assert old.task.thresholds.success_tilt == pytest.approx(math.radians(10.0))


@pytest.mark.parametrize(("options", "name"), [({"level": "stormy"}, "level"), ({"level": 3}, "level")])
def test_bad_levels_are_named(options: dict[str, Any], name: str) -> None:
    with pytest.raises((TypeError, ValueError), match=name):
        make_config(task="landing-v2", raw=True, **options)
    with pytest.raises(ValueError, match="level"):
        make_config(task="landing-v1", raw=True, level="calm")


def test_a_calm_episode_runs_with_its_wind_and_ship(make_env: Any) -> None:
    env = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", level="calm")
    obs, info = env.reset(seed=TEST_SEEDS[0])
    assert obs.shape == env.observation_space.shape and np.isfinite(obs).all()
    assert np.linalg.norm(info["wind_velocity"][:2]) <= LEVELS["calm"].wind_max * 3  # gusts on a mean
    for _ in range(10):
        obs, reward, terminated, truncated, info = env.step(np.zeros(4, np.float32))
        assert np.isfinite(obs).all() and math.isfinite(reward)


def test_v2_starts_trimmed_in_its_wind_and_earlier_tasks_level(make_env: Any) -> None:
    """v2's drone starts as an autopilot already holding position in the wind would be: leaning
    into it (drag over weight), its camera still looking at the drawn start point."""
    assert make_config(task="landing-v2", raw=True).task.start.trimmed
    for task in ("hover", "landing-v1"):
        assert not make_config(task=task, raw=True).task.start.trimmed
    env = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", level="moderate")
    _, info = env.reset(seed=TEST_SEEDS[0])
    q = np.asarray(info["drone_quaternion_world"])
    up_z = 1.0 - 2.0 * (q[0] ** 2 + q[1] ** 2)  # world z of the body z axis
    assert math.degrees(math.acos(up_z)) > 8.0  # 8-12 m/s: a lean of roughly 10-17 deg
    untrimmed = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", start_trimmed=False)
    _, info = untrimmed.reset(seed=TEST_SEEDS[0])
    assert np.asarray(info["drone_quaternion_world"])[:2] == pytest.approx([0.0, 0.0], abs=1e-9)


def test_bad_start_trimmed_is_named() -> None:
    with pytest.raises((TypeError, ValueError), match="start_trimmed"):
        make_config(task="landing-v2", raw=True, start_trimmed="yes")


def test_a_ship_draw_beyond_the_leg_stroke_is_drawn_again(make_env: Any) -> None:
    """A sea the platform mostly reproduces (sea state 5 at 1:30: about a third of the draws would
    take a leg beyond its stroke within the horizon) resets on every seed: such a draw is drawn
    again from the deck's stream, so a seed still gives one deck motion."""
    env = make_env(V2, camera_model="projected", ship={"sea_state": 5, "length_scale": 30.0})
    for seed in range(8):
        _, info = env.reset(seed=seed)
        assert np.isfinite(info["deck_position_world"]).all()
    a = np.asarray(env.reset(seed=5)[1]["deck_position_world"])
    env.step(np.zeros(4, np.float32))
    b = np.asarray(env.reset(seed=5)[1]["deck_position_world"])
    np.testing.assert_array_equal(a, b)


def test_a_sea_the_platform_cannot_follow_is_refused_at_reset(make_env: Any) -> None:
    env = make_env(V2, camera_model="projected", ship={"sea_state": 6, "length_scale": 30.0})
    with pytest.raises(ValueError, match="deck_profile 'ship'.*stroke"):
        env.reset(seed=0)
