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
