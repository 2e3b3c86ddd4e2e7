"""What a hostile user tries: absurd magnitudes, odd actions and reset options, disturbances that
return garbage. Each gets a clear error naming the thing, never NaN in an observation."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import ihrcf_env

RAW = {"camera": False}


@pytest.mark.parametrize(
    ("options", "name"),
    [
        (
            {"reward_weights": dict.fromkeys(("distance", "height", "speed", "time", "success"), 1e308)},
            "reward",
        ),
        ({"reward_weights": {"crash": math.inf}}, "crash"),
        ({"autopilot_feedback": {"horizontal_sigma": 1e200}}, "horizontal_sigma"),
        ({"autopilot_feedback": {"velocity_noise": 1e300}}, "velocity_noise"),
        ({"autopilot_feedback": {"position_time_constant": 1e-170}}, "position_time_constant"),
        ({"wind": {"turbulence": 1e200}}, "turbulence"),
        ({"wind": {"height": 1e300}}, "height"),
        ({"tof_noise": {"sigma_floor": 1e300}}, "sigma_floor"),
        ({"tof_noise": {"offset_sigma": 1e300}}, "offset_sigma"),
        ({"tof_noise": {"dark_range": 1e300}}, "dark_range"),
        ({"imu_noise": {"tilt_sigma": 1e300}}, "tilt_sigma"),
        ({"imu_noise": {"yaw_drift_rate": 1e300}}, "yaw_drift_rate"),
        ({"max_velocity": (1e300, 1.0, 1.0, 1.0)}, "max_velocity"),
        ({"start_offset": 1e300}, "start_offset"),
        ({"arena_half_width": 1e300}, "arena_half_width"),
        ({"tof_max_range": 1e300}, "tof_max_range"),
        ({"control_hz": 10**400}, "control_hz"),
        ({"camera_width": 10**9}, "camera_width"),
    ],
)
def test_absurd_magnitudes_are_refused_by_name(options: dict[str, Any], name: str) -> None:
    from ihrcf_env.config.make import make_config

    with pytest.raises((TypeError, ValueError), match=name):
        make_config(task="landing-v1", raw=True, **options)


@pytest.mark.parametrize(
    "action",
    [np.array([1j, 0, 0, 0]), ["a", "b", "c", "d"], np.array(["0", "0", "0", "0"]), [object()] * 4, None],
)
def test_non_real_actions_are_refused(make_env: Any, action: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, **RAW)
    env.reset(seed=0)
    with pytest.raises((TypeError, ValueError), match="action"):
        env.step(action)


@pytest.mark.parametrize("options", ["abc", 5, ["altitude"], {3: 1.0}])
def test_reset_options_of_the_wrong_kind_are_named(make_env: Any, options: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, **RAW)
    with pytest.raises((TypeError, ValueError), match="reset options"):
        env.reset(seed=0, options=options)


class _Bad:
    def __init__(self, value: Any) -> None:
        self.value = value

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(self, t: float, position: Any, velocity: Any) -> Any:
        return self.value

    def __repr__(self) -> str:
        return f"_Bad({self.value!r})"


@pytest.mark.parametrize(
    "value", [(math.nan, 0.0, 0.0), (1.0, 0.0), (1.0, 0.0, 0.0, 0.0), "xyz", (1e9, 0, 0)]
)
def test_a_disturbance_returning_garbage_is_named(make_env: Any, value: Any) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, disturbances=[_Bad(value)], **RAW)
    env.reset(seed=0)
    with pytest.raises((TypeError, ValueError), match="_Bad"):
        env.step(np.zeros(4, np.float32))


def test_observations_stay_finite_at_the_bounds(make_env: Any) -> None:
    """The largest accepted noise magnitudes still give finite observations."""
    env = make_env(
        ihrcf_env.LANDING_V1_ID,
        camera_model="projected",
        tof_noise={"ambient": 1.0},
        wind={"mean_speed_min": 20.0, "mean_speed_max": 20.0, "turbulence": 2.0},
    )
    obs, _ = env.reset(seed=0)
    for _ in range(20):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and math.isfinite(reward)
        if terminated or truncated:
            break
