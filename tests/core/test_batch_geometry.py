"""Batched geometry kernels (ihrcf_env.core.batch.geometry) equal the single-frame ones row by row,
including the degenerate inputs the single kernels reject (same validity, same message)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.batch.geometry import (
    HOMOGRAPHY_ERRORS,
    PLANE_ERRORS,
    PLANE_Z_ERROR,
    RIGID_ERROR,
    apply_homography_batch,
    collinear_batch,
    euler_batch,
    fit_plane_batch,
    homography4_batch,
    matrix_from_euler_batch,
    plane_z_batch,
    rigid_fit_batch,
)
from ihrcf_env.core.frames import euler_from_matrix, matrix_from_euler
from ihrcf_env.core.geometry import (
    apply_homography,
    collinear,
    fit_plane,
    homography_from_points,
    plane_z,
    rigid_fit,
)

TOL = 1e-9


def _single(fn, *args):
    """(result, '') or (None, the ValueError message)."""
    try:
        return fn(*args), ""
    except ValueError as e:
        return None, str(e)


def test_fit_plane_batch_random_masked_and_degenerate() -> None:
    rng = np.random.default_rng(0)
    n = 300
    pts = rng.normal(size=(n, 4, 3)) + [0.0, 0.0, 2.0]
    use = np.ones((n, 4), dtype=bool)
    use[::3, 1] = False  # three points: eq. (20)
    use[1::7, :2] = False  # two points
    pts[2::11] = pts[2::11, :1]  # coincident
    pts[4::13, :, :] = pts[4::13, :1] + np.linspace(0, 1, 4)[None, :, None] * [1.0, 2.0, 0.5]  # collinear
    pts[5::17, :, 2] = 0.0  # vertical normal along z... a plane z = 0
    pts[6::19, :, 0] = 1.5  # a plane x = 1.5: normal along x, n_z == 0
    normal, offset, code = fit_plane_batch(pts, use)
    for i in range(n):
        k = int(use[i].sum())
        if k < 3:
            assert code[i] == 3
            continue
        res, msg = _single(fit_plane, pts[i][use[i]])
        assert PLANE_ERRORS[code[i]] == msg, i
        if res is not None:
            np.testing.assert_allclose(normal[i], res[0], rtol=0, atol=TOL)
            assert abs(offset[i] - res[1]) <= TOL
    assert set(code.tolist()) == {0, 1, 2, 3}


def test_plane_z_batch() -> None:
    rng = np.random.default_rng(1)
    n = rng.normal(size=(50, 3))
    n[::5, 2] = 0.0  # parallel to z
    n[1] = 0.0
    d = rng.normal(size=50)
    xy = rng.normal(size=(50, 6, 2))
    z, ok = plane_z_batch(n, d, xy)
    for i in range(50):
        res, msg = _single(plane_z, n[i], d[i], xy[i])
        assert (msg == "") == ok[i] and (ok[i] or msg == PLANE_Z_ERROR)
        if res is not None:
            np.testing.assert_allclose(z[i], res, rtol=0, atol=TOL)


def test_homography4_batch_and_application() -> None:
    rng = np.random.default_rng(2)
    n = 300
    src = rng.uniform(-1, 1, (n, 4, 2)) * [[[300.0, 200.0]]] + 250.0
    dst = rng.uniform(-0.2, 0.2, (n, 4, 2))
    src[::9, 2] = src[::9, 0] + 0.5 * (src[::9, 1] - src[::9, 0])  # three collinear: not unique
    src[1::10, 3] = src[1::10, 2]  # coincident corners
    H, code = homography4_batch(src, dst)
    pts = rng.uniform(0, 500, (n, 5, 2))
    mapped = apply_homography_batch(H, pts)
    for i in range(n):
        res, msg = _single(homography_from_points, src[i], dst[i])
        assert HOMOGRAPHY_ERRORS[code[i]] == msg, i
        if res is not None:
            np.testing.assert_allclose(H[i], res, rtol=0, atol=TOL * np.abs(res).max())
            np.testing.assert_allclose(mapped[i], apply_homography(res, pts[i]), rtol=1e-9, atol=TOL)
            back = apply_homography_batch(H[i : i + 1], src[i : i + 1])[0]
            np.testing.assert_allclose(back, dst[i], rtol=0, atol=1e-9)
    assert (code == 0).sum() > 200 and (code == 1).sum() > 20
    shared, c2 = homography4_batch(dst[0], src[2:5])  # (4, 2) shared by all rows
    assert shared.shape == (3, 3, 3) and np.all(c2 == 0)
    np.testing.assert_allclose(shared[1], homography_from_points(dst[0], src[3]), rtol=1e-9)


def test_collinear_batch() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 10, (400, 4, 2))
    pts[::4, 3] = pts[::4, 1] + rng.uniform(-0.05, 0.05, (100, 2))  # near-coincident, around the tolerance
    out = collinear_batch(pts, 1e-2)
    assert out.tolist() == [collinear(p, 1e-2) for p in pts]
    assert 0 < out.sum() < 400


def test_rigid_fit_batch_random_reflection_and_degenerate() -> None:
    rng = np.random.default_rng(4)
    n = 200
    P = rng.normal(size=(n, 4, 3))
    P[::7] = P[::7, :1] + np.linspace(0, 1, 4)[None, :, None] * rng.normal(size=(1, 1, 3))  # collinear
    R_true = matrix_from_euler_batch(rng.uniform(-math.pi, math.pi, (n, 3)))
    Q = np.einsum("nij,nkj->nki", R_true, P) + rng.normal(size=(n, 1, 3)) + rng.normal(0, 0.01, (n, 4, 3))
    Q[3::5] = Q[3::5] * [-1.0, 1.0, 1.0]  # mirrored: the fit must stay a rotation
    R, t, rms, ok = rigid_fit_batch(P, Q)
    for i in range(n):
        res, msg = _single(rigid_fit, P[i], Q[i])
        assert ok[i] == (msg == "") and (ok[i] or msg == RIGID_ERROR)
        if res is not None:
            np.testing.assert_allclose(R[i], res[0], rtol=0, atol=TOL)
            np.testing.assert_allclose(t[i], res[1], rtol=0, atol=TOL)
            assert abs(rms[i] - res[2]) <= TOL
            assert np.linalg.det(R[i]) > 0
    # the planar tag model (rank-2 cross-covariance) shared by all rows
    model = np.array([[1.0, 1, 0], [1, -1, 0], [-1, -1, 0], [-1, 1, 0]]) * 0.2
    Qm = np.einsum("nij,kj->nki", R_true, model) + [0.0, 0.0, 2.0]
    Rm, _, rms_m, ok_m = rigid_fit_batch(model, Qm)
    assert ok_m.all() and rms_m.max() < 1e-12
    np.testing.assert_allclose(Rm, R_true, atol=1e-12)


def test_euler_batch_both_ways() -> None:
    rng = np.random.default_rng(5)
    e = rng.uniform(-math.pi, math.pi, (300, 3))
    e[:, 1] /= 2.0
    e[::10, 1] = math.pi / 2  # gimbal lock
    e[1::10, 1] = -math.pi / 2
    R = matrix_from_euler_batch(e)
    back = euler_batch(R)
    for i in range(300):
        np.testing.assert_allclose(R[i], matrix_from_euler(*e[i]), rtol=0, atol=1e-15)
        np.testing.assert_allclose(back[i], euler_from_matrix(R[i]), rtol=0, atol=TOL)


@pytest.mark.parametrize("bad", ["src", "dst"])
def test_homography4_batch_nonfinite_rows_fail_alone(bad: str) -> None:
    src = np.tile([[0.0, 0], [1, 0], [1, 1], [0, 1]], (3, 1, 1))
    dst = src * 2.0 + 1.0
    (src if bad == "src" else dst)[1, 2] = np.inf
    H, code = homography4_batch(src, dst)
    assert code.tolist() == [0, 1, 0]
    np.testing.assert_allclose(H[0], homography_from_points(src[0], dst[0]), atol=1e-12)
