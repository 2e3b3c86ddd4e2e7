"""Tests for ihrcf_env.core.geometry with synthetic data of known answer."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.core.geometry import (
    apply_homography,
    collinear,
    fit_plane,
    homography_from_points,
    plane_z,
    quad_is_degenerate,
    rigid_fit,
)
from ihrcf_env.core.rig import tag_corners_deck


def _random_h(rng: np.random.Generator) -> np.ndarray:
    H = np.eye(3) + rng.normal(0, 0.3, (3, 3))
    H[2, :2] = rng.normal(0, 0.002, 2)  # mild perspective, like the image <-> deck-plane maps
    H[:2, 2] = rng.uniform(-200, 200, 2)
    return H / H[2, 2]


@pytest.mark.parametrize("n", [4, 10])
def test_homography_recovers_random_h(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(20):
        H = _random_h(rng)
        src = rng.uniform(-100, 100, (n, 2))
        dst = apply_homography(H, src)
        H_est = homography_from_points(src, dst)
        assert H_est[2, 2] == 1.0
        np.testing.assert_allclose(H_est, H, rtol=1e-8, atol=1e-8 * np.abs(H).max())


def test_homography_metric_to_pixel_scale_and_inverse_round_trip() -> None:
    # Metres (0.1 m sensor square) to pixels (~500 px): the normalisation must cope with the scales.
    rng = np.random.default_rng(0)
    src = np.array([[-0.07, -0.07], [0.07, -0.07], [0.07, 0.07], [-0.07, 0.07]])
    H = np.array([[443.0, 12.0, 255.5], [-8.0, 440.0, 255.5], [0.05, -0.08, 1.0]])
    H_est = homography_from_points(src, apply_homography(H, src))
    np.testing.assert_allclose(H_est, H, rtol=1e-9, atol=1e-9)
    pts = rng.uniform(-0.3, 0.3, (50, 2))
    back = apply_homography(np.linalg.inv(H_est), apply_homography(H_est, pts))
    np.testing.assert_allclose(back, pts, atol=1e-12)


def test_homography_rejects_exactly_degenerate_and_bad_shapes() -> None:
    src = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])  # three collinear
    dst = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="degenerate"):
        homography_from_points(src, dst)
    with pytest.raises(ValueError, match="src"):
        homography_from_points(np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match="dst"):
        homography_from_points(np.eye(4, 2), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="same shape"):
        homography_from_points(np.random.default_rng(0).normal(size=(5, 2)), np.eye(4, 2))
    with pytest.raises(ValueError, match="H"):
        apply_homography(np.eye(2), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="pts"):
        apply_homography(np.eye(3), np.zeros(2))


def test_four_point_homography_matches_dlt_and_ignores_translation() -> None:
    # N = 4 is solved in closed form through the unit square, N > 4 by normalised DLT: the same map.
    rng = np.random.default_rng(7)
    for _ in range(50):
        H = _random_h(rng)
        src = rng.uniform(-100, 100, (5, 2))
        dst = apply_homography(H, src)
        np.testing.assert_allclose(
            homography_from_points(src[:4], dst[:4]), homography_from_points(src, dst), rtol=1e-8, atol=1e-8
        )
    # a well-shaped small quad far from the origin is not mistaken for a degenerate one
    quad = np.array([[0.0, 0.0], [1.0, 0.1], [1.1, 1.0], [-0.1, 0.9]])
    for offset in (0.0, 1e3, 1e5):
        H = homography_from_points(quad + offset, quad * 300.0)
        np.testing.assert_allclose(apply_homography(H, quad + offset), quad * 300.0, atol=1e-6)


def test_collinear_detection_is_scale_invariant() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    nearly = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1e-4], [0.0, 1.0]])
    for scale in (1e-6, 1.0, 1e6):
        assert not collinear(square * scale)
        assert not quad_is_degenerate(square * scale)
        assert quad_is_degenerate(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.0, 1.0]]) * scale)
        assert collinear(nearly * scale, tol=1e-3)
        assert not collinear(nearly * scale, tol=1e-5)
    assert collinear(np.array([[1.0, 1.0], [1.0, 1.0], [3.0, 0.0]]))  # coincident points
    assert not collinear(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    with pytest.raises(ValueError, match="pts"):
        quad_is_degenerate(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="pts"):
        collinear(np.zeros((2, 2)))


def _tilted_plane_points(n_true: np.ndarray, d_true: float, xy: np.ndarray) -> np.ndarray:
    z = (d_true - n_true[0] * xy[:, 0] - n_true[1] * xy[:, 1]) / n_true[2]
    return np.column_stack([xy, z])


@pytest.mark.parametrize("n_points", [3, 4, 7])
def test_fit_plane_tilted(n_points: int) -> None:
    rng = np.random.default_rng(n_points)
    n_true = np.array([0.25, -0.35, 1.0])
    n_true /= np.linalg.norm(n_true)
    d_true = 0.9
    xy = rng.uniform(-0.2, 0.2, (n_points, 2))
    pts = _tilted_plane_points(n_true, d_true, xy)
    n, d = fit_plane(pts)
    np.testing.assert_allclose(n, n_true, atol=1e-12)
    assert d == pytest.approx(d_true, abs=1e-12)
    # Same plane from reversed order (flips the cross product): the sign convention still holds.
    n2, d2 = fit_plane(pts[::-1])
    np.testing.assert_allclose(n2, n_true, atol=1e-12)
    assert d2 == pytest.approx(d_true, abs=1e-12)
    q = rng.uniform(-1, 1, (5, 2))
    np.testing.assert_allclose(plane_z(n, d, q), _tilted_plane_points(n_true, d_true, q)[:, 2], atol=1e-12)


def test_fit_plane_least_squares_on_noisy_points() -> None:
    # 4 points on z = 1 with +-e offsets alternating: the LSQ plane is z = 1 exactly.
    e = 1e-3
    pts = np.array([[-1, -1, 1 + e], [1, -1, 1 - e], [1, 1, 1 + e], [-1, 1, 1 - e]], dtype=float)
    n, d = fit_plane(pts)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-12)
    assert d == pytest.approx(1.0)


def test_fit_plane_and_plane_z_errors() -> None:
    with pytest.raises(ValueError, match="points"):
        fit_plane(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="collinear"):
        fit_plane(np.array([[0, 0, 1], [1, 1, 2], [2, 2, 3.0]]))
    with pytest.raises(ValueError, match="collinear"):
        fit_plane(np.array([[0, 0, 1], [1, 1, 2], [2, 2, 3.0], [3, 3, 4.0]]))
    with pytest.raises(ValueError, match="coincident"):
        fit_plane(np.ones((4, 3)))
    with pytest.raises(ValueError, match="parallel"):
        plane_z(np.array([1.0, 0.0, 0.0]), 1.0, np.zeros((1, 2)))
    with pytest.raises(ValueError, match="normal"):
        plane_z(np.zeros(2), 1.0, np.zeros((1, 2)))


def test_rigid_fit_exact_recovery() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        R = Rotation.random(random_state=rng).as_matrix()
        t = rng.uniform(-2, 2, 3)
        P = rng.normal(size=(6, 3))
        R_est, t_est, rms = rigid_fit(P, P @ R.T + t)
        np.testing.assert_allclose(R_est, R, atol=1e-12)
        np.testing.assert_allclose(t_est, t, atol=1e-12)
        assert rms < 1e-12


def _naive_kabsch(P: np.ndarray, Q: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd((Q - Q.mean(0)).T @ (P - P.mean(0)))
    return U @ Vt


def test_rigid_fit_det_guard_coplanar_points() -> None:
    # For coplanar points (our tag corners) the cross-covariance has rank 2 and the unguarded SVD
    # returns a reflection for some poses, even with exact data.
    rng = np.random.default_rng(2)
    P = tag_corners_deck(0.4)
    reflections = 0
    for _ in range(50):
        R = Rotation.random(random_state=rng).as_matrix()
        t = rng.uniform(-1, 1, 3)
        Q = P @ R.T + t
        reflections += np.linalg.det(_naive_kabsch(P, Q)) < 0
        R_est, t_est, rms = rigid_fit(P, Q)
        assert np.linalg.det(R_est) == pytest.approx(1.0)
        np.testing.assert_allclose(R_est, R, atol=1e-9)
        np.testing.assert_allclose(t_est, t, atol=1e-9)
        assert rms < 1e-9
    assert reflections > 0  # the cases above really exercised the guard


def test_rigid_fit_mirrored_data_returns_best_rotation() -> None:
    rng = np.random.default_rng(3)
    P = rng.normal(size=(8, 3))
    R = Rotation.random(random_state=rng).as_matrix()
    Q = (P @ np.diag([1.0, 1.0, -1.0])) @ R.T + np.array([0.3, -0.2, 1.0])
    assert np.linalg.det(_naive_kabsch(P, Q)) < 0
    R_est, t_est, rms = rigid_fit(P, Q)
    assert np.linalg.det(R_est) == pytest.approx(1.0)
    # Reference optimum among proper rotations (scipy's Kabsch on centred points).
    R_ref = Rotation.align_vectors(Q - Q.mean(0), P - P.mean(0))[0].as_matrix()
    np.testing.assert_allclose(R_est, R_ref, atol=1e-9)
    np.testing.assert_allclose(t_est, Q.mean(0) - R_ref @ P.mean(0), atol=1e-9)
    res = P @ R_est.T + t_est - Q
    assert rms == pytest.approx(np.sqrt(np.mean(np.sum(res**2, axis=1))))
    assert rms > 0.1


def test_rigid_fit_errors() -> None:
    with pytest.raises(ValueError, match="Q"):
        rigid_fit(np.zeros((4, 3)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="same shape"):
        rigid_fit(np.eye(3), np.eye(4, 3))
    with pytest.raises(ValueError, match="collinear"):
        rigid_fit(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]), np.eye(3))
    with pytest.raises(ValueError, match="NaN"):
        rigid_fit(np.full((3, 3), np.nan), np.eye(3))
