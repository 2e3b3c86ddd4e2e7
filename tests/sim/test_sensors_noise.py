"""The sensor, noise-model and disturbance interfaces of the sim layer, and World's lifecycle."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from conftest import temp_dirs

from ihrcf_env.config.sensors import ToFConfig
from ihrcf_env.config.wind import Disturbance
from ihrcf_env.config.world import DeckConfig, WorldConfig
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.disturbances import ConstantForce
from ihrcf_env.sim.noise import Chain, Dropout, GaussianNoise, NoiseModel, NoNoise
from ihrcf_env.sim.sensors import IMU, Sensor
from ihrcf_env.sim.world import World

N = 4000


def test_gaussian_noise_statistics() -> None:
    rng = np.random.default_rng(1)
    m = GaussianNoise(0.02)
    out = np.array([m.apply(np.full(4, 1.5), np.ones(4, bool), 0.05, rng)[0] for _ in range(N // 4)]).ravel()
    assert abs(out.mean() - 1.5) < 0.1 * 0.02
    assert out.std() == pytest.approx(0.02, rel=0.1)


def test_dropout_rate_and_chain_order() -> None:
    rng = np.random.default_rng(2)
    chain = Chain((GaussianNoise(0.01), Dropout(0.2)))
    valid = np.concatenate([chain.apply(np.zeros(4), np.ones(4, bool), 0.05, rng)[1] for _ in range(N // 4)])
    assert (~valid).mean() == pytest.approx(0.2, rel=0.1)
    # same draws as Gaussian then dropout applied by hand (the ToF preset's order)
    a, b = np.random.default_rng(7), np.random.default_rng(7)
    v1, ok1 = chain.apply(np.ones(4), np.ones(4, bool), 0.05, a)
    v2 = np.ones(4) + b.normal(0.0, 0.01, 4)
    ok2 = ~(b.random(4) < 0.2)
    np.testing.assert_array_equal(v1, v2)
    np.testing.assert_array_equal(ok1, ok2)


def test_ideal_models_draw_nothing() -> None:
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    for m in (NoNoise(), GaussianNoise(0.0), Dropout(0.0)):
        v, ok = m.apply(np.arange(3.0), np.ones(3, bool), 0.05, rng)
        np.testing.assert_array_equal(v, np.arange(3.0))
        assert ok.all()
    assert rng.bit_generator.state == state


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_noise_parameters_validated(bad) -> None:
    with pytest.raises(ValueError, match="sigma"):
        GaussianNoise(bad)
    with pytest.raises(ValueError, match="probability"):
        Dropout(bad)
    with pytest.raises(ValueError, match="probability"):
        Dropout(1.5)


@pytest.mark.parametrize("bad", ["0.1", True, None])
def test_noise_parameters_of_the_wrong_type_are_named(bad) -> None:
    """The package's convention: a wrong type is a TypeError naming the parameter."""
    with pytest.raises(TypeError, match="sigma"):
        GaussianNoise(bad)
    with pytest.raises(TypeError, match="probability"):
        Dropout(bad)


@pytest.fixture
def world(make_world) -> World:
    w = make_world(WorldConfig(camera=None))
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    return w


def test_sensors_share_one_interface_and_read_named_arrays(world: World) -> None:
    assert list(world.sensors) == ["tof", "imu"]
    assert all(isinstance(s, Sensor) for s in world.sensors.values())
    assert isinstance(GaussianNoise(0.1), NoiseModel) and isinstance(Chain(()), NoiseModel)
    out = world.sensing.read_sensors(np.random.default_rng(0))
    assert set(out) == {"ranges", "ranges_valid", "quaternion", "angular_velocity", "linear_acceleration"}
    assert out["linear_acceleration"][2] == pytest.approx(GRAVITY, abs=1e-6)  # hovering at rest
    assert out["ranges"] == pytest.approx(np.full(4, 0.97), abs=1e-3)  # 1 m less the camera 3 cm below


def test_camera_is_a_sensor_too(make_world) -> None:
    w = make_world(WorldConfig())
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    assert list(w.sensors) == ["camera", "tof", "imu"]
    img = w.sensing.read_sensors(np.random.default_rng(0), ("camera",))["image"]
    assert img.shape == (512, 512, 3) and img.dtype == np.uint8 and img.min() < 50  # the tag is seen


def test_imu_noise_is_pluggable(world: World) -> None:
    world.imu_sensor.gyro_noise = GaussianNoise(0.01)
    world.imu_sensor.accel_noise = GaussianNoise(0.1)
    rng = np.random.default_rng(4)
    g = np.array([world.sensing.read_sensors(rng, ("imu",))["angular_velocity"] for _ in range(N // 3)])
    a = np.array([world.sensing.read_sensors(rng, ("imu",))["linear_acceleration"] for _ in range(N // 3)])
    assert g.std(axis=0) == pytest.approx(np.full(3, 0.01), rel=0.1)
    assert a.std(axis=0) == pytest.approx(np.full(3, 0.1), rel=0.1)
    assert isinstance(IMU(), Sensor)


def test_tof_noise_is_pluggable(make_world) -> None:
    w = make_world(WorldConfig(camera=None, tof=ToFConfig(noise="ideal")))
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    w.tof.noise = Dropout(1.0)
    _, valid = w.sensing.read_tof(np.random.default_rng(0))
    assert not valid.any()


def test_disturbance_hook_pushes_the_drone(world: World) -> None:
    """Motors at hover thrust, level: a +2 N x force gives F/m of acceleration (minus drag)."""
    assert isinstance(ConstantForce((2.0, 0.0, 0.0)), Disturbance)
    world.add_disturbance(ConstantForce((2.0, 0.0, 0.0)))
    world.set_motor_thrusts(np.full(4, world.config.quad.mass * GRAVITY / 4 / world.config.quad.max_thrust))
    x0 = world.drone_pose()[0][0]
    for _ in range(4):  # 0.2 s
        world.step()
    x1 = world.drone_pose()[0][0]
    expected = 0.5 * 2.0 / world.config.quad.mass * 0.2**2
    assert x1 - x0 == pytest.approx(expected, rel=0.05)
    with pytest.raises(TypeError, match="disturbance"):
        world.add_disturbance(lambda t, pos, vel: (0, 0, 0))  # type: ignore[arg-type]


def test_failed_world_construction_leaks_nothing(private_tmp) -> None:
    before = temp_dirs()
    probe = p.connect(p.DIRECT)
    p.disconnect(physicsClientId=probe)
    with pytest.raises(ValueError, match="tag_id"):
        World(WorldConfig(camera=None, deck=DeckConfig(tag_id=-1)))
    assert p.getConnectionInfo(physicsClientId=probe)["isConnected"] == 0
    # the failed world's client (the next id) is disconnected again
    assert all(p.getConnectionInfo(physicsClientId=probe + k)["isConnected"] == 0 for k in range(1, 3))
    assert temp_dirs() == before


def test_closed_world_says_so() -> None:
    w = World(WorldConfig(camera=None))
    w.close()
    w.close()  # idempotent
    assert w.closed
    for call in (w.step, w.sensing.snapshot, w.sensing.body_state):
        with pytest.raises(RuntimeError, match="closed"):
            call()


def test_imu_attitude_noise_is_pluggable(world: World) -> None:
    from ihrcf_env.sim.sensors.imu import AttitudeError

    world.imu_sensor.attitude_noise = AttitudeError(0.01, 1.0, 0.0)
    world.imu_sensor.reset(np.random.default_rng(5))
    q = world.sensing.read_sensors(np.random.default_rng(6), ("imu",))["quaternion"]
    q_true = world.sensing.body_state().quaternion
    assert np.linalg.norm(q) == pytest.approx(1.0)
    assert 0 < 2 * np.arccos(min(1.0, abs(float(q @ q_true)))) < 0.1


def test_realistic_tof_takes_extra_noise_too(make_world) -> None:
    w = make_world(WorldConfig(camera=None, tof=ToFConfig(noise="realistic")))
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    assert isinstance(w.tof.noise, NoNoise)
    w.tof.noise = Dropout(1.0)
    _, valid = w.sensing.read_tof(np.random.default_rng(0))
    assert not valid.any()
