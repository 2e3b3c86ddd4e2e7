"""The batched square-tag PnP (ihrcf_env.core.batch.pnp) against ATDA's cv2 path."""

from __future__ import annotations

import math

import cv2
import numpy as np

from ihrcf_env.core.batch.ippe import marker_points, project, undistort
from ihrcf_env.core.batch.pnp import ATDABatch, atda_batch, ippe_square, pnp_candidates, pnp_choose
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import ATDAEstimator, SensorFrame, atda_estimate
from ihrcf_env.core.estimators.atda import atda_choose
from ihrcf_env.core.frames import body_pose_to_cam, matrix_from_euler, rotation_angle
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

TAG = 0.4
CAL = Calibration.load(default_calibration_path())
K, DIST = CAL.K, CAL.dist
RIG = SensorRig()


def poses_and_corners(n: int, seed: int, max_noise: float = 0.5):
    """Random deck poses (1-3 m, tilt <= 0.3 rad, any yaw) and their corners with 0..max_noise px noise."""
    rng = np.random.default_rng(seed)
    R_all, p_all, corners = np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 4, 2))
    for i in range(n):
        eul = rng.uniform(-0.3, 0.3, 3)
        eul[2] = rng.uniform(-math.pi, math.pi)
        h = rng.uniform(1.0, 3.0)
        R_all[i] = matrix_from_euler(*eul)
        p_all[i] = [rng.uniform(-0.1, 0.1) * h, rng.uniform(-0.1, 0.1) * h, -h]
        R_cd, t_cd = body_pose_to_cam(R_all[i], p_all[i], RIG.camera_position)
        px, _ = cv2.projectPoints(tag_corners_deck(TAG), cv2.Rodrigues(R_cd)[0], t_cd, K, DIST)
        corners[i] = px.reshape(4, 2) + rng.normal(0.0, rng.uniform(0, max_noise), (4, 2))
    return R_all, p_all, corners


def test_projection_jacobian_and_undistortion() -> None:
    rng = np.random.default_rng(0)
    X = rng.uniform(-0.5, 0.5, (20, 3)) + [0.0, 0.0, 2.0]
    px, J = project(K, DIST, X)
    ref, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K, DIST)
    np.testing.assert_allclose(px, ref.reshape(-1, 2), atol=1e-9)
    for k in range(3):
        dX = np.zeros(3)
        dX[k] = 1e-6
        num = (project(K, DIST, X + dX)[0] - project(K, DIST, X - dX)[0]) / 2e-6
        np.testing.assert_allclose(J[:, :, k], num, atol=1e-4)
    np.testing.assert_allclose(undistort(K, DIST, px), X[:, :2] / X[:, 2:], atol=1e-9)


def test_ippe_equals_cv2_ippe_square() -> None:
    _, _, corners = poses_and_corners(40, 1)
    R, t, ok = ippe_square(undistort(K, DIST, corners), TAG)
    assert ok.all()
    for i in range(40):
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(
            marker_points(TAG), corners[i].reshape(4, 1, 2), K, DIST, flags=cv2.SOLVEPNP_IPPE_SQUARE
        )
        for rv in rvecs:  # each cv2 solution is one of ours
            Rc = cv2.Rodrigues(rv)[0]
            assert min(np.abs(Rc - R[i, s]).max() for s in (0, 1)) < 1e-9


def test_atda_batch_against_cv2_refined() -> None:
    """Same validity and reason; the LM-polished poses and errors agree with cv2's (the same LM, up
    to rounding)."""
    R_true, p_true, corners = poses_and_corners(150, 2)
    det = np.ones(150, dtype=bool)
    det[::25] = False
    corners[1::30, 2] = np.nan
    corners[2::30, 1] = corners[2::30, 0] + 0.3 * (corners[2::30, 2] - corners[2::30, 0])  # degenerate quad
    out = atda_batch(corners, det, K, DIST, TAG, RIG)
    reasons = out.reasons()
    for i in range(150):
        if not det[i]:
            assert reasons[i] == "tag not found" and not out.valid[i]
            continue
        s = atda_estimate(corners[i], K, DIST, TAG, RIG)
        assert s.valid == out.valid[i] and s.reason == reasons[i], i
        if s.valid:
            assert np.abs(out.position[i] - s.position).max() < 5e-5
            assert rotation_angle(out.rotation[i], s.rotation) < 2e-4
            assert abs(out.residual[i] - s.residual) < 5e-4
    assert out.valid.sum() > 100


def test_atda_batch_exact_corners_recover_the_pose() -> None:
    R_true, p_true, corners = poses_and_corners(50, 3, max_noise=0.0)
    out = atda_batch(corners, np.ones(50, bool), K, DIST, TAG, RIG)
    assert out.valid.all()
    np.testing.assert_allclose(out.position, p_true, atol=1e-8)
    np.testing.assert_allclose(out.rotation, R_true, atol=1e-9)  # (acos loses digits near 0 rad)


def test_choice_rule_equals_atda_choose() -> None:
    """Given the same candidates, the batched choice (with and without priors) is ATDA's."""
    rng = np.random.default_rng(4)
    _, _, corners = poses_and_corners(60, 4, max_noise=2.0)
    c = pnp_candidates(corners, np.ones(60, bool), K, DIST, TAG, RIG)
    prior = np.array([matrix_from_euler(*rng.uniform(-math.pi, math.pi, 3)) for _ in range(60)])
    prior[::2] = c.rotation[::2, 1]  # near the second candidate
    has = rng.uniform(size=60) < 0.8
    out = pnp_choose(c, prior, has)
    for i in range(60):
        cands = [(float(c.error[i, s]), c.rotation[i, s], c.position[i, s]) for s in (0, 1) if c.usable[i, s]]
        ref = atda_choose(cands, prior[i] if has[i] else None)
        np.testing.assert_array_equal(out.rotation[i], ref.rotation)
        np.testing.assert_array_equal(out.position[i], ref.position)


def test_atda_batch_keeps_one_prior_per_row() -> None:
    _, _, corners = poses_and_corners(6, 5)
    batch = ATDABatch(6, K, DIST, TAG, RIG)
    singles = [ATDAEstimator(K, DIST, TAG, RIG) for _ in range(6)]
    det = np.array([True, False, True, True, False, True])
    for step in range(3):
        out = batch.update(corners, det if step == 1 else np.ones(6, bool))
        for i, est in enumerate(singles):
            s = est.update(
                SensorFrame(0.0, corners[i] if (step != 1 or det[i]) else None, np.ones(4), np.ones(4, bool))
            )
            assert s.valid == out.valid[i]
            if s.valid:
                assert rotation_angle(s.rotation, out.rotation[i]) < 1e-3
    assert batch.has_prior.all()
    batch.reset(np.array([True, False, False, False, False, False]))
    assert batch.has_prior.tolist() == [False] + [True] * 5
