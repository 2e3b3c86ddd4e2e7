"""The single-frame ATDA on the batched code (ihrcf_env.core.batch.single, .lm) against the batched
rows (bitwise) and against ATDA's cv2 path (accuracy, validity, reasons)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from test_batch_pnp import DIST, RIG, TAG, K, poses_and_corners

import ihrcf_env.core.estimators.atda as atda_mod
from ihrcf_env.core.batch import lm
from ihrcf_env.core.batch.pnp import AMBIGUITY_RATIO, R_MARKER_DECK, ATDABatch, atda_batch
from ihrcf_env.core.batch.single import atda_candidates_batched, atda_single
from ihrcf_env.core.estimators import ATDAEstimator, SensorFrame, atda_estimate
from ihrcf_env.core.frames import matrix_from_euler, rotation_angle


def _bad_rows(corners: np.ndarray) -> np.ndarray:
    """Non-finite and degenerate corner rows mixed in (in place); returns the detected flags."""
    n = len(corners)
    det = np.ones(n, dtype=bool)
    det[::17] = False
    corners[1::19, 2] = np.nan
    corners[2::23, 1] = corners[2::23, 0] + 0.3 * (corners[2::23, 2] - corners[2::23, 0])
    corners[3::29] = corners[3::29, :1]  # all four corners coincide
    return det


def test_constants_equal_atda() -> None:
    assert AMBIGUITY_RATIO == atda_mod.AMBIGUITY_RATIO
    np.testing.assert_array_equal(R_MARKER_DECK, atda_mod._R_MARKER_DECK)


def test_solve6_and_rotation_kernels() -> None:
    rng = np.random.default_rng(0)
    B = rng.normal(size=(20, 6, 9))
    A, b = B @ B.transpose(0, 2, 1), rng.normal(size=(20, 6))
    np.testing.assert_allclose(lm.solve6(A.copy(), b), np.linalg.solve(A, b[..., None])[..., 0], atol=1e-9)
    w = rng.normal(size=(20, 3))
    w[0] = 0.0
    w[1] = 1e-9
    ref = np.array([cv2.Rodrigues(v)[0] for v in w])
    np.testing.assert_allclose(lm._rotation(w), ref, atol=1e-14)


def test_normal_equations_are_the_gradient() -> None:
    """J^T r of evaluate() is half the numerical gradient of the squared error in (w, dt)."""
    from ihrcf_env.core.batch.ippe import distortion5, ippe_square, marker_points, undistort

    _, _, corners = poses_and_corners(5, 11)
    d5, obj = distortion5(DIST), marker_points(TAG)
    R, t, _ = ippe_square(undistort(K, d5, corners), TAG)
    R, t, pu, pv = R[:, 0], t[:, 0], corners[:, :, 0], corners[:, :, 1]
    cam = lm.Camera(K, d5)
    _, _, g = lm.evaluate(cam, obj[:, 0], obj[:, 1], R, t, pu, pv)
    for k in range(6):
        cost = []
        for h in (1e-7, -1e-7):
            e = np.zeros((5, 6))
            e[:, k] = h
            Rn, tn = lm._apply(lm._rotation(e[:, :3]), R, t, e[:, 3:])
            cost.append(lm.evaluate(cam, obj[:, 0], obj[:, 1], Rn, tn, pu, pv, jacobian=False)[0])
        np.testing.assert_allclose((cost[0] - cost[1]) / 4e-7, g[:, k], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("chunk", [1, 7, 60])
def test_single_equals_batched_rows_bitwise(chunk: int) -> None:
    """atda_single(frame i) == row i of atda_batch over any batch size, to the bit (priors too)."""
    rng = np.random.default_rng(12)
    _, _, corners = poses_and_corners(60, 12, max_noise=2.0)
    det = _bad_rows(corners)
    prior = np.array([matrix_from_euler(*rng.uniform(-0.3, 0.3, 3)) for _ in range(60)])
    has = rng.uniform(size=60) < 0.7
    rows = [
        atda_batch(
            corners[i : i + chunk],
            det[i : i + chunk],
            K,
            DIST,
            TAG,
            RIG,
            prior[i : i + chunk],
            has[i : i + chunk],
        )
        for i in range(0, 60, chunk)
    ]
    for i in range(60):
        out, j = rows[i // chunk], i % chunk
        if not det[i]:
            assert not out.valid[j]
            continue
        s = atda_single(corners[i], K, DIST, TAG, RIG, prior[i] if has[i] else None)
        assert s.valid == out.valid[j] and s.reason == out.reason(j), i
        np.testing.assert_array_equal(s.rotation, out.rotation[j])
        np.testing.assert_array_equal(s.position, out.position[j])
        assert s.residual == out.residual[j]
        np.testing.assert_allclose(s.euler, out.euler[j], rtol=0, atol=1e-12)


def test_single_matches_cv2_path() -> None:
    """Same validity and reason as atda_estimate; the chosen pose and its reprojection error agree
    with cv2's (the same LM, up to rounding)."""
    _, _, corners = poses_and_corners(200, 13)
    det = _bad_rows(corners)
    n_valid = 0
    for i in range(200):
        if not det[i]:
            continue
        s = atda_estimate(corners[i], K, DIST, TAG, RIG)
        b = atda_single(corners[i], K, DIST, TAG, RIG)
        assert s.valid == b.valid and s.reason == b.reason, i
        cands, ref = (
            atda_candidates_batched(corners[i], K, DIST, TAG, RIG),
            atda_mod.atda_candidates(corners[i], K, DIST, TAG, RIG),
        )
        assert isinstance(cands, str) == isinstance(ref, str)
        if s.valid:
            n_valid += 1
            # cv2's own result moves by up to ~1e-5 under rounding-level input changes
            assert abs(b.residual - s.residual) < 5e-4
            assert np.abs(b.position - s.position).max() < 5e-5
            assert rotation_angle(b.rotation, s.rotation) < 2e-4
    assert n_valid > 150


def test_single_with_priors_matches_cv2_choice() -> None:
    """With a prior near either flip, the chosen poses agree with atda_estimate's."""
    _, _, corners = poses_and_corners(80, 14)
    for i in range(80):
        ref = atda_mod.atda_candidates(corners[i], K, DIST, TAG, RIG)
        assert not isinstance(ref, str)
        for prior in (ref[0][1], ref[-1][1]):
            s = atda_estimate(corners[i], K, DIST, TAG, RIG, prior)
            b = atda_single(corners[i], K, DIST, TAG, RIG, prior)
            assert rotation_angle(b.rotation, s.rotation) < 2e-4, i
            assert abs(b.residual - s.residual) < 5e-4


def test_estimator_on_batched_candidates_equals_atda_batch(monkeypatch: pytest.MonkeyPatch) -> None:
    """With atda_candidates switched to the batched code, ATDAEstimator (priors included) gives
    ATDABatch's rows exactly."""
    monkeypatch.setattr(atda_mod, "atda_candidates", atda_candidates_batched)
    _, _, corners = poses_and_corners(5, 15, max_noise=1.0)
    batch = ATDABatch(5, K, DIST, TAG, RIG)
    singles = [ATDAEstimator(K, DIST, TAG, RIG) for _ in range(5)]
    rng = np.random.default_rng(15)
    for _ in range(4):
        c = corners + rng.normal(0.0, 0.3, corners.shape)
        out = batch.update(c, np.ones(5, bool))
        for i, est in enumerate(singles):
            s = est.update(SensorFrame(0.0, c[i], np.ones(4), np.ones(4, bool)))
            assert s.valid and out.valid[i]
            np.testing.assert_array_equal(s.rotation, out.rotation[i])
            np.testing.assert_array_equal(s.position, out.position[i])


def test_flip_pair_stop_keeps_the_lowest_error() -> None:
    """The flip-pair rules (stop the clearly worse solution, merge a duplicate) leave the best
    solution's error equal to refining both solutions fully."""
    from ihrcf_env.core.batch.ippe import distortion5, ippe_square, marker_points, undistort

    _, _, corners = poses_and_corners(100, 16, max_noise=1.0)
    d5, obj = distortion5(DIST), marker_points(TAG)
    R, t, ok = ippe_square(undistort(K, d5, corners), TAG)
    assert ok.all()
    args = (K, d5, R.reshape(-1, 3, 3), t.reshape(-1, 3), obj, np.repeat(corners, 2, axis=0))
    _, _, e_full, it_full = lm.refine_lm(*args)
    _, _, e_pair, it_pair = lm.refine_lm(*args, flip_pairs=True)
    e_full, e_pair = e_full.reshape(-1, 2), e_pair.reshape(-1, 2)
    np.testing.assert_allclose(e_pair.min(axis=1), e_full.min(axis=1), rtol=1e-9, atol=1e-12)
    assert it_pair.reshape(-1, 2).max(axis=1).mean() < it_full.reshape(-1, 2).max(axis=1).mean()
    assert math.isfinite(float(e_pair.sum()))
