"""Extension from user code: an estimator, a sensor and a noise model registered without editing
the package, chosen by option, seen in the observation."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.core.estimators import PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.registry import ESTIMATORS, EstimatorConfig
from ihrcf_env.sim import registry


class RangeMean:
    """Toy estimator: the deck straight below at the mean of the valid ranges."""

    name = "range_mean"

    def __init__(self, config: EstimatorConfig) -> None:
        self.camera_z = config.rig.camera_position[2]

    def reset(self) -> None:
        pass

    def update(self, frame: SensorFrame) -> PoseEstimate:
        if not frame.ranges_valid.any():
            return PoseEstimate.invalid("no valid range")
        depth = float(np.mean(frame.ranges[frame.ranges_valid]))
        return PoseEstimate.from_body_pose(np.eye(3), [0.0, 0.0, self.camera_z - depth], 0.0)


class Altimeter:
    """Toy sensor: the drone's true altitude (m), 10 Hz at a 20 Hz control rate."""

    name = "altimeter"
    update_interval = 2

    def reset(self, rng: np.random.Generator) -> None:
        self.offset = float(rng.normal(0.0, 0.01))

    def read(self, state: Any, dt: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
        return {"altitude": np.array([state.position[2] + self.offset])}


class Spikes:
    """Toy noise model: adds +1 to every value."""

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def apply(self, value: Any, valid: Any, dt: float, rng: np.random.Generator) -> tuple[Any, Any]:
        return value + 1.0, valid


@pytest.fixture
def registered() -> Iterator[None]:
    ihrcf_env.register_estimator("range_mean", RangeMean)
    ihrcf_env.register_sensor(
        "altimeter", lambda world: Altimeter(), {"altitude": registry.SensorOutput((1,), -10.0, 100.0)}
    )
    ihrcf_env.register_noise_model("spikes", lambda size: Spikes())
    try:
        yield
    finally:
        ESTIMATORS.pop("range_mean", None)
        registry.SENSORS.pop("altimeter", None)
        registry.NOISE_MODELS.pop("spikes", None)


def test_user_estimator_sensor_and_noise_model(registered: None, make_env: Any) -> None:
    env = make_env(
        ihrcf_env.HOVER_ID,
        camera_model="projected",
        estimators=("ihrcf", "range_mean"),
        sensors=("altimeter",),
        measurement_noise={"ranges": "spikes"},
    )
    plain = make_env(ihrcf_env.HOVER_ID, camera_model="projected", estimators=("ihrcf",))
    obs, info = env.reset(seed=0)
    ref, ref_info = plain.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["range_mean"]["valid"] == 1 and "range_mean_reason" in info
    np.testing.assert_allclose(obs["ranges"], np.minimum(ref["ranges"] + 1.0, 4.0), atol=1e-6)
    assert obs["altitude"].shape == (1,)
    assert obs["altitude"][0] == pytest.approx(info["drone_position_world"][2], abs=0.05)
    first = obs["altitude"].copy()
    obs, *_ = env.step(np.array([0, 0, 1, 0], np.float32))  # climb: the 10 Hz altimeter holds
    np.testing.assert_array_equal(obs["altitude"], first)
    obs, *_ = env.step(np.array([0, 0, 1, 0], np.float32))
    assert obs["altitude"][0] > first[0]
    # paired: the extension draws from its own streams, the episode is the same
    np.testing.assert_array_equal(info["drone_position_world"], ref_info["drone_position_world"])


def test_bad_registrations_and_options_are_named(registered: None) -> None:
    from ihrcf_env.config.make import make_config

    with pytest.raises(ValueError, match="already registered"):
        ihrcf_env.register_estimator("range_mean", RangeMean)
    with pytest.raises(ValueError, match="reserved"):
        ihrcf_env.register_estimator("ground_truth", RangeMean)
    with pytest.raises(ValueError, match="taken by the env"):
        ihrcf_env.register_sensor("baro", Altimeter, {"ranges": registry.SensorOutput((4,), 0.0, 1.0)})
    with pytest.raises(TypeError, match="callable"):
        ihrcf_env.register_noise_model("bad", 3)
    with pytest.raises(ValueError, match="sensors: unknown sensor 'lidar'"):
        make_config(raw=True, sensors=("lidar",))
    with pytest.raises(ValueError, match="measurement_noise: no measurement 'pressure'"):
        make_config(raw=True, measurement_noise={"pressure": "spikes"})
    with pytest.raises(ValueError, match="unknown noise model 'hail'"):
        make_config(raw=True, measurement_noise={"ranges": "hail"})
