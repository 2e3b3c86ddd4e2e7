"""The landing controller's sensing maths and first decision, on hand-made observations."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from ihrcf_env.control.landing import LandingConfig, LandingController
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix
from ihrcf_env.core.rig import SensorRig


def _obs(height: float, deck_rpy: tuple[float, float, float], tag: bool = True) -> dict[str, Any]:
    """A hand-made observation (no ground truth key): a level drone above a plane through the point
    ``height`` below its origin, with the plane's orientation ``deck_rpy`` in the body frame."""
    R_bd = matrix_from_euler(*deck_rpy)
    n = R_bd[:, 2]
    p0 = np.array([0.0, 0.0, -height])
    sensors = SensorRig().sensor_positions_body
    # beam from s along -z hits the plane n.(x - p0) = 0 at s - r e_z
    ranges = np.array([float(n @ (s - p0)) / n[2] for s in sensors], dtype=np.float32)
    quat = quat_from_matrix(np.eye(3)).astype(np.float32)
    est = {
        "position": p0.astype(np.float32),
        "euler": np.asarray(deck_rpy, np.float32),
        "valid": int(tag),
    }
    return {
        "ranges": ranges,
        "ranges_valid": np.ones(4, np.int8),
        "imu": {
            "quaternion": quat,
            "angular_velocity": np.zeros(3, np.float32),
            "linear_acceleration": np.array([0.0, 0.0, GRAVITY], np.float32),
        },
        "ihrcf": est,
    }


def test_tof_plane_fit_gives_height_and_tilt() -> None:
    ctrl = LandingController()
    rpy = (math.radians(6.0), math.radians(-4.0), 0.3)
    m = ctrl.measure(_obs(0.5, rpy))
    assert m.tof_height == pytest.approx(0.5, abs=1e-6)
    assert m.tof_full
    normal = matrix_from_euler(*rpy)[:, 2]  # level drone: level frame = body frame
    assert m.tof_normal == pytest.approx(normal, abs=1e-6)
    assert m.tag_normal == pytest.approx(normal, abs=1e-6)
    assert m.tag_xy == pytest.approx([0.0, 0.0], abs=1e-6)
    assert m.accel_z == pytest.approx(0.0, abs=1e-5)  # gravity removed


def test_controller_descends_without_ground_truth() -> None:
    ctrl = LandingController()
    ctrl.reset()
    a = ctrl.act(_obs(1.0, (0.0, 0.0, 0.0)))
    assert a.shape == (4,) and a.dtype == np.float32
    assert np.all(np.abs(a) <= 1.0)
    assert a[2] < 0  # above the hold height: going down
    assert ctrl.phase == "approach"


def test_heading_alignment_is_modulo_the_square_deck() -> None:
    # deck yaw 80 deg in the body frame is -10 deg modulo 90 deg: turn the short way (negative)
    ctrl = LandingController()
    a = ctrl.act(_obs(1.0, (0.0, 0.0, math.radians(80.0))))
    assert a[3] == pytest.approx(math.radians(-10.0), abs=1e-6)


def test_steers_on_the_chosen_estimate_never_ground_truth() -> None:
    obs = _obs(1.0, (0.0, 0.0, 0.0))
    obs["fused"] = {**obs["ihrcf"], "position": np.array([0.2, 0.0, -1.0], np.float32)}
    obs["ihrcf"] = {**obs["ihrcf"], "valid": 0}
    m = LandingController(estimator="fused").measure(obs)
    assert m.tag_xy == pytest.approx([0.2, 0.0], abs=1e-6)
    assert LandingController().measure(obs).tag_xy is None  # "ihrcf" (default) is invalid here
    with pytest.raises(ValueError, match="estimator"):
        LandingController(estimator="ground_truth")


def test_commit_below_turns_a_descent_under_the_hold_into_a_drop() -> None:
    # default: 0.3 m under the hold height (0.65 m) with the tag in view, no drop without a calm deck
    default = LandingController()
    default.act(_obs(0.8, (0.0, 0.0, 0.0)))
    default.act(_obs(0.35, (0.0, 0.0, 0.0)))
    assert default.phase == "approach" and default.commit_time is None
    # the teacher's option: more than 0.1 m under the hold height after seeing the tag is a drop
    teacher = LandingController(config=LandingConfig(commit_below=0.1))
    teacher.act(_obs(0.8, (0.0, 0.0, 0.0)))
    assert teacher.phase == "approach"
    teacher.act(_obs(0.35, (0.0, 0.0, 0.0)))
    assert teacher.phase == "drop" and teacher.commit_time is not None


def _leaning(ctrl: LandingController, lean: float, height: float, tag_x: float | None) -> np.ndarray:
    """One step of a drone leaning ``lean`` rad towards +x (level frame) ``height`` m above a level
    deck, the tag's centre at (``tag_x``, 0) (None: not seen): the action."""
    c, s = math.cos(lean), math.sin(lean)
    R_lb = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # body z towards +x
    q = ctrl.sensors @ R_lb.T
    d = R_lb @ np.array([0.0, 0.0, -1.0])
    ranges = (-height - q[:, 2]) / d[2]
    tag = None if tag_x is None else np.array([tag_x, 0.0, -height])
    normal = None if tag_x is None else np.array([0.0, 0.0, 1.0])
    yaw = None if tag_x is None else 0.0
    m = ctrl.measure_level(R_lb, 0.0, tag, yaw, normal, ranges, np.ones(4, bool))
    return ctrl.act_measured(m)


def test_axis_centring_holds_the_tag_on_the_leaning_camera_axis() -> None:
    lean, h = math.radians(15.0), 0.65
    depth = h + SensorRig().camera_position[2]
    on_axis = -depth * math.tan(lean)  # the camera looks downwind of the drone
    plain = LandingController(config=LandingConfig(k_yaw=0.0))
    axis = LandingController(config=LandingConfig(k_yaw=0.0, axis_centring=True))
    # the classic controller centres the tag straight below; the lean-aware one on the axis
    assert _leaning(plain, lean, h, 0.0)[0] == pytest.approx(0.0, abs=1e-6)
    assert _leaning(axis, lean, h, on_axis)[0] == pytest.approx(0.0, abs=1e-6)
    assert axis.axis_point() == pytest.approx([on_axis, 0.0], abs=1e-9)
    axis.reset()
    assert _leaning(axis, lean, h, 0.0)[0] > 0.1  # tag straight below: move upwind (+x)


def test_relative_tilt_compares_the_deck_with_the_drone_lean() -> None:
    lean, h = math.radians(15.0), 0.65
    level = LandingController(config=LandingConfig(k_yaw=0.0))
    relative = LandingController(config=LandingConfig(k_yaw=0.0, relative_tilt=True))
    for ctrl in (level, relative):
        for _ in range(3):
            _leaning(ctrl, lean, h, 0.0)
    assert level.predicted_tilt(0.0) == pytest.approx(0.0, abs=1e-6)  # a level deck
    assert relative.predicted_tilt(0.0) == pytest.approx(lean, abs=1e-6)  # 15 deg from the drone's up


def test_dead_reckoning_carries_a_lost_tag_through_the_drop() -> None:
    ctrl = LandingController(config=LandingConfig(k_yaw=0.0, dead_reckon=1.0))
    _leaning(ctrl, 0.0, 0.65, 0.2)
    ctrl.phase = "drop"
    a = _leaning(ctrl, 0.0, 0.5, None)
    assert a[0] > 0.0  # still towards the tag's last position
    assert ctrl.last_tag is not None and 0.0 < ctrl.last_tag[0] < 0.2  # moved by the command
    for _ in range(int(1.2 / ctrl.dt)):  # beyond dead_reckon: no lateral command
        a = _leaning(ctrl, 0.0, 0.5, None)
    assert a[0] == 0.0
    assert LandingController(config=LandingConfig(k_yaw=0.0)).cfg.dead_reckon == 0.0  # off by default


@pytest.mark.parametrize("flag", ["axis_centring", "relative_tilt", "full_plane_tilt"])
def test_lean_options_are_checked_by_name(flag: str) -> None:
    with pytest.raises((TypeError, ValueError), match=flag):
        LandingConfig(**{flag: "yes"})
    with pytest.raises(ValueError, match="lean_tau"):
        LandingConfig(lean_tau=-1.0)


def test_dead_reckoning_on_the_measured_velocity() -> None:
    """With ``dead_reckon_nav`` the lost tag moves against the drone's measured velocity (a gust
    that pushes it), not against its commands."""
    ctrl = LandingController(config=LandingConfig(k_yaw=0.0, dead_reckon=1.0, dead_reckon_nav=True))
    _leaning(ctrl, 0.0, 0.65, 0.2)
    ctrl.phase = "drop"
    assert ctrl.last_tag is not None
    before = ctrl.last_tag.copy()
    R = np.eye(3)
    ranges = np.full(4, 0.5 + ctrl.sensors[0, 2])
    m = ctrl.measure_level(R, 0.0, None, None, None, ranges, np.ones(4, bool), velocity_xy=(0.4, -0.2))
    ctrl.act_measured(m)
    assert ctrl.last_tag is not None
    np.testing.assert_allclose(ctrl.last_tag - before, [-0.4 * ctrl.dt, 0.2 * ctrl.dt], atol=1e-12)


def test_a_full_tof_plane_outvotes_a_disagreeing_estimate() -> None:
    """``estimate_height`` flies on the estimate when it disagrees with the ranges (beams across
    the deck's edge); with ``trust_full_plane`` four beams on one plane keep the ranges' height."""
    for trust, expected in ((False, 0.9), (True, 0.5)):
        cfg = LandingConfig(k_yaw=0.0, estimate_height=True, trust_full_plane=trust)
        ctrl = LandingController(config=cfg)
        ranges = np.full(4, 0.5) + ctrl.sensors[:, 2]  # a level plane 0.5 m below the origin
        tag = np.array([0.0, 0.0, -0.9])  # the estimate says 0.9 m
        m = ctrl.measure_level(np.eye(3), 0.0, tag, 0.0, np.array([0.0, 0.0, 1.0]), ranges, np.ones(4, bool))
        assert m.tof_full and m.tof_height == pytest.approx(0.5)
        ctrl.act_measured(m)
        assert ctrl.height == pytest.approx(expected)
