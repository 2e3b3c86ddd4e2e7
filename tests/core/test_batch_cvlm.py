"""cv2.solvePnPRefineLM's algorithm on N poses (ihrcf_env.core.batch.cvlm) against cv2 itself."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from test_batch_pnp import DIST, TAG, K, poses_and_corners

from ihrcf_env.core.batch import cvlm
from ihrcf_env.core.batch.ippe import distortion5, ippe_square, marker_points, undistort

OBJ = marker_points(TAG)
FLT_EPS = float(np.finfo(np.float32).eps)


def _frames(n: int, seed: int, dist: np.ndarray) -> np.ndarray:
    """Corners (n, 4, 2) of the tag at 0.3-3 m, tilt <= 0.5 rad, any yaw, inside the 512 x 512
    image, with 0-0.5 px noise."""
    rng = np.random.default_rng(seed)
    out = np.zeros((n, 4, 2))
    i = 0
    while i < n:
        rv = cv2.Rodrigues(np.array([math.pi, 0.0, 0.0]))[0]
        tilt = cv2.Rodrigues(np.r_[rng.uniform(-0.5, 0.5, 2), rng.uniform(-math.pi, math.pi)])[0]
        h = rng.uniform(0.3, 3.0)
        t = np.array([rng.uniform(-0.3, 0.3) * h, rng.uniform(-0.3, 0.3) * h, h])
        px, _ = cv2.projectPoints(OBJ, cv2.Rodrigues(rv @ tilt)[0], t, K, dist)
        px = px.reshape(4, 2) + rng.normal(0.0, rng.uniform(0.0, 0.5), (4, 2))
        if (px > 0).all() and (px < 512).all():
            out[i] = px
            i += 1
    return out


def _start(corners: np.ndarray, d5: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    R, t, ok = ippe_square(undistort(K, d5, corners, 5), TAG)
    assert ok.all()
    return cvlm.rodrigues_vector(R.reshape(-1, 3, 3)), t.reshape(-1, 3)


def _cv2_difference(
    corners: np.ndarray,
    dist: np.ndarray,
    rv0: np.ndarray,
    t0: np.ndarray,
    rv: np.ndarray,
    tv: np.ndarray,
    max_iter: int,
) -> np.ndarray:
    """Per row (two starts per frame), the largest difference between the batched result
    ``(rv, tv)`` and cv2.solvePnPRefineLM from the same start ``(rv0, t0)``."""
    diff = np.zeros(len(rv))
    for i in range(len(rv)):
        r_c, t_c = cv2.solvePnPRefineLM(
            OBJ,
            corners[i // 2].reshape(4, 1, 2),
            K,
            dist,
            rv0[i].reshape(3, 1).copy(),
            t0[i].reshape(3, 1).copy(),
            criteria=(cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, max_iter, FLT_EPS),
        )
        diff[i] = max(np.abs(r_c.ravel() - rv[i]).max(), np.abs(t_c.ravel() - tv[i]).max())
    return diff


def test_rodrigues_is_cv2_bitwise() -> None:
    rng = np.random.default_rng(0)
    r = rng.normal(size=(300, 3))
    r *= (rng.uniform(0.0, math.pi, 300) / np.linalg.norm(r, axis=1))[:, None]
    r[0], r[1] = 0.0, 1e-17
    R, dR = cvlm.rodrigues(r)
    for i in range(300):
        Rc, Jc = cv2.Rodrigues(r[i])
        np.testing.assert_array_equal(R[i], Rc.ravel())
        np.testing.assert_array_equal(dR[i], Jc)
    back = cvlm.rodrigues_vector(R.reshape(-1, 3, 3))
    ref = np.array([cv2.Rodrigues(R[i].reshape(3, 3))[0].ravel() for i in range(300)])
    np.testing.assert_allclose(back, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("dist", [DIST, np.zeros(5)])
def test_projection_and_jacobian_are_cv2_bitwise(dist: np.ndarray) -> None:
    rng = np.random.default_rng(1)
    n = 200
    p = np.hstack([rng.normal(size=(n, 3)), rng.normal(size=(n, 3)) * 0.3 + [0.0, 0.0, 2.0]])
    px = rng.normal(size=(n, 4, 2)) * 100 + 256
    res, J = cvlm.project(cvlm._Camera(K, distortion5(dist)), OBJ, p, px, True)
    for i in range(n):
        P, Jc = cv2.projectPoints(OBJ, p[i, :3], p[i, 3:], K, dist)
        np.testing.assert_array_equal(res[i], (P.reshape(4, 2) - px[i]).ravel())
        np.testing.assert_array_equal(J[i], Jc[:, :6])


@pytest.mark.parametrize("dist", [DIST])
def test_refine_matches_cv2_per_frame(dist: np.ndarray) -> None:
    """Each row against cv2.solvePnPRefineLM from the same start: one step agrees to rounding
    (magnified by the geodesic correction); the full refinement to the level at which cv2's own
    result moves under a rounding-level change of its input."""
    d5 = distortion5(dist)
    corners = poses_and_corners(150, 2)[2]  # 1-3 m, tilt <= 0.3 rad (the package camera's distortion)
    rv0, t0 = _start(corners, d5)
    px = np.repeat(corners, 2, axis=0)
    for max_iter, tol_max, tol_med in ((1, 1e-7, 5e-9), (cvlm.MAX_ITER, 3e-5, 1e-6)):
        rv, tv, e, it = cvlm.refine_cv_lm(K, d5, rv0, t0, OBJ, px, max_iter=max_iter)
        assert (it <= max_iter).all() and (it >= 1).all()
        diff = _cv2_difference(corners, dist, rv0, t0, rv, tv, max_iter)
        for i in range(len(rv)):
            P, _ = cv2.projectPoints(OBJ, rv[i], tv[i], K, dist)
            assert e[i] == pytest.approx(float(((P.reshape(4, 2) - corners[i // 2]) ** 2).sum()), rel=1e-12)
        assert diff.max() < tol_max, (max_iter, diff.max())
        assert np.median(diff) < tol_med, (max_iter, np.median(diff))


def test_rows_do_not_depend_on_n() -> None:
    d5 = distortion5(DIST)
    corners = _frames(40, 3, DIST)
    rv0, t0 = _start(corners, d5)
    px = np.repeat(corners, 2, axis=0)
    full = cvlm.refine_cv_lm(K, d5, rv0, t0, OBJ, px)
    for lo, hi in ((0, 1), (5, 12), (30, 80)):
        part = cvlm.refine_cv_lm(K, d5, rv0[lo:hi], t0[lo:hi], OBJ, px[lo:hi])
        for a, b in zip(part, full, strict=True):
            np.testing.assert_array_equal(a, b[lo:hi])


@pytest.mark.parametrize("dist", [DIST, np.zeros(5)], ids=["distorted", "pinhole"])
def test_refine_matches_cv2_over_the_wide_frame_set(dist: np.ndarray) -> None:
    """0.3-3 m, tilt up to 0.5 rad, anywhere in the image, with and without distortion: the
    refinement ends where cv2's does, to the level of cv2's own sensitivity to rounding."""
    d5 = distortion5(dist)
    corners = _frames(100, 7, dist)
    rv0, t0 = _start(corners, d5)
    px = np.repeat(corners, 2, axis=0)
    rv, tv, _, _ = cvlm.refine_cv_lm(K, d5, rv0, t0, OBJ, px)
    diff = _cv2_difference(corners, dist, rv0, t0, rv, tv, cvlm.MAX_ITER)
    assert diff.max() < 1e-4 and np.median(diff) < 1e-6, (diff.max(), np.median(diff))
