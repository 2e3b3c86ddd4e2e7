"""A trimmed start: the drone begins as an autopilot already holding position in the wind."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from ihrcf_env.config.vehicle import VelocityGains
from ihrcf_env.config.wind import DragModel, WindParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.world import World


def _world(make_world: Any, gains: VelocityGains, speed: float, camera: bool = False) -> World:
    cfg = WorldConfig(gains=gains) if camera else WorldConfig(camera=None, gains=gains)
    w = make_world(cfg)
    w.add_disturbance(Wind(WindParams(mean_speed_min=speed, mean_speed_max=speed, turbulence=0.0)))
    w.reset(StaticProfile(), horizon_s=30.0, altitude=2.0)
    w.reset_random(np.random.default_rng(3))
    return w


def _drift(w: World, seconds: float) -> tuple[float, float]:
    """Largest horizontal offset (m) from the start and largest tilt change (rad) over ``seconds``."""
    start, R0 = w.drone_pose()
    tilt0 = math.acos(R0[2, 2])
    w.set_velocity_setpoint(np.zeros(4))
    offset = dtilt = 0.0
    for _ in range(int(seconds * w.config.control_hz)):
        w.step()
        pos, R = w.drone_pose()
        offset = max(offset, float(np.hypot(*(pos[:2] - start[:2]))))
        dtilt = max(dtilt, abs(math.acos(R[2, 2]) - tilt0))
    return offset, dtilt


@pytest.mark.parametrize(
    ("gains", "speed"),
    # the classic loop's integrator clamp covers the drag up to about 6 m/s
    [
        (VelocityGains(wind_hold=True), 12.0),
        (VelocityGains(wind_hold=True, dob_tau=0.0), 12.0),
        (VelocityGains(), 5.0),
    ],
    ids=["observer", "integral", "classic"],
)
def test_a_trimmed_start_holds_its_position_from_the_first_step(
    make_world: Any, gains: VelocityGains, speed: float
) -> None:
    w = _world(make_world, gains, speed)
    w.trim()
    _, R = w.drone_pose()
    drag = math.hypot(*DragModel().force((speed, 0.0, 0.0))[:2])
    assert math.tan(math.acos(R[2, 2])) == pytest.approx(drag / (1.2 * 9.81), rel=0.02)
    offset, dtilt = _drift(w, 3.0)
    assert offset < 1e-3 and dtilt < 1e-3  # exact up to the physics step


def test_an_untrimmed_start_is_blown_off(make_world: Any) -> None:
    """The comparison: level and with no disturbance estimate, the same wind pushes it decimetres."""
    w = _world(make_world, VelocityGains(wind_hold=True), 8.0)
    offset, dtilt = _drift(w, 3.0)
    assert offset > 0.05 and dtilt > math.radians(5.0)


def test_keep_view_puts_the_drawn_point_on_the_camera_axis(make_world: Any) -> None:
    w = _world(make_world, VelocityGains(wind_hold=True), 12.0, camera=True)
    before, _ = w.drone_pose()
    deck_z = float(w.deck.pose()[0][2])
    shift = w.trim(keep_view=True)
    pos, R = w.drone_pose()
    np.testing.assert_allclose(pos, before + shift, atol=1e-9)
    assert shift[2] == 0.0 and 0.3 < float(np.hypot(*shift[:2])) < 1.0  # upwind, by depth x tan(lean)
    wind_dir = np.asarray(w.disturbances[0].mean[:2]) / 12.0
    assert float(shift[:2] @ wind_dir) < 0.0  # the drone moves upwind
    cam = pos + R @ np.asarray(w.config.rig.camera_position)
    axis = -R[:, 2]
    hit = cam + axis * (deck_z - cam[2]) / axis[2]
    np.testing.assert_allclose(hit[:2], before[:2], atol=1e-6)
    # the autopilot holds the shifted position
    np.testing.assert_allclose(w.controller.p_ref[:2], pos[:2], atol=1e-6)


def test_trim_in_calm_air_changes_nothing(make_world: Any) -> None:
    w = _world(make_world, VelocityGains(wind_hold=True), 0.0)
    before, R0 = w.drone_pose()
    assert not np.any(w.trim(keep_view=True))
    pos, R = w.drone_pose()
    np.testing.assert_allclose(pos, before, atol=1e-12)
    np.testing.assert_allclose(R, R0, atol=1e-9)
    np.testing.assert_allclose(w.controller.disturbance, [0.0, 0.0], atol=1e-12)
    assert matrix_from_quat(np.asarray(w.quad.state()[1]))[2, 2] == pytest.approx(1.0)
