"""Realistic sensing in the sim layer: noise-model statistics, the VL53L1X cone ToF, the BMI088 IMU
and attitude error, the GNSS/INS navigation estimate the autopilot flies on, and the ideal models
drawing nothing."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.sensors import VL53L1X, IMUConfig, IMUNoise, ToFConfig
from ihrcf_env.config.vehicle import NavigationConfig, NavigationErrors
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim.navigation import GNSSINSNavigation, TruthNavigation, make_navigation
from ihrcf_env.sim.noise import BiasRandomWalk, ConstantBias, GaussMarkov, WhiteNoise
from ihrcf_env.sim.sensors.base import BodyState
from ihrcf_env.sim.sensors.imu import IMU, AttitudeError
from ihrcf_env.sim.world import World

DT = 0.05  # the default control period
REL = 0.1  # statistics within 10 %


def _apply(model, n: int, rng: np.random.Generator, dt: float = DT, size: int = 3) -> np.ndarray:
    ok = np.ones(size, bool)
    return np.array([model.apply(np.zeros(size), ok, dt, rng)[0] for _ in range(n)])


# -- noise models: statistics against their parameters (>= 1000 samples, within 10 %) ----------------
def test_white_noise_std_is_density_times_sqrt_rate() -> None:
    density = (0.16e-3 * GRAVITY, 0.16e-3 * GRAVITY, 0.19e-3 * GRAVITY)  # BMI088 accel, m/s^2/sqrt(Hz)
    out = _apply(WhiteNoise(density), 3000, np.random.default_rng(1))
    assert out.std(axis=0) == pytest.approx(np.array(density) * math.sqrt(1 / DT), rel=REL)
    assert np.abs(out.mean(axis=0)).max() < 0.1 * out.std()
    # discretised at the rate it is sampled: 4x the rate, 2x the sigma
    out4 = _apply(WhiteNoise(1.0, size=1), 2000, np.random.default_rng(2), dt=DT / 4, size=1)
    assert out4.std() == pytest.approx(math.sqrt(4 / DT), rel=REL)


def test_constant_bias_is_drawn_at_reset_and_then_constant() -> None:
    m = ConstantBias(0.02, size=2000)
    rng = np.random.default_rng(3)
    m.reset(rng)
    a = _apply(m, 3, rng, size=2000)
    assert np.array_equal(a[0], a[2])
    assert a[0].std() == pytest.approx(0.02, rel=REL)
    m.reset(rng)
    assert not np.array_equal(m.bias, a[0])


def test_bias_random_walk_increments() -> None:
    sigma = 0.003
    m = BiasRandomWalk(sigma, initial_sigma=0.01)
    rng = np.random.default_rng(4)
    m.reset(rng)
    b = _apply(m, 2000, rng)
    inc = np.diff(b, axis=0).ravel()
    assert inc.std() == pytest.approx(sigma * math.sqrt(DT), rel=REL)
    assert abs(inc.mean()) < 0.1 * inc.std()
    starts = []
    for _ in range(1500):
        m.reset(rng)
        starts.append(m.bias[0])
    assert np.std(starts) == pytest.approx(0.01, rel=REL)


def test_gauss_markov_stationary_std_and_correlation() -> None:
    sigma, tau, n = 0.05, 2.0, 3000
    m = GaussMarkov(sigma, tau, size=n)  # n independent processes
    rng = np.random.default_rng(5)
    m.reset(rng)
    b0 = m.bias.copy()
    assert b0.std() == pytest.approx(sigma, rel=REL)
    b = _apply(m, 40, rng, size=n)  # 2 s later
    for k in (1, 10, 40):
        assert b[k - 1].std() == pytest.approx(sigma, rel=REL)  # stationary
        corr = np.corrcoef(b0, b[k - 1])[0, 1]
        assert corr == pytest.approx(math.exp(-k * DT / tau), rel=REL)


@pytest.mark.parametrize(
    "make",
    [
        lambda: WhiteNoise(-1.0),
        lambda: WhiteNoise((1.0, 2.0)),
        lambda: ConstantBias(math.nan),
        lambda: BiasRandomWalk(0.1, size=0),
        lambda: GaussMarkov(0.1, 0.0),
        lambda: GaussMarkov(-0.1, 1.0),
    ],
)
def test_noise_model_parameters_are_checked(make) -> None:
    with pytest.raises(ValueError):
        make()


# -- IMU -----------------------------------------------------------------------------------------------
def _hover_state() -> BodyState:
    return BodyState(
        time=0.0,
        position=np.zeros(3),
        rotation=np.eye(3),
        quaternion=np.array([0.0, 0.0, 0.0, 1.0]),
        velocity=np.zeros(3),
        angular_velocity=np.zeros(3),
        acceleration=np.zeros(3),
    )


def test_realistic_imu_white_noise_and_turn_on_bias_match_the_bmi088_figures() -> None:
    fig = IMUNoise()
    imu = IMU.from_config(IMUConfig("realistic"))
    rng = np.random.default_rng(6)
    imu.reset(rng)
    state = _hover_state()
    reads = [imu.read(state, DT, rng) for _ in range(1500)]
    gyro = np.array([r["angular_velocity"] for r in reads])
    accel = np.array([r["linear_acceleration"] for r in reads])
    # over 75 s the bias instability (2 deg/h, 0.2 mg) is far below the white noise
    assert gyro.std(axis=0) == pytest.approx(np.full(3, fig.gyro_noise_density / math.sqrt(DT)), rel=REL)
    assert accel.std(axis=0) == pytest.approx(np.array(fig.accel_noise_density) / math.sqrt(DT), rel=REL)
    # turn-on biases: one per episode, N(0, datasheet offset^2)
    g0, a0 = [], []
    for _ in range(400):
        imu.reset(rng)
        r = imu.read(state, DT, rng)
        g0.append(r["angular_velocity"])
        a0.append(r["linear_acceleration"] - [0, 0, GRAVITY])
    assert np.std(g0) == pytest.approx(
        math.hypot(fig.gyro_turn_on_bias, fig.gyro_noise_density / math.sqrt(DT)), rel=REL
    )
    assert np.std(a0) == pytest.approx(fig.accel_turn_on_bias, rel=REL)


def test_attitude_error_tilt_and_yaw_drift_statistics() -> None:
    fig = IMUNoise()
    att = AttitudeError(fig.tilt_sigma, fig.tilt_time_constant, fig.yaw_drift_rate)
    rng = np.random.default_rng(7)
    q_true = np.array([0.1, -0.2, 0.3, 0.9])
    q_true /= np.linalg.norm(q_true)
    tilt, yaw, angle = [], [], []
    for _ in range(1200):
        att.reset(rng)
        for _ in range(20):  # 1 s
            q, _ = att.apply(q_true, np.ones(4, bool), DT, rng)
        tilt.append(att.error[:2])
        yaw.append(att.error[2])
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
        angle.append(2 * math.acos(min(1.0, abs(float(q @ q_true)))))
    assert np.std(tilt, axis=0) == pytest.approx(np.full(2, fig.tilt_sigma), rel=REL)
    assert np.std(yaw) == pytest.approx(fig.yaw_drift_rate * 1.0, rel=REL)
    # the reported quaternion is off the truth by exactly the error rotation
    assert np.mean(angle) == pytest.approx(
        np.mean(np.linalg.norm(np.column_stack([tilt, yaw]), axis=1)), rel=1e-6
    )


def test_ideal_imu_and_tof_draw_nothing_and_pass_the_truth(make_world) -> None:
    w = make_world(WorldConfig(camera=None))
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    w.reset_random(SeedStreams(8))  # the world draws the episode's streams; ideal sensors none
    rng = np.random.default_rng(8)
    state = rng.bit_generator.state
    out = w.sensing.read_sensors(rng)
    assert rng.bit_generator.state == state
    s = w.sensing.body_state()
    np.testing.assert_array_equal(out["quaternion"], s.quaternion)
    assert isinstance(w.navigation, TruthNavigation)
    true = ((1.0, 2.0, 3.0), (0.1, 0.2, 0.3))
    est = w.navigation.estimate(0.5, *true)
    assert est[0] is true[0] and est[1] is true[1]
    np.testing.assert_array_equal(w.nav_velocity(), s.velocity)
    np.testing.assert_array_equal(w.nav_position(), s.position)


# -- ToF: the VL53L1X cone --------------------------------------------------------------------------
@pytest.fixture
def tof_world(make_world) -> World:
    w = make_world(WorldConfig(camera=None, tof=ToFConfig(noise=VL53L1X(dropout=0.0))))
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    return w


def _place(w: World, x: float, y: float, z: float, quat=(0.0, 0.0, 0.0, 1.0)) -> None:
    p.resetBasePositionAndOrientation(w.quad.body, [x, y, z], quat, physicsClientId=w.client)


def test_cone_reads_a_perpendicular_plane_at_its_distance(tof_world: World) -> None:
    pos, R = tof_world.drone_pose()
    true, _ = tof_world.tof.true_ranges(pos, R)
    cone, signal = tof_world.tof.cone_ranges(pos, R)
    np.testing.assert_allclose(cone, true, atol=1e-9)  # the sensor's flat-target calibration
    m = tof_world.tof.model
    assert m is not None and m.rays == 16
    # the signal is rho cos^3 / d^2 averaged over the cone
    assert signal == pytest.approx(m.reflectance * np.mean(m.directions()[:, 2] ** 3) / 0.97**2, rel=1e-6)


def test_beam_straddling_the_deck_edge_mixes_deck_and_ground(tof_world: World) -> None:
    w = tof_world
    sensors = w.config.rig.sensor_positions_body
    i = int(np.argmax(sensors[:, 0] + sensors[:, 1]))  # the sensor towards +x, +y
    edge = w.deck.top_half_extent
    deck_z = w.deck.pose()[0][2]
    alt = 1.0
    readings = {}
    for shift in (-0.3, 0.0, 0.3):  # axis well inside, on the edge, well outside the deck
        _place(w, edge - sensors[i, 0] + shift, 0.0, deck_z + alt)
        pos, R = w.drone_pose()
        r, s = w.tof.cone_returns(pos, R)
        cone, _ = w.tof.cone_ranges(pos, R)
        readings[shift] = (cone[i], r[i], s[i])
    d_deck, d_out = readings[-0.3][0], readings[0.3][0]
    assert d_deck == pytest.approx(alt + sensors[i, 2], abs=1e-6)  # all on the deck
    assert d_out > d_deck + 0.3  # beyond the deck: ground (or the platform's base) much further
    mixed, r, s = readings[0.0]
    near = r < d_deck + 0.1
    assert 0 < near.sum() < len(r)  # part of the cone on the deck, part beyond its edge
    assert d_deck < mixed < d_out
    # signal-weighted: nearer the deck than the plain mean of the rays (the deck returns are stronger)
    assert mixed < np.mean(r) / w.tof.model.flat_gain


def test_cone_noise_grows_with_range_as_the_model_says(tof_world: World) -> None:
    w = tof_world
    m = w.tof.model
    rng = np.random.default_rng(9)
    stds = []
    for h in (0.5, 1.5, 2.5):  # over open ground, away from the deck
        _place(w, 3.0, 0.0, h - w.config.rig.sensor_positions_body[0, 2])
        pos, R = w.drone_pose()
        mean, signal = w.tof.cone_ranges(pos, R)
        reads = np.array([w.sensing.read_tof(rng)[0] for _ in range(300)])  # 1200 samples
        assert np.all(reads < w.config.tof.max_range)
        err = reads - reads.mean(axis=0)  # the per-sensor offset is constant within an episode
        assert err.std() == pytest.approx(float(m.sigma(signal).mean()), rel=REL)
        assert np.abs(reads.mean(axis=0) - mean).max() < 0.005
        stds.append(err.std())
    assert stds[0] < stds[1] < stds[2]
    # ST: +-20 mm (2 sigma) at the dark range limit; sigma ~ d in the dark
    c3 = float(np.mean(m.directions()[:, 2] ** 3))
    s_lim = 0.88 * c3 / m.dark_range**2
    assert float(m.sigma(s_lim)) == pytest.approx(math.hypot(0.010, 0.001), rel=1e-6)
    # ambient light raises sigma at the same signal
    amb = VL53L1X(ambient=0.5)
    assert float(amb.sigma(0.5)) > float(m.sigma(0.5)) * 1.5


def test_range_limits_depend_on_reflectance_and_ambient() -> None:
    c3 = float(np.mean(VL53L1X().directions()[:, 2] ** 3))

    def max_range(m: VL53L1X) -> float:  # perpendicular target filling the cone
        s_needed = m.snr_min**2 / 2 * (1 + math.sqrt(1 + 4 * m.ambient * m.strong_ambient / m.snr_min**2))
        return math.sqrt(m.reflectance * c3 / s_needed)

    assert max_range(VL53L1X(reflectance=0.88)) == pytest.approx(3.6, rel=1e-6)  # ST, dark, white
    assert max_range(VL53L1X(reflectance=0.88, ambient=1.0)) == pytest.approx(0.73, rel=1e-6)  # sunlight
    assert max_range(VL53L1X(reflectance=0.17)) == pytest.approx(1.7, rel=0.1)  # ST: 1.7 m at 17 %
    assert 2.6 < max_range(VL53L1X()) < 3.0  # the default 54 % grey target in the dark


def test_no_target_out_of_range_and_too_close_are_invalid(make_world, tof_world: World) -> None:
    w = tof_world
    rng = np.random.default_rng(10)
    max_range = np.float32(w.config.tof.max_range)
    cases = {
        "nothing below 4 m": (3.0, 0.0, 4.5, (0, 0, 0, 1)),
        "looking at the sky": (3.0, 0.0, 1.0, (1, 0, 0, 0)),  # upside down
        "beyond the SNR limit (54 % grey, dark: 2.8 m)": (3.0, 0.0, 3.3, (0, 0, 0, 1)),
        "below the 4 cm minimum": (3.0, 0.0, 0.045, (0, 0, 0, 1)),
    }
    for name, (x, y, z, q) in cases.items():
        _place(w, x, y, z, q)
        ranges, valid = w.sensing.read_tof(rng)
        assert not valid.any(), name
        assert np.all(ranges == max_range), name
    # strong ambient light: 1 m is beyond reach for a grey target
    sunny = make_world(WorldConfig(camera=None, tof=ToFConfig(noise=VL53L1X(ambient=1.0, dropout=0.0))))
    sunny.reset(StaticProfile(), 10.0, altitude=1.0)
    assert not sunny.sensing.read_tof(rng)[1].any()
    sunny.reset(StaticProfile(), 10.0, altitude=0.4)
    assert sunny.sensing.read_tof(rng)[1].all()


def test_realistic_tof_is_seeded_and_offsets_are_per_episode(tof_world: World) -> None:
    w = tof_world
    a = w.sensing.read_tof(np.random.default_rng(5))
    b = w.sensing.read_tof(np.random.default_rng(5))
    np.testing.assert_array_equal(a[0], b[0])
    offsets = []
    for k in range(400):
        w.tof.reset(np.random.default_rng(k))
        offsets.append(w.tof.offset.copy())
    assert np.std(offsets) == pytest.approx(VL53L1X().offset_sigma, rel=REL)


# -- navigation: the estimate the autopilot flies on ------------------------------------------------
def test_navigation_errors_start_stationary_and_drift_as_the_model_says() -> None:
    e = NavigationErrors()
    nav = GNSSINSNavigation(e, dt=0.05)  # coarse steps keep the test fast; the physics uses 1/240 s
    rng = np.random.default_rng(11)
    p0, v0, dp = [], [], []
    zero = (0.0, 0.0, 0.0)
    for _ in range(1000):
        nav.reset(rng)
        p_a, v_a = nav.estimate(0.0, zero, zero)
        p_b, _ = nav.estimate(30.0, zero, zero)
        p0.append(p_a)
        v0.append(nav.velocity_error[:])
        dp.append(np.subtract(p_b, p_a))
    assert np.std(p0, axis=0) == pytest.approx(e.position_sigma, rel=REL)
    assert np.std(v0, axis=0) == pytest.approx(e.velocity_sigma, rel=REL)
    assert np.std(dp, axis=0) == pytest.approx(e.drift_std(30.0), rel=REL)
    # tens of centimetres in 30 s horizontally: what a GNSS-holding drone wanders
    assert 0.2 < math.hypot(*e.drift_std(30.0)[:2]) < 0.8


def test_navigation_velocity_is_the_position_error_rate_plus_white_noise() -> None:
    e = NavigationErrors()
    nav = GNSSINSNavigation(e, dt=1 / 240)
    nav.reset(np.random.default_rng(12))
    zero = (0.0, 0.0, 0.0)
    ps, vs = [], []
    for k in range(2400):  # 10 s
        pk, vk = nav.estimate(k / 240, zero, zero)
        ps.append(pk)
        vs.append(vk)
    ps, vs = np.array(ps), np.array(vs)
    rate = np.diff(ps, axis=0) * 240
    white = vs[1:] - rate
    assert white.std(axis=0) == pytest.approx(np.full(3, e.velocity_noise), rel=REL)


def test_navigation_is_deterministic_and_independent_of_how_often_it_is_read() -> None:
    e = NavigationErrors()
    a, b = GNSSINSNavigation(e, 1 / 240), GNSSINSNavigation(e, 1 / 240)
    a.reset(np.random.default_rng(13))
    b.reset(np.random.default_rng(13))
    zero = (0.0, 0.0, 0.0)
    for k in range(0, 1200):
        a.estimate(k / 240, zero, zero)
    assert a.estimate(5.0, zero, zero) == b.estimate(5.0, zero, zero)  # b read once only
    assert isinstance(make_navigation(NavigationConfig("truth"), 0.01), TruthNavigation)
    assert isinstance(make_navigation(NavigationConfig("estimated"), 0.01), GNSSINSNavigation)
    with pytest.raises(ValueError, match="autopilot_feedback"):
        NavigationConfig("gps")
    with pytest.raises(ValueError, match="horizontal_sigma"):
        NavigationErrors(horizontal_sigma=-1.0)


def _hold(
    make_world: Callable[..., World], feedback: str, seed: int, seconds: float = 30.0
) -> tuple[np.ndarray, np.ndarray, World]:
    w = make_world(WorldConfig(camera=None, navigation=NavigationConfig(feedback)))
    w.reset(StaticProfile(), 60.0, altitude=1.0)
    w.reset_random(np.random.default_rng(seed))
    p0 = w.drone_pose()[0]
    e0 = w.nav_position() - p0
    for _ in range(int(seconds * w.config.control_hz)):
        w.step()
    return p0, e0, w


@pytest.mark.parametrize("seed", [0, 1])
def test_zero_command_drifts_with_the_estimate_under_estimated_feedback(make_world, seed: int) -> None:
    p0, e0, w = _hold(make_world, "estimated", seed)
    p1 = w.drone_pose()[0]
    e1 = w.nav_position() - p1
    moved = p1 - p0
    # the drone holds its *estimated* position: it moves by minus the change of the estimate's error
    np.testing.assert_allclose(moved, -(e1 - e0), atol=0.03)
    assert np.linalg.norm(moved) > 0.02
    assert not np.array_equal(w.nav_velocity(), w.sensing.snapshot().drone_velocity)
    p0, _, w = _hold(make_world, "truth", seed, seconds=5.0)
    assert np.linalg.norm(w.drone_pose()[0] - p0) < 1e-3
