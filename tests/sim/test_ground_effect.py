"""Ground effect per rotor over the deck or the ground (Cheeseman-Bennett), and thrust_scale."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.vehicle import QuadParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.frames import matrix_from_euler
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.ground_effect import GroundEffect, cheeseman_bennett, rotor_positions
from ihrcf_env.sim.world import World

R = 0.1016  # the default rotor radius (8-inch propeller)


def test_ratio_at_1_2_4_rotor_radii() -> None:
    """1 / (1 - (R / 4z)^2): 16/15, 64/63, 256/255 (docs/flight-model.md)."""
    assert cheeseman_bennett(R, R) == pytest.approx(16 / 15)  # 1.0667
    assert cheeseman_bennett(2 * R, R) == pytest.approx(64 / 63)  # 1.0159
    assert cheeseman_bennett(4 * R, R) == pytest.approx(256 / 255)  # 1.0039
    assert QuadParams().rotor_radius == R


def test_ratio_tends_to_1_far_away_and_is_capped_close() -> None:
    assert 1.0 < cheeseman_bennett(100 * R, R) < 1.0 + 1e-5
    assert cheeseman_bennett(1e4, R) == pytest.approx(1.0, abs=1e-10)
    cap = cheeseman_bennett(0.5 * R, R)
    assert cap == pytest.approx(4 / 3)
    for z in (0.4 * R, 0.1 * R, 0.0, -1.0):  # at or below the floor of 0.5 R: held there
        assert cheeseman_bennett(z, R) == cap
    heights = np.linspace(0.5 * R, 10 * R, 50)
    ratios = [cheeseman_bennett(float(z), R) for z in heights]
    assert all(a > b for a, b in zip(ratios, ratios[1:], strict=False))  # decreasing with height


def _level_deck(height: float) -> tuple[np.ndarray, np.ndarray]:
    return np.array([0.0, 0.0, height]), np.eye(3)


def test_rotors_over_the_deck_feel_the_deck_others_the_ground() -> None:
    ge = GroundEffect(R)
    deck_pos, deck_rot = _level_deck(0.8)  # top face 0.8 m above the ground, 0.6 m square
    half = 0.3
    over = (0.1, 0.0, 0.8 + R)  # one radius above the deck
    beyond = (0.3 + 1.5 * R, 0.0, 0.8 + R)  # past the edge by more than a radius: the ground, 0.9 m down
    edge = (0.3, 0.0, 0.8 + R)  # centre on the edge: half the disc over the deck
    low = (0.6, 0.0, R)  # beside the deck, one radius above the ground
    s = ge.thrust_scale([over, beyond, edge, low], deck_pos, deck_rot, half)
    assert s[0] == pytest.approx(16 / 15)
    assert s[1] == pytest.approx(cheeseman_bennett(0.8 + R, R))
    assert s[2] == pytest.approx(0.5 * (16 / 15 + cheeseman_bennett(0.8 + R, R)))
    assert s[3] == pytest.approx(16 / 15)
    # continuous across the edge
    xs = np.linspace(0.3 - 2 * R, 0.3 + 2 * R, 81)
    ratios = [ge.thrust_scale([(float(x), 0.0, 0.8 + R)], deck_pos, deck_rot, half)[0] for x in xs]
    assert max(abs(a - b) for a, b in zip(ratios, ratios[1:], strict=False)) < 0.005
    # a rotor below the deck's top plane (beside it, lower) is not over the deck
    assert ge.thrust_scale([(0.0, 0.0, 0.5)], deck_pos, deck_rot, half)[0] == pytest.approx(
        cheeseman_bennett(0.5, R)
    )


def test_tilted_deck_uses_the_distance_to_its_plane() -> None:
    ge = GroundEffect(R)
    tilt = math.radians(10.0)
    deck_rot = matrix_from_euler(tilt, 0.0, 0.0)  # rolled about x: +y side goes up
    deck_pos = np.array([0.0, 0.0, 1.0])
    n = deck_rot[:, 2]
    # two rotors at the same world height 1.0 + 1.5 R, on either side of the roll axis
    a, b = (0.0, 0.1, 1.0 + 1.5 * R), (0.0, -0.1, 1.0 + 1.5 * R)
    sa, sb = ge.thrust_scale([a, b], deck_pos, deck_rot, 0.3)
    ha, hb = float(n @ (np.array(a) - deck_pos)), float(n @ (np.array(b) - deck_pos))
    assert ha < hb  # the +y side of the deck is higher: closer to rotor a
    assert sa == pytest.approx(cheeseman_bennett(ha, R))
    assert sb == pytest.approx(cheeseman_bennett(hb, R))
    assert sa > sb > 1.0


def test_rotor_positions_follow_the_body() -> None:
    q = p.getQuaternionFromEuler([0.0, 0.0, math.pi / 2])
    rot = p.getMatrixFromQuaternion(q)
    xy = QuadParams().motor_xy.tolist()
    pts = rotor_positions((1.0, 2.0, 3.0), rot, xy)
    d = 0.15 / math.sqrt(2)
    np.testing.assert_allclose(pts[0], (1.0 - d, 2.0 + d, 3.0), atol=1e-12)  # front-left, yawed 90 deg


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="rotor_radius"):
        GroundEffect(0.0)
    with pytest.raises(TypeError, match="rotor_radius"):
        GroundEffect("0.1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="min_height_ratio"):
        GroundEffect(R, min_height_ratio=0.25)
    with pytest.raises(ValueError, match="rotor_radius"):
        QuadParams(rotor_radius=2.0)


def _free_flight(world: World, scale: tuple[float, ...] | None, steps: int = 24) -> np.ndarray:
    """Hover-speed rotors from rest 5 m up, ``steps`` physics steps with ``thrust_scale``."""
    world.reset(StaticProfile(), horizon_s=5.0, altitude=5.0)
    quad = world.quad
    cmd = list(quad.rotor_speed)
    for _ in range(steps):
        pos, quat, vel, _ = quad.state()
        quad.apply(cmd, world.dt, pos, quat, vel, thrust_scale=scale) if scale is not None else quad.apply(
            cmd, world.dt, pos, quat, vel
        )
        p.stepSimulation(physicsClientId=world.client)
    return np.concatenate([np.asarray(x) for x in quad.state()])


def test_thrust_scale_default_is_bit_for_bit_and_scales_the_force() -> None:
    w = World(WorldConfig(camera=None))
    try:
        plain = _free_flight(w, None)
        ones = _free_flight(w, (1.0, 1.0, 1.0, 1.0))
        assert np.array_equal(plain, ones)
        up = _free_flight(w, (1.1, 1.1, 1.1, 1.1))
        t = 24 * w.dt
        # 10 % more thrust than the weight: 0.1 g upwards, no rotation
        assert up[9] == pytest.approx(0.1 * 9.81 * t, rel=0.02)
        assert np.abs(up[10:13]).max() < 1e-9
        tilted = _free_flight(w, (1.1, 1.0, 1.0, 1.1))  # more thrust on the left (+y) rotors
        assert tilted[10] > 1e-3  # the left side rises: a positive rate about x
    finally:
        w.close()


def test_deck_surface_matches_the_deck_pose() -> None:
    """The scalar top-face pose the world passes each physics step equals ``Deck.pose()``."""
    from ihrcf_env.core.profiles import CallableProfile
    from ihrcf_env.sim.ground_effect import deck_surface

    offset, rpy = np.array([0.02, -0.01, 0.03]), np.array([0.08, -0.05, 0.3])
    w = World(WorldConfig(camera=None))
    try:
        w.reset(CallableProfile(lambda t: (offset, rpy)), horizon_s=2.0, altitude=0.5)
        w.step()
        body_pos, body_quat = p.getBasePositionAndOrientation(w.deck.body, physicsClientId=w.client)
        point, rot = deck_surface(body_pos, body_quat, w.config.deck.thickness / 2)
        deck_pos, deck_rot = w.deck.pose()
        np.testing.assert_allclose(point, deck_pos, atol=1e-12)
        np.testing.assert_allclose(np.reshape(rot, (3, 3)), deck_rot, atol=1e-12)
        ge = GroundEffect(R)
        rotors = rotor_positions(*w.drone_pose()[:1], np.reshape(w.drone_pose()[1], 9).tolist(), [(0.1, 0.1)])
        a = ge.thrust_scale(rotors, point, rot, w.deck.top_half_extent)
        b = ge.thrust_scale(rotors, deck_pos, deck_rot, w.deck.top_half_extent)
        assert a == pytest.approx(b, abs=1e-12) and a[0] > 1.0
    finally:
        w.close()


def test_the_world_applies_ground_effect_when_asked() -> None:
    """A drone resting its rotors ~1 R above the deck gets more thrust with ground_effect on: with
    the same commands it climbs away from the deck, and the option is off by default."""
    from ihrcf_env.core.profiles import StaticProfile

    heights = []
    for flag in (False, True):
        w = World(WorldConfig(camera=None, ground_effect=flag))
        try:
            w.reset(StaticProfile(), 10.0, altitude=0.13)
            for _ in range(20):
                w.step()
            heights.append(w.sensing.snapshot().drone_position[2])
        finally:
            w.close()
    assert WorldConfig().ground_effect is False
    assert heights[1] > heights[0] + 0.005
