"""The batched IHRCF (ihrcf_env.core.batch.ihrcf) equals the single-frame estimator row by row."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from ihrcf_env.core.batch import REASONS, BatchTable, ihrcf_batch
from ihrcf_env.core.batch.ihrcf import ihrcf_measure_batch
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import IHRCFEstimator, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.ihrcf import ihrcf_measure
from ihrcf_env.core.frames import body_pose_to_cam, matrix_from_euler
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

TAG = 0.4
CAL = Calibration.load(default_calibration_path())
RIG = SensorRig()
TOL = 1e-9


def frames(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Random frames seen through the calibration's camera: corners (n, 4, 2), ranges (n, 4) with
    ToF noise, validity (n, 4) and detected (n,), with every kind of bad measurement mixed in."""
    rng = np.random.default_rng(seed)
    corners, ranges = np.zeros((n, 4, 2)), np.zeros((n, 4))
    for i in range(n):
        eul = rng.uniform(-0.3, 0.3, 3)
        eul[2] = rng.uniform(-math.pi, math.pi)
        h = rng.uniform(0.6, 3.0)
        p = np.array([rng.uniform(-0.1, 0.1) * h, rng.uniform(-0.1, 0.1) * h, -h])
        R_cd, t_cd = body_pose_to_cam(matrix_from_euler(*eul), p, RIG.camera_position)
        px, _ = cv2.projectPoints(tag_corners_deck(TAG), cv2.Rodrigues(R_cd)[0], t_cd, CAL.K, CAL.dist)
        corners[i] = px.reshape(4, 2) + rng.normal(0.0, rng.uniform(0, 0.5), (4, 2))
        nrm = R_cd[:, 2]
        xy = RIG.sensor_xy_cam
        ranges[i] = (nrm @ t_cd - xy @ nrm[:2]) / nrm[2] + rng.normal(0.0, 0.003, 4)
    valid = np.ones((n, 4), dtype=bool)
    detected = np.ones(n, dtype=bool)
    kind = rng.integers(0, 12, n)
    for i in range(n):
        k = kind[i]
        if k == 1:
            valid[i, rng.integers(4)] = False  # one range missing: predicted from the plane
        elif k == 2:
            valid[i, rng.choice(4, 2, replace=False)] = False  # too few
        elif k == 3:
            ranges[i, rng.integers(4)] = np.nan  # NaN flagged valid
        elif k == 4:
            ranges[i, rng.integers(4)] = -0.5
        elif k == 5:
            detected[i] = False
            corners[i] = np.nan
        elif k == 6:
            corners[i, 2] = np.nan
        elif k == 7:
            ranges[i] = 4.5 + rng.uniform(0, 1, 4)  # beyond the table
        elif k == 8:
            corners[i, 1] = corners[i, 0] + 0.5 * (corners[i, 2] - corners[i, 0])  # collinear quad
        elif k == 9:
            corners[i, 0] += rng.uniform(-30, 30, 2)  # no longer a square: fit residual
        elif k == 10:
            ranges[i, :3] = ranges[i, 0]  # exact plane through 3 equal + 1
            valid[i, 3] = False
    return corners, ranges, valid, detected


def single(corners, ranges, valid, detected, table, max_residual=0.01) -> list[PoseEstimate]:
    est = IHRCFEstimator(table, RIG, TAG, max_residual)
    return [
        est.update(SensorFrame(0.0, c if d else None, r, v))
        for c, r, v, d in zip(corners, ranges, valid, detected, strict=True)
    ]


def assert_rows_equal(batch, singles: list[PoseEstimate]) -> None:
    reasons = batch.reasons()
    for i, s in enumerate(singles):
        assert bool(batch.valid[i]) == s.valid, (i, s.reason, reasons[i])
        assert reasons[i] == s.reason, i
        np.testing.assert_allclose(batch.position[i], s.position, rtol=0, atol=TOL)
        np.testing.assert_allclose(batch.rotation[i], s.rotation, rtol=0, atol=TOL)
        np.testing.assert_allclose(batch.euler[i], s.euler, rtol=0, atol=TOL)
        assert abs(batch.residual[i] - s.residual) <= TOL
        assert batch.estimate(i).reason == s.reason


@pytest.mark.parametrize("seed", [0, 1])
def test_ihrcf_batch_equals_single_on_the_calibration_table(seed: int) -> None:
    c, r, v, d = frames(200, seed)
    batch = ihrcf_batch(c, r, v, d, CAL.tables, RIG, TAG)
    singles = single(c, r, v, d, CAL.tables)
    assert_rows_equal(batch, singles)
    seen = {s.reason.split(" ")[0] for s in singles}
    assert {"", "tag", "non-finite", "fewer", "range", "fit"} <= seen  # the mix reaches these reasons
    assert batch.valid.sum() > 60


def test_ihrcf_batch_intermediate_equals_ihrcf_measure() -> None:
    c, r, v, d = frames(60, 3)
    out = ihrcf_measure_batch(c, r, v, d, CAL.tables, RIG, TAG)
    for i in range(60):
        if not d[i]:
            continue
        meas, _ = ihrcf_measure(SensorFrame(0.0, c[i], r[i], v[i]), r[i], CAL.tables, RIG, TAG)
        assert out.measured[i] == (not isinstance(meas, str))
        if not isinstance(meas, str):
            np.testing.assert_allclose(out.corners_cam[i], meas.corners_cam, rtol=0, atol=TOL)
            np.testing.assert_allclose(out.normal[i], meas.normal, rtol=0, atol=TOL)
            assert abs(out.offset[i] - meas.offset) <= TOL
            assert np.array_equal(out.ranges_used[i], meas.ranges_used)


def test_batch_table_equals_range_pixel_table() -> None:
    rng = np.random.default_rng(4)
    d = rng.uniform(0.1, 4.5, (300, 4))
    d[::17, 1] = np.nan
    d[5, :] = [0.2152, 4.0, CAL.tables.tables[2].ranges[7], 0.0]  # ends and a break point
    uv, inside = BatchTable(CAL.tables)(d)
    for i in range(len(d)):
        uv1, in1 = CAL.tables(d[i])
        np.testing.assert_allclose(uv[i], uv1, rtol=0, atol=1e-9)
        assert np.array_equal(inside[i], in1)


def test_ihrcf_batch_custom_tables_and_reasons() -> None:
    """Single-frame tables are called per row; their failures give the single reasons."""
    c, r, v, d = frames(30, 5)
    nan_px = lambda rr: (np.full((4, 2), np.nan), np.ones(4, bool))  # noqa: E731
    line_px = lambda rr: (np.array([[100.0, 100], [200, 200], [300, 300], [100, 300]]), np.ones(4, bool))  # noqa: E731
    for table in (nan_px, line_px):
        batch = ihrcf_batch(c, r, v, d, table, RIG, TAG)
        assert_rows_equal(batch, single(c, r, v, d, table))
    loose = ihrcf_batch(c, r, v, d, CAL.tables, RIG, TAG, max_residual=1.0)
    assert_rows_equal(loose, single(c, r, v, d, CAL.tables, max_residual=1.0))
    # undetected rows take the frame's own reason when given
    out = ihrcf_batch(c, r, v, np.zeros(30, bool), CAL.tables, RIG, TAG)
    assert out.reasons(["camera frame dropped"] * 30) == ["camera frame dropped"] * 30
    assert REASONS[1] == "tag not found"


def test_ihrcf_batch_shapes_checked() -> None:
    c, r, v, d = frames(4, 6)
    with pytest.raises(ValueError, match="corners_px"):
        ihrcf_batch(c[:, :3], r, v, d, CAL.tables, RIG, TAG)
    with pytest.raises(ValueError, match="rows"):
        ihrcf_batch(c, r[:3], v, d, CAL.tables, RIG, TAG)
