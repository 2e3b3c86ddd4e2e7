"""Touchdown geometry (ihrcf_env.fast.contact) against PyBullet's collision detection in a world's
scene (the drone's URDF boxes, the deck plate, the ground plane, the Stewart base's cylinder):
the drone's collision corners are PyBullet's collision shapes', and the contact code of random
poses is the body PyBullet finds penetrating (deck first, then ground, then base, as the world's
touchdown names it), for every pose whose PyBullet distance to each body is at least
:data:`CLEARANCE` from zero (Bullet's convex shapes carry a GJK tolerance; the plate and the
ground are exact to 1e-16 m: a level drone 1 um above the deck is clear, 1 um into it touches).
Measured: the codes are equal for all 2048 poses, the 1923 compared among them."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.collision import drone_boxes
from ihrcf_env.fast import contact as fc
from ihrcf_env.fast.contact import box_corners, first_contact
from ihrcf_env.sim.world import World

from .fast_helpers import Counted, rotations

CFG = WorldConfig(camera=None)
C, H = drone_boxes()
HALF, THICK = CFG.deck.size / 2, CFG.deck.thickness
BASE_R, BASE_H = CFG.stewart.base_radius + 0.06, CFG.stewart.base_height
CORNERS = box_corners(C, H)
CONTACT = Counted(
    lambda p, R, dp, dR: first_contact(p, R, dp, dR, HALF, THICK, BASE_R, BASE_H, C, H, CORNERS)
)
#: Poses nearer than this (m) to touching a body (PyBullet's distance) are not compared.
CLEARANCE = 0.003


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    w = World(CFG)
    yield w
    w.close()


def _bodies(w: World) -> dict[int, int]:
    """The scene's collision bodies -> their contact codes."""
    return {w.deck.body: fc.DECK, w.ground: fc.GROUND, w.deck.base_body: fc.BASE}


def bullet_contacts(
    w: World, p_: np.ndarray, R: np.ndarray, dp: np.ndarray, dR: np.ndarray
) -> tuple[int, float]:
    """(contact code, smallest |distance| (m) to any body) of the drone at ``p_`` with ``R`` and
    the deck's top face at ``dp`` with ``dR``, by PyBullet."""
    cid = w.client
    q = Rotation.from_matrix(R).as_quat()
    dq = Rotation.from_matrix(dR).as_quat()
    plate = dp - dR[:, 2] * (THICK / 2)
    p.resetBasePositionAndOrientation(w.deck.body, plate.tolist(), dq.tolist(), physicsClientId=cid)
    p.resetBasePositionAndOrientation(w.quad.body, p_.tolist(), q.tolist(), physicsClientId=cid)
    p.performCollisionDetection(physicsClientId=cid)
    touching = {c[2] for c in p.getContactPoints(bodyA=w.quad.body, physicsClientId=cid) if c[8] < 0.0}
    codes = [code for body, code in _bodies(w).items() if body in touching]
    code = min(codes) if codes else fc.NO_CONTACT  # deck (1), then ground (2), then base (3)
    nearest = np.inf
    for body in _bodies(w):
        near = p.getClosestPoints(w.quad.body, body, CLEARANCE, physicsClientId=cid)
        nearest = min([nearest, *(abs(c[8]) for c in near)])
    return code, nearest


def test_corners_are_pybullets_collision_boxes(world: World) -> None:
    shapes = p.getCollisionShapeData(world.quad.body, -1, physicsClientId=world.client)
    assert all(s[2] == p.GEOM_BOX and s[6] == (0.0, 0.0, 0.0, 1.0) for s in shapes)
    centres = np.array([s[5] for s in shapes])
    halves = np.array([s[3] for s in shapes]) / 2
    np.testing.assert_allclose(CORNERS, box_corners(centres, halves), rtol=0, atol=1e-15)


def test_contact_codes_match_pybullet(world: World) -> None:
    rng = np.random.default_rng(0)
    n = 2048
    R = rotations(rng, n, 0.8)
    dR = rotations(rng, n, 0.3)
    dp = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0.5, 1.1, n)])
    pos = dp + np.column_stack([rng.uniform(-0.8, 0.8, (n, 2)), rng.uniform(-0.2, 0.3, n)])
    pos[:256, 2] = rng.uniform(-0.05, 0.2, 256)  # near the ground, off the deck
    pos[256:512, :2] = rng.uniform(-0.8, 0.8, (256, 2))  # around the base
    pos[256:512, 2] = rng.uniform(0.0, 0.4, 256)
    got = np.asarray(CONTACT(pos, R, dp, dR))
    want = np.empty(n, dtype=np.int64)
    clear = np.empty(n, dtype=bool)
    for i in range(n):
        want[i], d = bullet_contacts(world, pos[i], R[i], dp[i], dR[i])
        clear[i] = d >= CLEARANCE
    assert clear.sum() > n // 2
    assert np.array_equal(got[clear], want[clear]), np.flatnonzero(clear & (got != want))
    assert set(np.unique(want[clear]).tolist()) == {0, 1, 2, 3}


def test_just_touching_and_just_clear(world: World) -> None:
    """A level drone over a level deck: its lowest corner 1 um above the top face is clear, 1 um
    below it touches, for both."""
    n = 2
    dp = np.tile([0.0, 0.0, 0.8], (n, 1))
    dR = np.tile(np.eye(3), (n, 1, 1))
    low = -CORNERS[:, 2].min()
    pos = dp + np.array([[0.0, 0.0, low + 1e-6], [0.0, 0.0, low - 1e-6]])
    R = np.tile(np.eye(3), (n, 1, 1))
    got = np.asarray(CONTACT(pos, R, dp, dR)).tolist()
    want = [bullet_contacts(world, pos[i], R[i], dp[i], dR[i])[0] for i in range(n)]
    assert got == want == [fc.NO_CONTACT, fc.DECK]
