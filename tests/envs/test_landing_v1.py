"""DeckLanding-v1's task: start distribution, success criterion (incl. the 0.15 m radius),
termination vs truncation, the reward's order with fixed policies, options and bad input.

Camera-less raw envs (``raw=True, camera=False``) keep these fast where the camera does not matter;
the reward order is shown with the scripted baseline (own sensing) on the projected camera.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import descend

import ihrcf_env
from ihrcf_env.control.policies import ScriptedLanding
from ihrcf_env.envs.landing_v1 import DeckLandingV1Env
from ihrcf_env.sim.disturbances import Wind

FAST = {"raw": True, "camera": False, "horizon_s": 60.0}
DIVE = np.array([0.0, 0.0, -1.0, 0.0], np.float32)  # full-speed descent


@pytest.fixture
def make(make_v1: Callable[..., gym.Env]) -> Callable[..., gym.Env]:
    """``make(**options)``: a fast v1 env (``FAST`` unless overridden), closed when the test ends."""
    return lambda **kwargs: make_v1(**{**FAST, **kwargs})


def test_registered_with_v1_defaults(make) -> None:
    env = make()
    base = env.unwrapped
    assert isinstance(base, DeckLandingV1Env)
    assert env.spec is not None and env.spec.max_episode_steps == 600
    assert base.config.task.deck.profile == "sea_state" and base.config.task.deck.random_start
    assert base.config.world.navigation.feedback == "estimated"  # the realistic preset
    assert isinstance(base.wind, Wind) and base.goal.success_radius == 0.15
    assert base.config.task.start.lowest == pytest.approx(
        1.5
    ) and base.config.task.start.highest == pytest.approx(3.0)


def test_start_distribution_bounds(make) -> None:
    """Altitude 1.5-3 m, any yaw, offset in the disc of start_radius(altitude) <= 1 m, which keeps
    the tag in view (a camera with the default geometry, tiny images: the geometry is the same)."""
    env = make(camera=True, camera_width=32, camera_height=32, camera_quality="ideal")
    base = env.unwrapped
    alts, offs, yaws = [], [], []
    for seed in range(60):
        _, info = env.reset(seed=seed)
        e = info["drone_position_world"] - info["deck_position_world"]
        R = base.world.drone_pose()[1]
        alt, off = float(e[2]), float(math.hypot(e[0], e[1]))
        assert 1.5 - 1e-6 <= alt <= 3.0 + 1e-6
        assert off <= base.start_radius(alt) + 1e-6 <= 1.0 + 1e-6
        alts.append(alt)
        offs.append(off)
        yaws.append(math.atan2(R[1, 0], R[0, 0]))
    assert max(offs) > 0.6 and min(alts) < 1.7 and max(alts) > 2.8
    assert min(yaws) < -2.0 and max(yaws) > 2.0  # any yaw
    # the in-view radius: 0.40 m at 1.5 m, the full 1 m from ~2.6 m up
    assert base.start_radius(1.5) == pytest.approx(0.395, abs=0.01)
    assert base.start_radius(3.0) == 1.0
    assert base.start_radius(1.5) < base.start_radius(2.0) < 1.0
    # without the in-view clip (or without a camera) the disc is the full start_offset
    env = make(start_in_view=False, start_offset=0.7)
    assert env.unwrapped.start_radius(1.5) == 0.7


@pytest.mark.parametrize(
    ("offset", "vz", "outcome", "reason"),
    [
        ((0.08, 0.05), 0.3, "success", ""),
        ((0.20, 0.0), 0.3, "crash", "from the tag centre"),  # on the deck, slow, level, off target
        ((0.0, -0.13), 0.3, "success", ""),
        ((0.0, -0.17), 0.3, "crash", "from the tag centre"),
        ((0.0, 0.0), 1.0, "crash", "vertical speed"),
    ],
)
def test_success_needs_the_radius(
    make, offset: tuple[float, float], vz: float, outcome: str, reason: str
) -> None:
    """Static deck, no wind, ideal sensors: a vertical descent from a chosen offset."""
    env = make(deck_profile="static", wind=False, sensor_preset="ideal", random_deck_start=False)
    terminated, truncated, info = descend(env, {"altitude": 0.5, "offset": offset, "yaw": 0.3}, vz)
    assert terminated and not truncated
    assert info["outcome"] == outcome and reason in info["crash_reason"]
    assert info["is_success"] == (outcome == "success")
    assert info["touchdown"]["on_deck"]
    assert info["tag_offset"] == pytest.approx(math.hypot(*offset), abs=0.01)
    if outcome == "success":
        assert info["reward_terminal"] == 100.0
    else:  # graded: 20 just outside the limits, 100 at twice them or more
        td = info["touchdown"]
        miss = max(
            abs(td["relative_vertical_speed"]) / 0.5,
            td["relative_tilt"] / math.radians(10.0),
            info["tag_offset"] / 0.15,
        )
        assert miss >= 1.0
        assert info["reward_terminal"] == pytest.approx(-(20.0 + 80.0 * min(1.0, miss - 1.0)))


def test_success_radius_option(make) -> None:
    env = make(deck_profile="static", wind=False, sensor_preset="ideal", success_radius=0.25)
    _, _, info = descend(env, {"altitude": 0.5, "offset": (0.2, 0.0), "yaw": 0.0})
    assert info["outcome"] == "success"


def _run(env: gym.Env, seed: int, policy: Any) -> tuple[float, dict, bool, bool]:
    obs, info = env.reset(seed=seed)
    policy.reset()
    ret = 0.0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        ret += float(reward)
        terms = sum(v for k, v in info.items() if k.startswith("reward_"))
        assert reward == pytest.approx(terms)
        if terminated or truncated:
            return ret, info, terminated, truncated


class _Constant:
    def __init__(self, action: np.ndarray) -> None:
        self.action = action

    def reset(self) -> None:
        pass

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.action


def test_returns_order_success_hover_crash(make_env) -> None:
    """On the default v1 task (projected camera for speed): the scripted landing (own sensing) >
    a safe hover until the time limit > a crash (full-speed dive), seed by seed."""
    env = make_env(ihrcf_env.LANDING_V1_ID, camera_model="projected", horizon_s=60.0)
    base = env.unwrapped
    scripted = ScriptedLanding(
        env.get_wrapper_attr("obs_slices"),
        env.get_wrapper_attr("obs_scales"),
        base.config.world.control_hz,
        base.max_velocity,
        base.rig,
    )
    for seed in (0, 1):
        r_land, info, terminated, truncated = _run(env, seed, scripted)
        assert info["outcome"] == "success" and terminated and not truncated, info["crash_reason"]
        assert info["is_success"]
        r_hover, info, terminated, truncated = _run(env, seed, _Constant(np.zeros(4, np.float32)))
        assert info["outcome"] == "flying" and truncated and not terminated  # only the TimeLimit
        assert not info["is_success"]
        r_crash, info, terminated, truncated = _run(env, seed, _Constant(DIVE))
        assert info["outcome"] == "crash" and terminated and not truncated  # never truncation
        assert r_land > 90 > 0 > -15 > r_hover > -45 > -70 > r_crash, (r_land, r_hover, r_crash)


def test_wind_leans_the_drone_and_info_has_it(make) -> None:
    """A steady 5 m/s wind: the autopilot leans into it (~5 deg) and holds; info reports the wind."""
    env = make(
        wind={"mean_speed_min": 5.0, "mean_speed_max": 5.0, "turbulence": 0.0},
        sensor_preset="ideal",
        deck_profile="static",
    )
    _, info = env.reset(seed=3)
    w = info["wind_velocity"]
    assert np.linalg.norm(w) == pytest.approx(5.0)
    for _ in range(100):
        _, _, _, _, info = env.step(np.zeros(4, np.float32))
    R = env.unwrapped.world.drone_pose()[1]
    lean = R[:, 2][:2]  # the thrust axis tilts into the wind (towards where it comes from)
    assert float(lean @ w[:2]) < 0
    assert math.degrees(math.asin(np.linalg.norm(lean))) == pytest.approx(5.2, abs=1.0)
    assert np.linalg.norm(info["relative_velocity"]) < 0.3  # holding position (static deck)
    calm = make(wind=False)
    assert calm.unwrapped.wind is None
    _, info = calm.reset(seed=0)
    assert np.all(info["wind_velocity"] == 0)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"wind": "strong"}, TypeError, "wind"),
        ({"wind": {"mean_speed_max": -1.0}}, ValueError, "wind"),
        ({"wind": {"gusts": 1.0}}, ValueError, "wind has no parameter 'gusts'"),
        ({"success_radius": 0.0}, ValueError, "success_radius"),
        ({"success_radius": "0.1"}, TypeError, "success_radius"),
        ({"start_in_view": 1}, TypeError, "start_in_view"),
        ({"view_margin": -0.1}, ValueError, "view_margin"),
        ({"reward_weights": {"bonus": 1.0}}, ValueError, "reward_weights has no parameter 'bonus'"),
        ({"reward_weights": {"crash": -1.0}}, ValueError, "reward_weights"),
        ({"reward_weights": [1.0]}, TypeError, "reward_weights"),
        ({"start_altitude": 0.8}, ValueError, "start_altitude"),  # v0's checks still apply
        ({"disturbances": "wind"}, TypeError, "disturbances"),
    ],
)
def test_bad_options_name_themselves(make, kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        make(**kwargs)
