"""Gymnasium env: API compliance, determinism, termination, bad input."""

import math
import subprocess
import sys
from collections.abc import Callable

import gymnasium as gym
import numpy as np
import pytest
from conftest import descend, rollout, same, same_runs
from gymnasium.utils.env_checker import check_env

import ihrcf_env  # noqa: F401  (registers the env)
from ihrcf_env.envs.deck_landing import DeckLandingEnv

HOVER_ID = "ihrcf_env/DeckHoverRaw-v0"  # the raw env; the wrapped id is tested in test_wrapper.py
SMALL = {"camera_width": 96, "camera_height": 96}


@pytest.fixture
def raw(make_env) -> Callable[..., DeckLandingEnv]:
    """``raw(**options)``: the unwrapped raw env, closed when the test ends."""
    return lambda **kw: make_env(HOVER_ID, **kw).unwrapped


def test_check_env_passes(make_env):
    env = make_env(HOVER_ID, **SMALL)
    check_env(env.unwrapped, skip_render_check=True)


def test_check_env_motor_mode_without_camera(make_env):
    env = make_env(HOVER_ID, camera=False, action_mode="motors")
    check_env(env.unwrapped, skip_render_check=True)
    assert "image" not in env.observation_space.spaces


def test_make_in_fresh_interpreter():
    code = (
        "import gymnasium as gym, ihrcf_env; e = gym.make('ihrcf_env/DeckHoverRaw-v0', camera=False); "
        "o, i = e.reset(seed=0); print(sorted(o)); e.close()"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "ranges" in out.stdout


def test_same_seed_same_actions_bitwise_identical(make_env):
    kw = dict(deck_profile="sea_state", tof_noise="realistic", **SMALL)
    e1, e2 = make_env(HOVER_ID, **kw), make_env(HOVER_ID, **kw)
    s1, s2 = rollout(e1, 123, 60), rollout(e2, 123, 60)
    assert same_runs(s1, s2)
    # the same env reset with the same seed repeats itself too
    s3 = rollout(e1, 123, 60)
    assert same_runs(s1, s3)
    s4 = rollout(e2, 124, 60)
    assert not same_runs(s1, s4)


def test_seed_zero_is_a_seed(raw):
    env = raw(camera=False)
    _, i1 = env.reset(seed=0)
    _, i2 = env.reset(seed=0)
    np.testing.assert_array_equal(i1["drone_position_world"], i2["drone_position_world"])


def test_start_state_and_reset_options(raw):
    env = raw(camera=False)
    for seed in range(5):
        _, info = env.reset(seed=seed)
        h = -info["deck_position_body"][2]
        assert 0.9 < h < 1.1
    _, info = env.reset(seed=1, options={"altitude": 2.0, "offset": (0.0, 0.0), "yaw": 0.0})
    np.testing.assert_allclose(info["deck_position_body"], [0, 0, -2.0], atol=1e-6)
    np.testing.assert_allclose(info["deck_euler_body"], 0.0, atol=1e-9)
    with pytest.raises(ValueError, match="altitude"):
        env.reset(options={"altitude": -1.0})
    with pytest.raises(ValueError, match="unknown"):
        env.reset(options={"height": 1.0})


def test_info_ground_truth_contents(raw):
    env = raw(camera=False)
    _, info = env.reset(seed=3)
    _, r, term, trunc, info = env.step(np.zeros(4))
    for key in (
        "deck_position_body",
        "deck_euler_body",
        "drone_position_world",
        "drone_quaternion_world",
        "deck_position_world",
        "deck_quaternion_world",
        "leg_lengths",
        "contact_deck",
        "contact_ground",
        "reward_position",
        "reward_terminal",
    ):
        assert key in info
    assert info["leg_lengths"].shape == (6,)
    parts = sum(v for k, v in info.items() if k.startswith("reward_"))
    assert r == pytest.approx(parts)
    assert not term and not trunc


def test_out_of_range_actions_are_clipped(raw):
    e1, e2 = raw(camera=False), raw(camera=False)
    e1.reset(seed=5)
    e2.reset(seed=5)
    for _ in range(5):
        o1, *_ = e1.step(np.array([5.0, -7.0, 3.0, 2.0]))
        o2, *_ = e2.step(np.array([1.0, -1.0, 1.0, 1.0]))
    assert same(o1, o2)


@pytest.mark.parametrize("bad", [[np.nan, 0, 0, 0], [0, np.inf, 0, 0]])
def test_nan_or_inf_action_raises(raw, bad):
    env = raw(camera=False)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.array(bad, dtype=np.float64))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"camera_fov": 0.0}, "fov"),
        ({"camera_fov": -1.0}, "fov"),
        ({"camera_width": 0}, "width"),
        ({"camera_height": -5}, "height"),
        ({"deck_profile": "tsunami"}, "deck_profile"),
        ({"action_mode": "thoughts"}, "action_mode"),
        ({"control_hz": 7}, "control_hz"),
        ({"control_hz": 0}, "control_hz"),
        ({"tof_noise": "loud"}, "tof_noise"),
        ({"tof_max_range": 0.0}, "max_range"),
        ({"tag_size": -0.1}, "tag_size"),
        ({"tag_size": 2.0}, "tag_size"),
        ({"tag_id": 100000}, "tag_id"),
        ({"render_mode": "ascii"}, "render_mode"),
        ({"max_velocity": (1.0, 1.0, 0.0, 1.0)}, "max_velocity"),
        ({"sea_state_amplitudes": {"wobble": 1.0}, "deck_profile": "sea_state"}, "unknown"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*render_mode.*:UserWarning")  # gymnasium warns before our ValueError
def test_bad_config_raises_at_make(kwargs, name):
    with pytest.raises(ValueError, match=name):
        gym.make(HOVER_ID, **kwargs)


def test_profile_exceeding_stroke_raises_naming_time_and_leg(raw):
    env = raw(camera=False, deck_profile=lambda t: (np.array([0.0, 0.0, 0.05 * t]), np.zeros(3)))
    with pytest.raises(ValueError, match=r"t = .* s: leg \d"):
        env.reset(seed=0)


def test_landing_by_descending_slowly_succeeds(raw):
    env = raw(camera=False, deck_profile="static")
    term, _, info = descend(env, {"altitude": 0.6, "offset": (0.0, 0.0), "yaw": 0.0}, 0.3, steps=400)
    assert term and info["outcome"] == "success", info.get("crash_reason")
    assert info["touchdown"]["body"] == "deck"
    assert info["reward_terminal"] == 100.0


def test_fast_descent_is_a_crash_and_not_a_truncation(raw):
    env = raw(camera=False, deck_profile="static", max_velocity=(1.0, 1.0, 3.0, 1.0))
    term, trunc, info = descend(env, {"altitude": 1.5, "offset": (0.0, 0.0), "yaw": 0.0}, 1.0, steps=200)
    assert not trunc
    assert term and info["outcome"] == "crash"
    assert "vertical speed" in info["crash_reason"]
    assert info["reward_terminal"] == -100.0


def test_landing_beside_the_deck_is_a_crash(raw):
    env = raw(camera=False, deck_profile="static")
    term, _, info = descend(env, {"altitude": 0.5, "offset": (1.5, 0.0), "yaw": 0.0}, 1.0, steps=600)
    assert term and info["outcome"] == "crash"


def test_truncation_only_by_max_episode_steps(make_env):
    env = make_env(HOVER_ID, camera=False, max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(np.zeros(4))[3] for _ in range(5)]
    assert flags == [False, False, False, False, True]


def test_rgb_array_render_and_double_close(make_env):
    env = make_env(HOVER_ID, render_mode="rgb_array", camera=False, chase_size=(160, 120))
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 5  # something is drawn
    env.close()
    env.close()


def test_observations_are_finite_and_in_space(make_env):
    env = make_env(HOVER_ID, tof_noise="realistic", **SMALL)
    obs, _ = env.reset(seed=9)
    rng = np.random.default_rng(0)
    for _ in range(40):
        obs, *_ = env.step(rng.uniform(-1, 1, 4))
        assert env.observation_space.contains(obs)
        assert np.all(np.isfinite(obs["ranges"]))


def test_tilt_crash_in_motor_mode(raw):
    env = raw(camera=False, action_mode="motors")
    env.reset(seed=0, options={"altitude": 2.0})
    for _ in range(100):
        _, _, term, _, info = env.step(np.array([1.0, -1.0, -1.0, 1.0]))  # roll hard
        if term:
            break
    assert term and info["outcome"] == "crash"
    assert math.isfinite(info["reward_terminal"])


def test_random_deck_start_is_seeded_and_deck_time_option_sets_it(raw):
    from ihrcf_env.core.profiles import paper_profile

    env = raw(camera=False, random_deck_start=True)
    _, a = env.reset(seed=4)
    _, b = env.reset(seed=4)
    _, c = env.reset(seed=5)
    np.testing.assert_array_equal(a["deck_quaternion_world"], b["deck_quaternion_world"])
    assert not np.array_equal(a["deck_quaternion_world"], c["deck_quaternion_world"])
    _, d = env.reset(seed=0, options={"deck_time": 37.0})
    off, rpy = paper_profile()(37.0)
    home = env.config.world.stewart.home_position
    np.testing.assert_allclose(d["deck_position_world"], home + off, atol=1e-6)
    with pytest.raises(ValueError, match="deck_time"):
        env.reset(options={"deck_time": -1.0})


def test_drone_state_is_the_truth_of_info_with_velocity_and_body_rates(
    make_env: Callable[..., gym.Env],
) -> None:
    """``drone_state()`` (through the wrappers): the world pose of ``info``, the world velocity
    (against the positions' change over a step) and the body rates (a yaw-rate command turns it)."""
    env = make_env("ihrcf_env/DeckLanding-v1", camera_model="projected")
    env.reset(seed=4)
    positions = []
    for _ in range(8):
        _, _, _, _, info = env.step(np.array([0.5, -0.3, 0.2, 0.6], np.float32))
        positions.append(np.asarray(info["drone_position_world"]))
    s = env.get_wrapper_attr("drone_state")()
    assert s.time == pytest.approx(info["time"])
    np.testing.assert_allclose(s.position, info["drone_position_world"])
    np.testing.assert_allclose(s.quaternion, info["drone_quaternion_world"])
    dt = 1.0 / env.unwrapped.config.world.control_hz
    np.testing.assert_allclose(s.velocity, (positions[-1] - positions[-2]) / dt, atol=0.05)
    assert s.rates[2] > 0.05  # turning left (a positive yaw-rate command), nearly level
