"""Stewart-platform kinematics and motion profiles (pure numpy, no simulator)."""

import math

import numpy as np
import pytest

from ihrcf_env.core.frames import matrix_from_euler
from ihrcf_env.core.profiles import (
    CallableProfile,
    StaticProfile,
    make_profile,
    paper_profile,
    sea_state_profile,
)
from ihrcf_env.core.stewart import StewartGeometry

GEO = StewartGeometry()


def _hand_leg(base_deg: float, top_deg: float, dz: float, yaw: float = 0.0, dx: float = 0.0) -> float:
    """Leg length from polar joint coordinates, computed by hand (law of cosines in the plane)."""
    rb, rt = GEO.base_radius, GEO.top_radius
    bx, by = rb * math.cos(math.radians(base_deg)), rb * math.sin(math.radians(base_deg))
    a = math.radians(top_deg) + yaw
    tx, ty = rt * math.cos(a) + dx, rt * math.sin(a)
    return math.sqrt((tx - bx) ** 2 + (ty - by) ** 2 + dz**2)


# base joint angle, top joint angle (deg) of legs 1..6 for the default 20-degree pair spacing
LEGS = [(-10, -50), (10, 50), (110, 70), (130, 170), (230, 190), (250, 290)]


def test_home_leg_lengths_match_hand_computation():
    dz = GEO.home_height - GEO.joint_depth - GEO.base_height
    expected = [_hand_leg(b, t, dz) for b, t in LEGS]
    # law of cosines: all six equal at home by symmetry
    rb, rt = GEO.base_radius, GEO.top_radius
    cos40 = math.cos(math.radians(40))
    by_cosines = math.sqrt(rb**2 + rt**2 - 2 * rb * rt * cos40 + dz**2)
    np.testing.assert_allclose(GEO.neutral_lengths, expected, atol=1e-12)
    np.testing.assert_allclose(GEO.neutral_lengths, by_cosines, atol=1e-12)


@pytest.mark.parametrize(
    "heave, yaw, surge",
    [(0.05, 0.0, 0.0), (-0.04, 0.0, 0.0), (0.0, math.radians(7.0), 0.0), (0.02, math.radians(-5.0), 0.03)],
)
def test_leg_lengths_for_known_poses(heave, yaw, surge):
    dz = GEO.home_height + heave - GEO.joint_depth - GEO.base_height
    expected = [_hand_leg(b, t, dz, yaw=yaw, dx=surge) for b, t in LEGS]
    pos = GEO.home_position + np.array([surge, 0.0, heave])
    got = GEO.leg_lengths(pos, matrix_from_euler(0.0, 0.0, yaw))
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_pure_roll_lengthens_one_side_and_shortens_the_other():
    R = matrix_from_euler(math.radians(10.0), 0.0, 0.0)
    L = GEO.leg_lengths(GEO.home_position, R)
    top = GEO.top_joints
    # roll about +x raises the +y side: legs whose top joint has y > 0 get longer
    assert np.all(L[top[:, 1] > 0.1] > GEO.neutral_lengths[0])
    assert np.all(L[top[:, 1] < -0.1] < GEO.neutral_lengths[0])


def test_leg_lengths_broadcast_over_poses():
    R = np.stack([matrix_from_euler(0.1 * k, -0.05 * k, 0.02 * k) for k in range(5)])
    P = GEO.home_position + np.linspace(0, 0.05, 5)[:, None] * np.array([1.0, -1.0, 0.5])
    batch = GEO.leg_lengths(P, R)
    assert batch.shape == (5, 6)
    for k in range(5):
        np.testing.assert_allclose(batch[k], GEO.leg_lengths(P[k], R[k]), atol=1e-14)


def test_stroke_violation_names_time_and_leg():
    t = np.array([0.0, 0.5, 1.0])
    L = np.tile(GEO.neutral_lengths, (3, 1))
    L[2, 4] = GEO.max_leg + 0.01
    with pytest.raises(ValueError, match=r"t = 1\.000 s: leg 5"):
        GEO.check_stroke(t, L)


def test_bad_geometry_rejected():
    with pytest.raises(ValueError, match="top_radius"):
        StewartGeometry(top_radius=-1.0)


def test_paper_profile_amplitudes_and_start():
    prof = paper_profile()
    t = np.arange(0, 130, 0.05)
    off, rpy = prof.sample(t)
    np.testing.assert_allclose(off[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(rpy[0], 0.0, atol=1e-12)
    assert 0.01 < np.abs(off).max() < 0.06  # centimetres
    assert math.radians(10) < np.abs(rpy[:, :2]).max() < math.radians(16)  # ~10-15 deg roll/pitch
    assert math.radians(2) < np.abs(rpy[:, 2]).max() < math.radians(12)  # some yaw
    # within the legs' stroke over the whole run
    from scipy.spatial.transform import Rotation

    R = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    GEO.check_stroke(t, GEO.leg_lengths(GEO.home_position + off, R))


def test_sea_state_is_seeded_and_bounded():
    a = sea_state_profile(np.random.default_rng(3))
    b = sea_state_profile(np.random.default_rng(3))
    c = sea_state_profile(np.random.default_rng(4))
    t = np.linspace(0, 60, 600)
    np.testing.assert_array_equal(a.sample(t)[0], b.sample(t)[0])
    assert not np.array_equal(a.sample(t)[0], c.sample(t)[0])
    prof = sea_state_profile(np.random.default_rng(0), {"heave": 0.02, "roll": 0.0})
    off, rpy = prof.sample(t)
    assert np.abs(off[:, 2]).max() <= 0.02 + 1e-12
    assert np.abs(rpy[:, 0]).max() == 0.0
    with pytest.raises(ValueError, match="unknown"):
        sea_state_profile(np.random.default_rng(0), {"swell": 1.0})


def test_callable_profile_and_make_profile():
    prof = CallableProfile(lambda t: (np.array([0.0, 0.0, 0.01 * t]), np.zeros(3)))
    off, rpy = prof.sample(np.array([0.0, 1.0, 2.0]))
    np.testing.assert_allclose(off[:, 2], [0.0, 0.01, 0.02])
    with pytest.raises(ValueError, match="finite"):
        CallableProfile(lambda t: np.array([np.nan] * 6)).sample(np.array([0.0]))
    with pytest.raises(ValueError, match="deck_profile"):
        make_profile("tsunami", np.random.default_rng(0))
    assert isinstance(make_profile("static", np.random.default_rng(0)), StaticProfile)


def test_batched_euler_matrices_match_the_scalar_ones_and_scipy():
    from scipy.spatial.transform import Rotation

    from ihrcf_env.core.frames import matrices_from_euler

    rpy = np.random.default_rng(4).uniform(-3.0, 3.0, (200, 3))
    R = matrices_from_euler(rpy)
    assert R.shape == (200, 3, 3)
    for k in (0, 57, 199):
        assert np.array_equal(R[k], matrix_from_euler(*rpy[k]))
    np.testing.assert_allclose(R, Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix(), rtol=0, atol=1e-14)
    with pytest.raises(ValueError, match="rpy"):
        matrices_from_euler(np.zeros(3))


def test_leg_lengths_equal_the_norm_of_the_leg_vectors():
    rng = np.random.default_rng(5)
    from ihrcf_env.core.frames import matrices_from_euler

    R = matrices_from_euler(rng.uniform(-0.2, 0.2, (50, 3)))
    p = GEO.home_position + rng.uniform(-0.05, 0.05, (50, 3))
    want = np.linalg.norm(
        np.einsum("nij,kj->nki", R, GEO.top_joints) + p[:, None, :] - GEO.base_joints, axis=-1
    )
    np.testing.assert_allclose(GEO.leg_lengths(p, R), want, rtol=0, atol=1e-14)
    assert GEO.leg_lengths(p[0], R[0]).shape == (6,)
