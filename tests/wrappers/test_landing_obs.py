"""The RL observation of DeckLanding-v1: one float32 Box, named slices, no ground truth by default,
check_env (Gymnasium, and SB3 when installed), is_success, determinism, held estimates."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from ihrcf_env.core.estimators import PoseEstimate
from ihrcf_env.wrappers.landing_obs import (
    MAX_AGE,
    POSITION_SCALE,
    LandingObservation,
    heading_rotation,
    landing_obs_fields,
)


def test_layout_is_documented_and_contiguous() -> None:
    slices, scales, low, high = landing_obs_fields()
    assert slices["all"] == slice(0, 50) and low.shape == high.shape == (50,)
    assert GROUND_TRUTH_FREE(slices)
    assert slices["ranges"] == slice(0, 4) and slices["nav_velocity"] == slice(17, 20)
    assert (
        slices["ihrcf"] == slice(20, 30)
        and slices["atda"] == slice(30, 40)
        and slices["fused"] == slice(40, 50)
    )
    assert slices["fused.position"] == slice(40, 43) and slices["fused.age"] == slice(49, 50)
    assert scales["ranges"] == 4.0 and scales["fused.position"] == POSITION_SCALE
    covered = np.zeros(50, int)
    for name, sl in slices.items():
        if "." in name or name in ("ranges", "ranges_valid", "nav_velocity"):
            covered[sl] += 1
    assert np.all(covered == 1)  # the leaf fields tile the vector exactly once
    assert np.all(low < high)
    p_slices, _, p_low, _ = landing_obs_fields(privileged=True)
    assert p_slices["all"] == slice(0, 64) and p_slices["ground_truth"] == slice(50, 64)
    assert np.array_equal(p_low[:50], low)


def GROUND_TRUTH_FREE(slices: dict[str, slice]) -> bool:
    return not any(k.startswith("ground_truth") for k in slices)


def test_check_env_passes_without_warnings(make_v1) -> None:
    env = make_v1()
    assert isinstance(env.observation_space, spaces.Box) and env.observation_space.dtype == np.float32
    assert env.observation_space.shape == (50,)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)  # the raw v1 env
        check_env(env, skip_render_check=True)  # as made (wrappers, TimeLimit)
    ours = [str(w.message) for w in caught if "different from the unwrapped" not in str(w.message)]
    assert ours == [], ours


@pytest.mark.rl  # needs stable-baselines3: runs in the [rl] venv (`pytest -m rl`, .ci/run)
def test_sb3_check_env(make_v1) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = make_v1()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env, warn=True)
    assert [str(w.message) for w in caught] == []


def test_no_ground_truth_by_default_and_privileged_block(make_v1) -> None:
    """The default observation equals the first 50 values of the privileged one; the 14 more are
    the true deck pose (heading frame), relative velocity and wind, as in info."""
    env, priv = make_v1(), make_v1(privileged=True)
    assert GROUND_TRUTH_FREE(env.get_wrapper_attr("obs_slices"))
    assert priv.observation_space.shape == (64,)
    obs, info = env.reset(seed=5)
    pobs, pinfo = priv.reset(seed=5)
    for _ in range(5):
        a = np.array([0.2, -0.1, -0.2, 0.0], np.float32)
        obs, *_, info = env.step(a)
        pobs, *_, pinfo = priv.step(a)
    assert np.array_equal(obs, pobs[:50])
    s = priv.get_wrapper_attr("obs_slices")
    R_lb, R_lw = heading_rotation(pinfo["drone_quaternion_world"])
    assert pobs[s["ground_truth.position"]] * POSITION_SCALE == pytest.approx(
        R_lb @ pinfo["deck_position_body"], abs=1e-5
    )
    assert pobs[s["ground_truth.velocity"]] == pytest.approx(R_lw @ pinfo["relative_velocity"], abs=1e-5)
    assert pobs[s["ground_truth.wind"]] == pytest.approx(R_lw @ pinfo["wind_velocity"], abs=1e-5)
    # ground truth is always in info, whatever the observation
    for key in ("deck_position_body", "deck_euler_body", "drone_position_world", "relative_velocity"):
        assert key in info


def test_estimate_blocks_decode_to_the_estimates(make_v1) -> None:
    env = make_v1(wind=False)  # calm: the tag stays in view of a hovering drone
    obs, info = env.reset(seed=2)
    for _ in range(15):  # the fused filter converges in 10 frames
        obs, *_, info = env.step(np.zeros(4, np.float32))
    s, sc = env.get_wrapper_attr("obs_slices"), env.get_wrapper_attr("obs_scales")
    assert env.observation_space.contains(obs)
    assert obs[s["fused.valid"]][0] == 1.0 and obs[s["atda.valid"]][0] == 1.0
    # the estimate, in the heading frame, is close to the truth (a few cm at ~2 m)
    R_lb, _ = heading_rotation(info["drone_quaternion_world"])
    truth = R_lb @ info["deck_position_body"]
    assert obs[s["fused.position"]] * sc["fused.position"] == pytest.approx(truth, abs=0.1)
    assert obs[s["fused.normal"]][2] > 0.97  # the deck tilts a few degrees
    assert math.hypot(*obs[s["fused.yaw"]]) == pytest.approx(1.0, abs=1e-5)
    assert obs[s["fused.age"]][0] == pytest.approx(info["fused_age"])
    assert np.linalg.norm(obs[s["imu.up"]]) == pytest.approx(1.0, abs=1e-5)
    assert obs[s["imu.linear_acceleration"]][2] == pytest.approx(1.0, abs=0.1)  # hovering
    assert np.all(obs[s["ranges_valid"]] == np.isin(obs[s["ranges_valid"]], (0.0, 1.0)))


def test_is_success_and_determinism(make_v1) -> None:
    env = make_v1()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (12, 4)).astype(np.float32)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=11)
        assert info["is_success"] is False
        seq = [obs]
        for a in actions:
            obs, _, terminated, truncated, info = env.step(a)
            assert "is_success" in info and info["is_success"] == (info["outcome"] == "success")
            seq.append(obs)
        runs.append(np.array(seq))
    assert runs[0].tobytes() == runs[1].tobytes()  # bitwise equal
    other, _ = env.reset(seed=12)
    assert not np.array_equal(other, runs[0][0])


class _FakeStage:
    """Stands in for the estimator stage: scripted validity of the fused estimate per step."""

    def __init__(self, valid: list[int]) -> None:
        self.valid = valid
        self.sources: dict[str, Any] = {}
        self.ages: dict[str, float] = {}
        self.k = 0

    @property
    def time(self) -> float:
        return self.k * 0.05

    def reset(self) -> None:
        self.k = 0

    def tick(self) -> None:
        self.k += 1

    @property
    def estimator(self) -> _FakeStage:
        return self  # its update(frame) gives the scripted estimates

    def prepare(self, observation: Any) -> str:
        return "frame"

    def update(self, frame: Any) -> dict[str, PoseEstimate]:
        v = bool(self.valid[min(self.k, len(self.valid) - 1)])
        p = np.array([0.1 * self.k, 0.0, -2.0])
        return {"fused": PoseEstimate(p, np.zeros(3), np.eye(3), v, 0.0, "" if v else "x")}

    def finish(self, estimates: dict[str, PoseEstimate]) -> dict[str, PoseEstimate]:
        self.ages = {"fused": 0.0}
        return estimates

    def add_info(self, info: dict[str, Any]) -> None:
        pass


def _scripted(make_v1: Callable[..., gym.Env], valid: list[int]) -> LandingObservation:
    env = LandingObservation(make_v1(raw=True, camera_model="projected"), estimators=("fused",))
    env.stage = _FakeStage(valid)  # type: ignore[assignment]
    return env


def test_invalid_estimates_hold_the_last_values_and_age(make_v1) -> None:
    env = _scripted(make_v1, [1, 1, 0, 0, 0, 1])
    s = env.obs_slices
    obs, _ = env.reset(seed=0)
    assert obs[s["fused.valid"]][0] == 1.0 and obs[s["fused.age"]][0] == 0.0
    obs, *_ = env.step(np.zeros(4))
    held = obs[s["fused.position"]].copy()
    assert np.linalg.norm(held) * POSITION_SCALE == pytest.approx(math.hypot(0.1, 2.0), abs=1e-5)
    for k in (2, 3, 4):  # invalid: the values of step 1 stay, their age grows
        obs, *_ = env.step(np.zeros(4))
        assert obs[s["fused.valid"]][0] == 0.0
        assert np.array_equal(obs[s["fused.position"]], held)
        assert obs[s["fused.age"]][0] == pytest.approx(0.05 * (k - 1))
    obs, *_ = env.step(np.zeros(4))  # valid again
    assert obs[s["fused.valid"]][0] == 1.0 and obs[s["fused.age"]][0] == 0.0
    assert np.linalg.norm(obs[s["fused.position"]]) * POSITION_SCALE == pytest.approx(
        math.hypot(0.5, 2.0), abs=1e-5
    )
    never = _scripted(make_v1, [0])  # never valid: zeros and the largest age
    obs, _ = never.reset(seed=0)
    assert np.all(obs[s["fused.position"]] == 0) and obs[s["fused.age"]][0] == MAX_AGE


def test_bad_wrapper_options(make_v1) -> None:
    with pytest.raises(TypeError, match="privileged"):
        make_v1(privileged="yes")
    with pytest.raises(ValueError, match="privileged"):
        make_v1(raw=True, privileged=True)
    with pytest.raises(TypeError, match="max_residual"):
        make_v1(max_residual="0.01")
    raw = make_v1(raw=True, camera_model="projected")
    with pytest.raises(TypeError, match="privileged"):
        LandingObservation(raw, privileged=1)  # type: ignore[arg-type]


def test_the_tag_is_in_view_at_the_start(make_v1) -> None:
    """ATDA (tag corners + K) is valid at reset: on drawn starts and on the worst corner of the start
    region (lowest altitude, largest offset, along the image diagonal)."""
    env = make_v1()
    base = env.unwrapped
    s = env.get_wrapper_attr("obs_slices")
    for seed in range(8):
        obs, info = env.reset(seed=seed)
        assert obs[s["atda.valid"]][0] == 1.0, (seed, info["atda_reason"])
    r = base.start_radius(1.5)
    for yaw in (math.pi / 4, -3 * math.pi / 4):
        obs, info = env.reset(seed=0, options={"altitude": 1.5, "offset": (r, 0.0), "yaw": yaw})
        assert obs[s["atda.valid"]][0] == 1.0, (yaw, info["atda_reason"])


def test_deck_motion_block_tracks_the_deck(make_v1) -> None:
    """deck_motion=True appends the fused filter's deck motion (6 values, heading frame): zeros until
    the filter converges, then the deck origin's velocity relative to the drone and the rate of the
    deck normal; with ideal sensors they follow the truth (measured MAE 2-9 mm/s, 0.03 1/s)."""
    slices, _, low, high = landing_obs_fields(deck_motion=True)
    assert slices["motion"] == slice(50, 56) and slices["all"] == slice(0, 56)
    assert slices["motion.velocity"] == slice(50, 53) and slices["motion.normal_rate"] == slice(53, 56)
    assert np.all(low[50:] == -20.0) and np.all(high[50:] == 20.0)
    env = make_v1(camera_model="projected", sensor_preset="ideal", deck_motion=True, wind=False)
    sl = env.get_wrapper_attr("obs_slices")
    world = env.unwrapped.world
    obs, _ = env.reset(seed=2)
    assert obs.shape == (56,) and not np.any(obs[sl["motion"]])  # not converged yet
    est, true, prev = [], [], None
    for k in range(120):
        obs, _, terminated, truncated, _ = env.step(np.zeros(4, np.float32))
        assert not (terminated or truncated)
        s = world.sensing.snapshot()
        _, R_lw = heading_rotation(s.drone_quaternion)
        if prev is not None and k >= 40:
            assert obs[sl["fused.valid"]][0] == 1.0
            v = (s.deck_position - prev) * 20.0 - s.drone_velocity  # 20 Hz control
            est.append(obs[sl["motion.velocity"]])
            true.append(R_lw @ v)
        prev = s.deck_position.copy()
    err = np.abs(np.array(est) - np.array(true)).mean(axis=0)
    assert np.all(err < 0.02), err
    assert np.corrcoef(np.array(est)[:, 2], np.array(true)[:, 2])[0, 1] > 0.8


def test_deck_motion_bad_options(make_v1) -> None:
    with pytest.raises(ValueError, match="deck_motion needs the fused estimator"):
        make_v1(camera_model="projected", deck_motion=True, estimators=("ihrcf", "atda"))
    with pytest.raises(TypeError, match="deck_motion must be True or False"):
        make_v1(camera_model="projected", deck_motion="yes")
    with pytest.raises(ValueError, match="deck_motion: observation-wrapper options have no effect"):
        make_v1(camera_model="projected", deck_motion=True, raw=True)
