"""Simulation layer (PyBullet world) tested without Gymnasium."""

import math

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.sensors import CameraConfig, ToFConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.frames import body_pose_to_cam, matrix_from_euler
from ihrcf_env.core.profiles import CallableProfile, StaticProfile, paper_profile, sea_state_profile
from ihrcf_env.core.rig import tag_corners_deck
from ihrcf_env.sim.world import World


@pytest.fixture
def world(make_world) -> World:
    return make_world(WorldConfig(camera=None))


def fixed_pose(offset, rpy) -> CallableProfile:
    o, r = np.asarray(offset, float), np.asarray(rpy, float)
    return CallableProfile(lambda t: (o, r))


def test_tof_matches_analytic_plane_distance(world):
    rng = np.random.default_rng(7)
    for _ in range(12):
        off = rng.uniform(-1, 1, 3) * np.array([0.04, 0.04, 0.05])
        rpy = rng.uniform(-1, 1, 3) * np.array([math.radians(15), math.radians(15), math.radians(20)])
        world.reset(
            fixed_pose(off, rpy),
            horizon_s=0.1,
            altitude=rng.uniform(0.4, 2.5),
            offset_xy=tuple(rng.uniform(-0.1, 0.1, 2)),
            yaw=rng.uniform(-1, 1),
        )
        ranges, valid = world.sensing.read_tof(np.random.default_rng(0))
        pos, R = world.drone_pose()
        deck_pos, R_wd = world.deck.pose()
        n = R_wd[:, 2]
        beam = -R[:, 2]
        for i, s_body in enumerate(world.config.rig.sensor_positions_body):
            s = pos + R @ s_body
            expected = float(n @ (deck_pos - s) / (n @ beam))
            assert valid[i] == 1
            assert abs(float(ranges[i]) - expected) <= 1e-4, (i, ranges[i], expected)


def test_tof_miss_is_flagged_and_clamped(world):
    world.reset(StaticProfile(), horizon_s=0.1, altitude=1.0, offset_xy=(3.0, 0.0))
    # far from the deck: beams reach the ground (~1.85 m) -> valid; raise the drone beyond range
    p.resetBasePositionAndOrientation(
        world.quad.body, [3.0, 0.0, 4.5], [0, 0, 0, 1], physicsClientId=world.client
    )
    ranges, valid = world.sensing.read_tof(np.random.default_rng(0))
    assert np.all(valid == 0)
    assert np.all(ranges == np.float32(world.config.tof.max_range))


def test_realistic_tof_noise_is_seeded(make_world):
    w = make_world(
        WorldConfig(
            camera=None,
            tof=ToFConfig(noise="realistic"),
        )
    )
    w.reset(StaticProfile(), horizon_s=0.1, altitude=1.0)
    a = [w.sensing.read_tof(np.random.default_rng(5)) for _ in range(2)]
    np.testing.assert_array_equal(a[0][0], a[1][0])
    true, _ = w.tof.true_ranges(*w.drone_pose())
    samples = np.array([w.sensing.read_tof(np.random.default_rng(k))[0] for k in range(300)])
    err = samples - true.astype(np.float32)
    ok = np.abs(err) < 0.1
    assert 0.0028 < err[ok].std() < 0.0046  # VL53L1X model: sigma 3.7 mm at 0.97 m in the dark
    assert np.all(np.isfinite(samples))


def test_tag_corners_project_onto_black_border(make_world):
    w = make_world(WorldConfig(camera=CameraConfig()))
    rng = np.random.default_rng(11)
    for _ in range(4):
        off = rng.uniform(-1, 1, 3) * 0.03
        rpy = rng.uniform(-1, 1, 3) * np.array([0.2, 0.2, 0.3])
        w.reset(
            fixed_pose(off, rpy),
            horizon_s=0.1,
            altitude=rng.uniform(0.9, 1.3),
            yaw=rng.uniform(-0.5, 0.5),
        )
        img = w.sensing.render_camera().astype(float).mean(axis=2)
        p_bd, R_bd = w.sensing.deck_in_body()
        R_cd, t_cd = body_pose_to_cam(R_bd, p_bd, w.config.rig.camera_position)
        K = w.config.camera.intrinsics
        s = w.config.deck.tag_size

        def project(pts, K=K, R_cd=R_cd, t_cd=t_cd):
            X = pts @ R_cd.T + t_cd
            uv = X @ K.T
            return uv[:, :2] / uv[:, 2:]

        inner = project(tag_corners_deck(s) * 0.93)  # inside the black border, near the corner
        outer = project(tag_corners_deck(s) * 1.07)  # in the white quiet zone
        for (u, v), (uo, vo) in zip(inner, outer, strict=True):
            assert img[int(round(v)), int(round(u))] < 60, "expected black border"
            assert img[int(round(vo)), int(round(uo))] > 150, "expected white quiet zone"


def test_deck_follows_trajectory_with_real_velocity(world):
    world.reset(paper_profile(), horizon_s=12.0)
    traj = world.deck.trajectory
    errs, vel_err = [], []
    for _ in range(200):  # 10 s
        world.step()
        pos, R = world.deck.pose()
        k = world.tick
        errs.append(np.linalg.norm(pos - traj.position[k]))
        v, _ = world.deck.velocity()
        v_fd = (traj.position[k] - traj.position[k - 1]) / world.dt  # finite-difference deck-origin velocity
        vel_err.append(np.linalg.norm(v - v_fd))
    assert max(errs) < 1e-4
    # the plate's centre of mass moves almost like the deck origin (2 cm apart, slow rotation)
    assert np.median(vel_err) < 5e-3
    assert np.abs(world.deck.velocity()[0]).max() > 1e-3  # it really moves


def test_drone_hovers_within_2cm_for_10s(world):
    world.reset(paper_profile(), horizon_s=11.0, altitude=1.0, offset_xy=(0.05, -0.03), yaw=0.3)
    start, R0 = world.drone_pose()
    world.set_velocity_setpoint(np.zeros(4))
    # a gust: the controller must reject it (without one, an ideal simulation would not move at all)
    p.resetBaseVelocity(world.quad.body, [0.04, -0.04, 0.04], [0.3, -0.3, 0.2], physicsClientId=world.client)
    worst = 0.0
    for _ in range(200):
        world.step()
        pos, R = world.drone_pose()
        worst = max(worst, float(np.abs(pos - start).max()))
    assert 0.001 < worst < 0.02  # it was pushed, and held within 2 cm
    assert float(np.abs(pos - start).max()) < 0.003  # and came back


def test_velocity_setpoint_is_tracked(world):
    world.reset(StaticProfile(), horizon_s=6.0, altitude=1.5, yaw=0.5)
    world.set_velocity_setpoint(np.array([0.5, 0.0, 0.2, 0.0]))
    for _ in range(60):
        world.step()
    _, _, vel, _ = world.quad.state()
    # heading frame x = world direction of yaw 0.5
    np.testing.assert_allclose(vel, [0.5 * math.cos(0.5), 0.5 * math.sin(0.5), 0.2], atol=0.03)


def test_resting_drone_is_carried_by_the_deck(make_world):
    w = make_world(WorldConfig(camera=None))
    prof = sea_state_profile(
        np.random.default_rng(2), {"heave": 0.05, "roll": 0.06, "pitch": 0.06, "yaw": 0.04}
    )
    w.reset(prof, horizon_s=7.0, altitude=0.12)
    w.set_motor_thrusts(np.zeros(4))
    for _ in range(10):  # settle 0.5 s
        w.step()

    def in_deck():
        pos, _ = w.drone_pose()
        deck_pos, R_wd = w.deck.pose()
        return R_wd.T @ (pos - deck_pos)

    start = in_deck()
    moved = 0.0
    for _ in range(100):  # 5 s
        w.step()
        moved = max(moved, float(np.linalg.norm(in_deck()[:2] - start[:2])))
    deck_travel = np.ptp(w.deck.trajectory.position[: w.tick], axis=0)
    assert deck_travel.max() > 0.03  # the deck really moved
    assert moved < 0.02
    assert w.quad.body in {c[1] for c in p.getContactPoints(bodyB=w.deck.body, physicsClientId=w.client)}


def test_two_worlds_are_independent(make_world):
    a, b = make_world(WorldConfig(camera=None)), make_world(WorldConfig(camera=None))
    assert a.client != b.client
    a.reset(paper_profile(), horizon_s=3.0)
    b.reset(paper_profile(), horizon_s=3.0)
    b.set_velocity_setpoint(np.array([0.5, 0.0, 0.0, 0.0]))
    for _ in range(20):
        a.step()
        b.step()
    pa, _ = a.drone_pose()
    pb, _ = b.drone_pose()
    assert abs(pa[0] - pb[0]) > 0.2
    a.close()  # second close is a no-op


def test_stroke_violation_raises_with_time_and_leg(world):
    prof = CallableProfile(lambda t: (np.array([0.0, 0.0, 0.1 * t]), np.zeros(3)))
    with pytest.raises(ValueError, match=r"at t = \d+\.\d+ s: leg \d"):
        world.reset(prof, horizon_s=5.0)


def test_level_deck_reads_zero_angles_and_negative_height(world):
    world.reset(StaticProfile(), horizon_s=0.1, altitude=1.2)
    p_bd, R_bd = world.sensing.deck_in_body()
    np.testing.assert_allclose(p_bd, [0.0, 0.0, -1.2], atol=1e-9)
    np.testing.assert_allclose(R_bd, np.eye(3), atol=1e-9)
    _ = matrix_from_euler  # frames helpers exercised elsewhere


def test_lens_distortion_moves_corners_as_brown_conrady(make_world):
    import cv2

    w = make_world(WorldConfig(camera=CameraConfig(distortion=(-0.15, 0.02))))
    w.reset(StaticProfile(), horizon_s=0.1, altitude=0.8, yaw=0.3)
    img = w.sensing.render_camera()
    p_bd, R_bd = w.sensing.deck_in_body()
    R_cd, t_cd = body_pose_to_cam(R_bd, p_bd, w.config.rig.camera_position)
    X = tag_corners_deck(w.config.deck.tag_size) @ R_cd.T + t_cd
    cam = w.config.camera
    distorted, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.intrinsics, cam.distortion_coefficients)
    ideal, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), cam.intrinsics, np.zeros(5))
    prm = cv2.aruco.DetectorParameters()
    prm.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), prm)
    corners, ids, _ = det.detectMarkers(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY))
    found = corners[0].reshape(4, 2)
    assert np.abs(found - distorted.reshape(4, 2)).max() < 0.5
    assert np.abs(found - ideal.reshape(4, 2)).max() > 1.5  # distortion really there (~2.8 px)


def test_motion_beyond_the_checked_horizon_stalls_instead_of_crashing(world):
    prof = CallableProfile(
        lambda t: (np.array([0.0, 0.0, 0.1 * t]), np.zeros(3))
    )  # leaves the stroke at ~1.5 s
    world.reset(prof, horizon_s=1.0)
    for _ in range(80):  # 4 s
        world.step()
    traj = world.deck.trajectory
    assert traj.stalled_at is not None and 1.0 < traj.stalled_at < 2.0
    legs = world.deck.leg_lengths()
    geo = world.config.stewart
    assert np.all(legs <= geo.max_leg + 1e-4)


@pytest.mark.parametrize("tz", [0.05, -0.05])
def test_saturated_mixer_keeps_yaw_within_the_motor_range(world, tz):
    """Under saturation (collective thrust near the top) yaw is scaled to the margin, not dropped:
    the realised yaw torque has the command's sign, and every motor stays within its range."""
    quad = world.quad
    kf, km, fmax = quad._kf, quad._km, quad._fmax
    unsaturated = [kf * w * w for w in quad.wrench_to_speeds(2.0 * fmax, (0.0, 0.0, tz))]
    f = [kf * w * w for w in quad.wrench_to_speeds(3.7 * fmax, (0.02, 0.0, tz))]
    assert all(0.0 <= fi <= fmax * (1 + 1e-9) for fi in f)

    def yaw(forces: list[float]) -> float:
        return -(km / kf) * sum(s * fi for s, fi in zip(quad._spin_list, forces, strict=True))

    assert yaw(unsaturated) == pytest.approx(tz, rel=1e-6)
    assert math.copysign(1.0, yaw(f)) == math.copysign(1.0, tz)
    assert 0.05 * abs(tz) < abs(yaw(f)) <= abs(tz) * (1 + 1e-9)
