"""IHRCF and its geometry (ihrcf_env.fast.homography / plane / rigid / table / ihrcf) against the
single-frame reference (ihrcf_env.core.estimators.ihrcf, ihrcf_env.core.geometry and the
RangePixelTable lookup), frame by frame, float64: the reason code of every frame names the
reference's reason text (ihrcf_env.core.estimators.reasons), the poses agree within 1e-9
relative."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core import geometry
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.estimators import reasons as rs
from ihrcf_env.core.estimators.base import TAG_NOT_FOUND
from ihrcf_env.core.estimators.ihrcf import ihrcf_corners, ihrcf_estimate
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov, tag_corners_deck
from ihrcf_env.fast.homography import homography4
from ihrcf_env.fast.ihrcf import ihrcf, ihrcf_setup
from ihrcf_env.fast.plane import fit_plane
from ihrcf_env.fast.rigid import rigid_fit
from ihrcf_env.fast.table import lookup, touch_table

from .fast_helpers import Counted, rel_err, rotations

RIG = SensorRig()
TAG = 0.4
K = intrinsics_from_fov(512, 512, math.radians(60))
XY = RIG.sensor_xy_cam
N = 256  # frames per call: one shape, one compilation


def _table() -> RangePixelTable:
    d = np.linspace(0.3, 3.0, 40)
    u = K[0, 0] * XY[:, 0] / d[:, None] + K[0, 2]
    v = K[1, 1] * XY[:, 1] / d[:, None] + K[1, 2]
    pixels = np.stack([u, v], axis=2)
    pixels[5, 2] = np.nan  # ps3 has one sample fewer: tables of different lengths
    return RangePixelTable.from_samples(np.tile(d[:, None], 4), pixels)


TABLE = _table()
SETUP = ihrcf_setup(touch_table(TABLE), RIG, TAG)
IHRCF = Counted(lambda c, r, v, d: ihrcf(c, r, v, d, SETUP))
LOOKUP = Counted(lambda r: lookup(SETUP.table, r))
HOMOGRAPHY = Counted(homography4)
PLANE = Counted(fit_plane)
RIGID = Counted(rigid_fit, in_axes=(None, 0))


def frames(seed: int, n: int, noise_px: float = 0.3):
    """Tag corners and ranges of decks below the drone (camera frame), with pixel noise."""
    rng = np.random.default_rng(seed)
    R_bd = rotations(rng, n, 0.25)
    p_bd = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), -rng.uniform(0.5, 2.5, n)])
    R_cd = R_BODY_CAM.T @ R_bd
    t_cd = (p_bd - RIG.camera_position_array) @ R_BODY_CAM
    P = np.einsum("nij,kj->nki", R_cd, tag_corners_deck(TAG)) + t_cd[:, None, :]
    corners = np.stack(
        [K[0, 0] * P[..., 0] / P[..., 2] + K[0, 2], K[1, 1] * P[..., 1] / P[..., 2] + K[1, 2]], -1
    )
    corners += rng.normal(0.0, noise_px, corners.shape)
    nrm = R_cd[:, :, 2]
    off = (nrm * t_cd).sum(1)
    ranges = (off[:, None] - nrm[:, None, 0] * XY[:, 0] - nrm[:, None, 1] * XY[:, 1]) / nrm[:, None, 2]
    ranges += rng.normal(0.0, 0.002, ranges.shape)
    valid = np.ones((n, 4), dtype=bool)
    detected = np.ones(n, dtype=bool)
    return corners, ranges, valid, detected


def edge_cases(corners, ranges, valid, detected):
    """Rows 0..9 turned into failures of each kind."""
    detected[0] = False
    corners[1, 2] = np.nan
    valid[2, :2] = False  # two ranges
    ranges[3, 1] = np.nan  # three valid: the plane through them
    ranges[4] = [5.0, 5.0, 5.0, 5.0]  # outside the table
    ranges[5, 3] = 0.1  # below the table's span
    corners[6] = [[10.0, 10.0], [20.0, 20.0], [30.0, 30.0], [40.0, 40.0]]  # collinear corners
    corners[7, 1] = corners[7, 0]  # a coincident corner
    ranges[8] = [1.0, 1.0, 3.0, 3.0]  # a steep plane: corners far off, residual too large
    valid[9] = False


MAX_RESIDUAL = 0.01  # ihrcf_setup's default


def reference(c, r, v, d):
    """The single-frame IHRCF of every frame: (codes (n,), rotations, positions, eulers, residuals,
    fit RMS (n,): the rigid fit's RMS behind a residual failure, else 0). The code of a frame is the
    index of its reason text in REASONS (the residual template matched by its filled text)."""
    n = len(c)
    code = np.zeros(n, dtype=int)
    R, p, e = np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), np.zeros((n, 3))
    res, rms = np.zeros(n), np.zeros(n)
    model = tag_corners_deck(TAG)
    for i in range(n):
        if not d[i]:
            code[i] = rs.NOT_DETECTED
            continue
        est = ihrcf_estimate(c[i], r[i], v[i], TABLE, RIG, TAG, MAX_RESIDUAL)
        if est.valid:
            R[i], p[i], e[i], res[i] = est.rotation, est.position, est.euler, est.residual
            continue
        if est.reason.startswith("fit residual"):
            corners = ihrcf_corners(c[i], r[i], v[i], TABLE, RIG)
            assert not isinstance(corners, str)
            rms[i] = geometry.rigid_fit(model, corners.corners_cam)[2]
            code[i] = rs.FIT_RESIDUAL
            assert rs.reason_text(code[i], rms[i], MAX_RESIDUAL) == est.reason
        else:
            assert est.reason in rs.REASONS, est.reason
            code[i] = rs.REASONS.index(est.reason)
    return code, R, p, e, res, rms


def compare(seed: int, n: int, edges: bool) -> float:
    c, r, v, d = frames(seed, n)
    if edges:
        edge_cases(c, r, v, d)
    code, R, p, e, res, rms = reference(c, r, v, d)
    got = IHRCF(c, r, v, d)
    assert np.array_equal(np.asarray(got.code), code), np.flatnonzero(np.asarray(got.code) != code)
    assert np.array_equal(np.asarray(got.valid), code == rs.OK)
    for i in np.flatnonzero(code == rs.FIT_RESIDUAL):  # the same text, the RMS filled in
        text = rs.reason_text(int(got.code[i]), float(got.fit_rms[i]), MAX_RESIDUAL)
        assert text == rs.reason_text(code[i], rms[i], MAX_RESIDUAL)
    err = max(
        rel_err(got.rotation, R),
        rel_err(got.position, p),
        rel_err(got.euler, e),
        rel_err(got.residual, res, floor=1e-3),
        rel_err(got.fit_rms, rms, floor=1e-3),
    )
    return err


def test_ihrcf_matches_the_single_frame_estimator() -> None:
    err = compare(0, N, edges=False)
    assert err < 1e-9


def test_ihrcf_failure_codes_match() -> None:
    c, r, v, d = frames(1, N)
    edge_cases(c, r, v, d)
    code = reference(c, r, v, d)[0]
    codes = set(code[:10].tolist())
    assert {rs.NOT_DETECTED, rs.NONFINITE_CORNERS, rs.FEW_RANGES, rs.OUTSIDE_TABLE, rs.FIT_RESIDUAL} <= codes
    assert compare(1, N, edges=True) < 1e-9


def test_reason_texts() -> None:
    assert rs.REASONS[rs.OK] == "" and rs.REASONS[rs.NOT_DETECTED] == TAG_NOT_FOUND
    assert len(set(rs.REASONS)) == len(rs.REASONS) == rs.TAG_BEHIND + 1
    assert rs.reason_text(rs.FIT_RESIDUAL, 0.02, 0.01) == "fit residual 0.02 m > 0.01 m"


def test_table_lookup_matches() -> None:
    rng = np.random.default_rng(3)
    r = rng.uniform(0.2, 3.2, (200, 4))
    r[0] = [np.nan, 0.3, 3.0, 0.1]
    want = [TABLE(row) for row in r]
    want_uv, want_in = np.array([w[0] for w in want]), np.array([w[1] for w in want])
    uv, inside = LOOKUP(r)
    assert np.array_equal(np.asarray(inside), want_in) and not want_in.all() and want_in.any()
    assert rel_err(uv, want_uv) < 1e-12


#: The geometry kernels' ValueError texts -> the array kernels' error codes.
HOMOGRAPHY_CODES = {
    "degenerate point configuration: homography is not unique": 1,
    "homography has H[2, 2] = 0 and cannot be normalised": 2,
}
PLANE_CODES = {"points are all coincident: plane undefined": 1, "points are collinear: plane undefined": 2}


def _single(fn, codes, *args):
    """(fn(*args), 0), or (None, the code of its ValueError)."""
    try:
        return fn(*args), 0
    except ValueError as e:
        return None, codes[str(e)]


def test_homography_matches_including_degenerate() -> None:
    rng = np.random.default_rng(4)
    src = rng.uniform(-1, 1, (128, 4, 2))
    dst = rng.uniform(0, 500, (128, 4, 2))
    src[0] = [[0, 0], [1, 1], [2, 2], [0, 1]]  # three collinear
    src[1, 3] = src[1, 2]  # coincident
    want = [
        _single(geometry.homography_from_points, HOMOGRAPHY_CODES, s, t)
        for s, t in zip(src, dst, strict=True)
    ]
    want_code = np.array([w[1] for w in want])
    H, code = HOMOGRAPHY(src, dst)
    assert np.array_equal(np.asarray(code), want_code) and want_code[:2].tolist() == [1, 1]
    ok = want_code == 0
    want_H = np.array([w[0] for w in want if w[1] == 0])
    assert rel_err(np.asarray(H)[ok], want_H, floor=1e-6) < 1e-9


def test_plane_fit_matches_including_degenerate() -> None:
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(128, 4, 3)) * [0.1, 0.1, 0.02] + [0.0, 0.0, 1.0]
    use = rng.random((128, 4)) > 0.15
    pts[0] = [[0, 0, 1], [1, 1, 2], [2, 2, 3], [3, 3, 4]]  # collinear (4 points)
    use[0] = True
    pts[1] = [[0, 0, 1], [1, 1, 2], [2, 2, 3], [0, 1, 0]]
    use[1] = [True, True, True, False]  # collinear (3 points)
    pts[2] = 1.0
    use[2] = True  # coincident
    pts[3, 1] = [5.0, 0.0, 1.0]  # a vertical plane through the x axis
    pts[3, :, 1] = 0.0
    use[3] = True
    want_code = np.zeros(128, dtype=int)
    want_n, want_d = np.tile([0.0, 0.0, 1.0], (128, 1)), np.zeros(128)
    for i in range(128):
        if use[i].sum() < 3:  # the reference needs three points (IHRCF checks the count first)
            want_code[i] = 3
            continue
        fit, want_code[i] = _single(geometry.fit_plane, PLANE_CODES, pts[i][use[i]])
        if fit is not None:
            want_n[i], want_d[i] = fit
    n, d, code = PLANE(pts, use)
    assert np.array_equal(np.asarray(code), want_code)
    assert {1, 2, 3} <= set(want_code.tolist())
    ok = want_code == 0
    assert rel_err(np.asarray(n)[ok], want_n[ok]) < 1e-9 and rel_err(np.asarray(d)[ok], want_d[ok]) < 1e-9
    with pytest.raises(ValueError, match="parallel to the z axis"):  # the vertical plane: no z
        geometry.plane_z(want_n[3], want_d[3], XY)


def test_rigid_fit_matches() -> None:
    rng = np.random.default_rng(6)
    P = tag_corners_deck(TAG)
    R = rotations(rng, 128, 3.0)
    Q = np.einsum("nij,kj->nki", R, P) + rng.normal(size=(128, 1, 3)) + rng.normal(0, 1e-3, (128, 4, 3))
    want = [geometry.rigid_fit(P, q) for q in Q]
    got = RIGID(P, Q)
    assert np.asarray(got[3]).all()
    for k in range(3):
        w = np.array([x[k] for x in want])
        assert rel_err(got[k], w, floor=1e-3) < 1e-9
    with pytest.raises(ValueError, match="collinear or coincident"):
        geometry.rigid_fit(np.zeros((4, 3)), Q[0])
    assert not np.asarray(RIGID(np.zeros((4, 3)), Q)[3]).any()  # coincident P: no rotation


def test_compiled_once() -> None:
    before = IHRCF.traces
    for seed in (7, 8):
        IHRCF(*frames(seed, N))
    assert IHRCF.traces - before <= 1
