"""Touchdown geometry (ihrcf_env.fast.contact) against sim.batched.contact.first_contact: the same
contact code for every pose, including boxes just touching and just clear of the deck plate."""

from __future__ import annotations

import numpy as np

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.fast.contact import box_corners, first_contact
from ihrcf_env.sim.batched.contact import drone_boxes, drone_corners
from ihrcf_env.sim.batched.contact import first_contact as np_first_contact

from .fast_helpers import Counted, rotations

CFG = WorldConfig(camera=None)
C, H = drone_boxes()
HALF, THICK = CFG.deck.size / 2, CFG.deck.thickness
BASE_R, BASE_H = CFG.stewart.base_radius + 0.06, CFG.stewart.base_height
CORNERS = box_corners(C, H)
CONTACT = Counted(
    lambda p, R, dp, dR: first_contact(p, R, dp, dR, HALF, THICK, BASE_R, BASE_H, C, H, CORNERS)
)


def test_corners_match() -> None:
    assert np.array_equal(CORNERS, drone_corners())


def test_contact_codes_match() -> None:
    rng = np.random.default_rng(0)
    n = 2048
    R = rotations(rng, n, 0.8)
    dR = rotations(rng, n, 0.3)
    dp = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0.5, 1.1, n)])
    p = dp + np.column_stack([rng.uniform(-0.8, 0.8, (n, 2)), rng.uniform(-0.2, 0.3, n)])
    p[:256, 2] = rng.uniform(-0.05, 0.2, 256)  # near the ground, off the deck
    p[256:512, :2] = rng.uniform(-0.8, 0.8, (256, 2))  # around the base
    p[256:512, 2] = rng.uniform(0.0, 0.4, 256)
    want = np_first_contact(p, R, dp, dR, HALF, THICK, BASE_R, BASE_H)
    got = np.asarray(CONTACT(p, R, dp, dR))
    assert np.array_equal(got, want)
    assert set(np.unique(want).tolist()) == {0, 1, 2, 3}


def test_just_touching_and_just_clear() -> None:
    """A level drone over a level deck: its lowest corner 1 um above the top face is clear, 1 um
    below it touches."""
    n = 2
    dp = np.tile([0.0, 0.0, 0.8], (n, 1))
    dR = np.tile(np.eye(3), (n, 1, 1))
    low = -CORNERS[:, 2].min()
    p = dp + np.array([[0.0, 0.0, low + 1e-6], [0.0, 0.0, low - 1e-6]])
    R = np.tile(np.eye(3), (n, 1, 1))
    got = np.asarray(CONTACT(p, R, dp, dR)).tolist()
    assert got == np_first_contact(p, R, dp, dR, HALF, THICK, BASE_R, BASE_H).tolist() == [0, 1]
