"""The MAVLink face's frame conversions (pure functions: no sockets, no env)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix
from ihrcf_env.mavlink import frames


def _q(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return quat_from_matrix(matrix_from_euler(roll, pitch, yaw))


def test_world_and_ned_are_x_north_y_west_z_up() -> None:
    np.testing.assert_allclose(frames.world_to_ned([1.0, 2.0, 3.0]), [1.0, -2.0, -3.0])
    np.testing.assert_allclose(frames.ned_to_world(frames.world_to_ned([0.3, -0.7, 2.5])), [0.3, -0.7, 2.5])
    np.testing.assert_allclose(frames.flu_to_frd([0.1, 0.2, 0.3]), [0.1, -0.2, -0.3])
    np.testing.assert_allclose(frames.frd_to_flu(frames.flu_to_frd([0.1, 0.2, 0.3])), [0.1, 0.2, 0.3])
    assert np.linalg.det(frames.FLIP) == pytest.approx(1.0)  # a rotation, not a mirror


def test_attitude_yaw_turns_the_other_way_and_rates_flip() -> None:
    # a level drone turned 90 deg counter-clockwise (seen from above) in the world faces west:
    # MAVLink yaw -90 deg (clockwise from north)
    a = frames.attitude_to_mavlink(_q(0.0, 0.0, math.pi / 2), [0.1, 0.2, 0.3])
    assert (a.roll, a.pitch) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert a.yaw == pytest.approx(-math.pi / 2)
    assert (a.rollspeed, a.pitchspeed, a.yawspeed) == pytest.approx((0.1, -0.2, -0.3))
    # FLU roll +0.2 (left side up = right wing down) is FRD roll +0.2; FLU pitch -0.1 (about
    # y-left: nose up) is FRD pitch +0.1 (nose up)
    b = frames.attitude_to_mavlink(_q(0.2, -0.1, 0.0), [0.0, 0.0, 0.0])
    assert (b.roll, b.pitch) == pytest.approx((0.2, 0.1))


def test_quaternions_round_trip_and_level_is_identity() -> None:
    np.testing.assert_allclose(frames.quat_to_mavlink([0.0, 0.0, 0.0, 1.0]), [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = _q(*rng.uniform(-1.0, 1.0, 3))
        back = frames.quat_from_mavlink(frames.quat_to_mavlink(q))
        assert abs(float(np.dot(back, q))) == pytest.approx(1.0, abs=1e-12)


def test_a_ned_velocity_setpoint_becomes_the_heading_frame_command() -> None:
    # a drone facing world +y (west): north (world +x) is to its right, i.e. heading-frame -y
    v, rate = frames.velocity_command([1.0, 0.0, -0.5], 0.2, math.pi / 2)
    np.testing.assert_allclose(v, [0.0, -1.0, 0.5], atol=1e-12)  # climb 0.5 m/s (NED up is -down)
    assert rate == pytest.approx(-0.2)  # clockwise in NED = clockwise = negative about world z up
    # facing north (yaw 0): east is to the right
    v, _ = frames.velocity_command([0.0, 2.0, 0.0], 0.0, 0.0)
    np.testing.assert_allclose(v, [0.0, -2.0, 0.0], atol=1e-12)


def test_body_velocity_rotates_by_the_heading_only() -> None:
    # heading east (NED yaw +90 deg): forward is east, right is south
    np.testing.assert_allclose(
        frames.body_velocity_to_ned([1.0, 0.0, 0.2], math.pi / 2), [0.0, 1.0, 0.2], atol=1e-12
    )
    np.testing.assert_allclose(
        frames.body_velocity_to_ned([0.0, 1.0, 0.0], math.pi / 2), [-1.0, 0.0, 0.0], atol=1e-12
    )


def test_target_in_local_ned_adds_the_rotated_body_position() -> None:
    # drone level at world (1, 2, 3) heading world +y; deck 2 m below, 0.5 m ahead in the body frame
    q = _q(0.0, 0.0, math.pi / 2)
    R_bd = matrix_from_euler(0.0, 0.0, -math.pi / 2)  # the deck's axes: world-aligned
    t = frames.target_local_ned([1.0, 2.0, 3.0], q, [0.5, 0.0, -2.0], R_bd)
    # world: (1, 2.5, 1) -> NED (1, -2.5, -1)
    np.testing.assert_allclose(t.position, [1.0, -2.5, -1.0], atol=1e-12)
    np.testing.assert_allclose(np.abs(t.q), [1.0, 0.0, 0.0, 0.0], atol=1e-12)  # a level deck heading north


def test_target_in_body_frd_gives_the_line_of_sight_ardupilot_reads() -> None:
    # deck 1 m below, 0.1 m ahead and 0.2 m to the left (FLU)
    t = frames.target_body_frd([0.1, 0.2, -1.0])
    np.testing.assert_allclose(t.position, [0.1, -0.2, 1.0])
    assert t.distance == pytest.approx(math.sqrt(0.01 + 0.04 + 1.0))
    assert t.angle_x == pytest.approx(math.atan(-0.2))  # left of the image centre: negative
    assert t.angle_y == pytest.approx(math.atan(-0.1))  # ahead (image top): negative
    los = np.array([-math.tan(t.angle_y), math.tan(t.angle_x), 1.0])  # ArduPilot's reading
    np.testing.assert_allclose(los / np.linalg.norm(los), t.position / t.distance, atol=1e-12)


def test_deck_quaternion_in_the_body_frame() -> None:
    np.testing.assert_allclose(np.abs(frames.deck_quat_body_frd(np.eye(3))), [1.0, 0.0, 0.0, 0.0], atol=1e-12)
    # a deck yawed +30 deg about body up reads -30 deg about body down
    w, x, y, z = frames.deck_quat_body_frd(matrix_from_euler(0.0, 0.0, math.radians(30)))
    assert 2 * math.atan2(z, w) == pytest.approx(math.radians(-30))


def test_conversions_refuse_nan() -> None:
    with pytest.raises(ValueError, match="NaN"):
        frames.world_to_ned([math.nan, 0.0, 0.0])
