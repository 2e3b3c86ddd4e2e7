"""Closed-form contacts and ground effect of the numpy physics against PyBullet and the scalar code."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.sim.batched import contact
from ihrcf_env.sim.batched.surface import rotor_positions_batch, thrust_scale_batch
from ihrcf_env.sim.ground_effect import GroundEffect, rotor_positions
from ihrcf_env.sim.world import World


def test_drone_corners_come_from_the_urdf() -> None:
    c = contact.drone_corners()
    assert c.shape == (40, 3)  # five boxes
    assert c[:, 2].min() == pytest.approx(-0.0625 - 0.0375)  # the legs' feet
    assert np.abs(c[:, 0]).max() == pytest.approx(0.126)


def _pybullet_contact(world: World, pos: np.ndarray, quat: np.ndarray) -> set[str]:
    cid = world.client
    p.resetBasePositionAndOrientation(world.quad.body, pos.tolist(), quat.tolist(), physicsClientId=cid)
    p.performCollisionDetection(physicsClientId=cid)
    ids = {c[2] for c in p.getContactPoints(bodyA=world.quad.body, physicsClientId=cid) if c[8] < 0}
    names = {world.deck.body: "deck", world.ground: "ground", world.deck.base_body: "base"}
    return {names[i] for i in ids if i in names}


def test_contacts_agree_with_pybullet_away_from_the_boundary() -> None:
    """Random poses around the deck's edge, the base and the ground: where every collision corner
    is at least 3 mm from every surface, the closed form and PyBullet's penetrating contacts agree."""
    world = World(WorldConfig(camera=None))
    try:
        deck_pos, deck_R = world.deck.pose()
        rng = np.random.default_rng(3)
        half = world.deck.top_half_extent
        geo = world.config.stewart
        agree = checked = 0
        for _ in range(400):
            kind = rng.integers(3)
            if kind == 0:  # over the deck and its edges
                xy = rng.uniform(-half - 0.2, half + 0.2, 2)
                z = deck_pos[2] + rng.uniform(0.02, 0.16)
            elif kind == 1:  # near the ground, beside the platform
                r, a = rng.uniform(0.9, 1.5), rng.uniform(0, 2 * math.pi)
                xy, z = np.array([r * math.cos(a), r * math.sin(a)]), rng.uniform(0.0, 0.2)
            else:  # near the base's rim
                r, a = rng.uniform(geo.base_radius - 0.1, geo.base_radius + 0.3), rng.uniform(0, 2 * math.pi)
                xy, z = np.array([r * math.cos(a), r * math.sin(a)]), rng.uniform(0.05, 0.3)
            rpy = rng.uniform(-0.4, 0.4, 3)
            quat = np.array(p.getQuaternionFromEuler(rpy.tolist()))
            pos = np.array([xy[0], xy[1], z])
            R = matrix_from_quat(quat)
            pts = contact.corners_world(pos[None], R[None])[0]
            d = (pts - deck_pos) @ deck_R
            margins = [np.abs(pts[:, 2]).min()]
            margins.append(np.abs(d[:, 2]).min())
            margins.append(np.abs(np.abs(d[:, :2]) - half).min())
            rad = np.hypot(pts[:, 0], pts[:, 1])
            margins.append(np.abs(rad - (geo.base_radius + 0.06)).min())
            margins.append(np.abs(pts[:, 2] - geo.base_height).min())
            if min(margins) < 0.003:
                continue
            checked += 1
            code = contact.first_contact(
                pos[None],
                R[None],
                deck_pos[None],
                deck_R[None],
                half,
                world.config.deck.thickness,
                geo.base_radius + 0.06,
                geo.base_height,
            )[0]
            got = _pybullet_contact(world, pos, quat)
            want = "deck" if "deck" in got else ("ground" if "ground" in got else ("base" if got else ""))
            agree += contact.CONTACT_NAMES[code] == want
        assert checked > 100
        assert agree == checked
    finally:
        world.close()


def test_batched_ground_effect_equals_the_scalar_model() -> None:
    ge = GroundEffect(0.065)
    rng = np.random.default_rng(0)
    n = 64
    pos = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), rng.uniform(0.0, 0.6, n)])
    R = np.stack([matrix_from_quat(q / np.linalg.norm(q)) for q in rng.normal([0, 0, 0, 8], 1, (n, 4))])
    deck_p = np.column_stack([rng.uniform(-0.05, 0.05, (n, 2)), rng.uniform(0.0, 0.3, n)])
    deck_R = np.stack([matrix_from_quat(q / np.linalg.norm(q)) for q in rng.normal([0, 0, 0, 10], 1, (n, 4))])
    motor_xy = np.array([[0.106, 0.106], [0.106, -0.106], [-0.106, -0.106], [-0.106, 0.106]])
    rotors = rotor_positions_batch(pos, R, motor_xy)
    got = thrust_scale_batch(ge, rotors, deck_p, deck_R, 0.3)
    for i in range(n):
        r_s = rotor_positions(pos[i].tolist(), R[i].ravel().tolist(), motor_xy.tolist())
        np.testing.assert_allclose(rotors[i], np.array(r_s), rtol=0, atol=1e-15)
        want = ge.thrust_scale(r_s, deck_p[i].tolist(), deck_R[i].tolist(), 0.3)
        np.testing.assert_allclose(got[i], want, rtol=1e-14)
    # rows do not depend on the other rows
    np.testing.assert_array_equal(
        thrust_scale_batch(ge, rotors[5:6], deck_p[5:6], deck_R[5:6], 0.3), got[5:6]
    )
