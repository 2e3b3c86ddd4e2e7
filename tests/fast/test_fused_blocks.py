"""The fused filter's measurement blocks (ihrcf_env.fast.fused_blocks) against the single filter's
(ihrcf_env.core.estimators.fused_measurements.MeasurementBlocks), its IMU sample
(fused_delay.imu_sample) and its range-noise and range-offset updates (FusedEstimator), row by
row, float64."""

from __future__ import annotations

import math

import jax
import numpy as np
from scipy.stats import chi2

from ihrcf_env.core.estimators import fused_reasons as fr
from ihrcf_env.core.estimators.base import ImuSample, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.fused import FusedEstimator
from ihrcf_env.core.estimators.fused_delay import imu_sample
from ihrcf_env.core.estimators.fused_measurements import MeasurementBlocks, _plane_shape, plane_covariance
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.estimators.ihrcf import IHRCFCorners
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast import fused_blocks as fb

from .fast_helpers import rel_err, rotations

RIG = SensorRig()
TAG = 0.4
PARAMS = FusedParams()
MAXRES = 0.01
REF = MeasurementBlocks(PARAMS, RIG, TAG, MAXRES)
C = fb.fused_consts(PARAMS, RIG, TAG, MAXRES)
V = jax.vmap
XY = RIG.sensor_xy_cam


def pose(R: np.ndarray, p: np.ndarray) -> PoseEstimate:
    return PoseEstimate.from_body_pose(R, p, 0.0)


def corners(used: np.ndarray, corners_cam: np.ndarray | None = None) -> IHRCFCorners:
    """IHRCF's 3-D corners as the blocks read them (the corners and the used ranges)."""
    cc = np.zeros((4, 3)) if corners_cam is None else corners_cam
    return IHRCFCorners(cc, np.array([0.0, 0.0, 1.0]), 1.0, used)


def stacked(ms):
    """(z (n, k), R (n, k, k)) of n single measurements."""
    return np.stack([m.z for m in ms]), np.stack([m.R for m in ms])


def scene(seed: int, n: int):
    rng = np.random.default_rng(seed)
    R_wb = rotations(rng, n, 0.3)
    R_bd = rotations(rng, n, 0.2)
    p_bd = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), -rng.uniform(0.3, 3.0, n)])
    used = rng.random((n, 4)) < 0.85
    used[np.arange(n), rng.integers(0, 4, n)] = True
    while (few := used.sum(axis=1) < 3).any():
        used[few, rng.integers(0, 4, few.sum())] = True
    sigma_r = rng.uniform(0.002, 0.05, n)
    model = tag_corners_deck(TAG)
    corners_b = np.einsum("nij,kj->nki", R_bd, model) + p_bd[:, None, :]
    corners_cam = (corners_b - np.asarray(RIG.camera_position)) @ R_BODY_CAM
    corners_cam += rng.normal(0.0, 0.003, corners_cam.shape)
    depth = -p_bd[:, 2] + rng.normal(0.0, 0.01, n)
    ranges = depth[:, None] + rng.normal(0.0, 0.01, (n, 4))
    return R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges


def test_consts_match_the_single_filter() -> None:
    masks = 0
    for key in range(16):
        used = np.array([(key >> j) & 1 for j in range(4)], dtype=bool)
        if used.sum() >= 3:
            shape, tilt = _plane_shape(np.ascontiguousarray(XY[used], dtype=np.float64).tobytes())
            assert np.array_equal(C.shape[key], shape) and C.tilt[key] == tilt
            masks += 1
    assert masks == 5
    assert C.gate == tuple(float(chi2.ppf(PARAMS.gate_probability, k)) for k in (1, 2, 3))
    single = FusedEstimator(lambda r: (np.zeros((4, 2)), np.ones(4, bool)), RIG, TAG)
    assert rel_err(C.residual_direction, single._residual_direction) < 1e-15


def test_blocks_match_the_single_blocks() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(0, 300)
    n = len(R_wb)
    est = [pose(R_bd[i], p_bd[i]) for i in range(n)]
    sig = [float(x) for x in sigma_r]
    checks = [
        (
            V(lambda R, p, W: fb.atda_attitude(C, R, p, W)),
            (R_bd, p_bd, R_wb),
            stacked([REF.atda_attitude(est[i], R_wb[i]) for i in range(n)]),
        ),
        (
            V(lambda p, W: fb.atda_position(C, p, W)),
            (p_bd, R_wb),
            stacked([REF.atda_position(est[i], R_wb[i]) for i in range(n)]),
        ),
        (
            V(lambda p, u, W, s: fb.ihrcf_position(C, p, u, W, s)),
            (p_bd, used, R_wb, sigma_r),
            stacked([REF.ihrcf_position(est[i], corners(used[i]), R_wb[i], sig[i]) for i in range(n)]),
        ),
        (
            V(lambda R, p, s, W: fb.refit_yaw(C, R, p, s, W)),
            (R_bd, p_bd, sigma_r, R_wb),
            stacked([REF.refit_yaw(est[i], sig[i], R_wb[i]) for i in range(n)]),
        ),
        (
            V(lambda p, u, W, s, t: fb.refit_position(C, p, u, W, s, t)),
            (p_bd, used, R_wb, sigma_r, sigma_r**2),
            stacked(
                [REF.refit_position(est[i], corners(used[i]), R_wb[i], sig[i], sig[i] ** 2) for i in range(n)]
            ),
        ),
    ]
    for yaw in (True, False):
        checks.append(
            (
                V(lambda R, p, u, W, s, y=yaw: fb.ihrcf_attitude(C, R, p, u, W, s, y)),
                (R_bd, p_bd, used, R_wb, sigma_r),
                stacked(
                    [REF.ihrcf_attitude(est[i], corners(used[i]), R_wb[i], sig[i], yaw) for i in range(n)]
                ),
            )
        )
    for fn, args, (z, R) in checks:
        gz, gR = jax.jit(fn)(*args)
        assert rel_err(gz, z) < 1e-12
        assert rel_err(gR, R) < 1e-12
        assert np.array_equal(np.asarray(gR), np.asarray(gR).transpose(0, 2, 1))
    pl = V(lambda u, s: fb.plane(C, u, s))(used, sigma_r)
    want = [plane_covariance(XY[used[i]], sig[i]) for i in range(n)]
    assert rel_err(pl[0], np.stack([w[0] for w in want])) < 1e-15
    assert rel_err(pl[1], np.array([w[1] for w in want])) < 1e-15


def test_refit_matches_the_single_refit() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(1, 300)
    corners_cam[:5, 0, 2] = -1.0  # a corner behind the plane: not refitted
    ranges[5:10] = -1.0  # negative distance
    n = len(R_bd)
    want = [REF.refit(corners(used[i], corners_cam[i]), ranges[i], R_bd[i]) for i in range(n)]
    ok = np.array([w is not None for w in want])
    gR, gp, gok = jax.jit(V(lambda a, u, r, b: fb.refit(C, a, u, r, b)))(corners_cam, used, ranges, R_bd)
    assert np.array_equal(np.asarray(gok), ok) and 100 < ok.sum() < 300
    assert rel_err(np.asarray(gR)[ok], np.stack([w.rotation for w in want if w is not None])) < 1e-9
    assert rel_err(np.asarray(gp)[ok], np.stack([w.position for w in want if w is not None])) < 1e-9


def test_imu_sample_matches_the_single_filters() -> None:
    rng = np.random.default_rng(2)
    n = 64
    q = rng.normal(size=(n, 4))
    f = rng.normal(0, 9.0, (n, 3))
    w = rng.normal(size=(n, 3))
    q[0], f[1, 2], w[2, 0], q[3] = 0.0, np.nan, np.inf, 1e-7
    gR, ga, gc = (np.asarray(x) for x in jax.jit(V(fb.imu_sample))(q, f, w))
    bad = 0
    for i in range(n):
        want = imu_sample(ImuSample(q[i], w[i], f[i]))
        if isinstance(want, str):
            assert want == fr.OUTER[gc[i]], i
            bad += 1
            continue
        assert gc[i] == fr.OK
        assert rel_err(gR[i], want[0]) < 1e-12 and rel_err(ga[i], want[1]) < 1e-12
    assert bad == 4


def test_range_noise_and_offset_match_the_single_filters() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(3, 200)
    n = len(ranges)
    rng = np.random.default_rng(4)
    valid = rng.random((n, 4)) < 0.9
    take = rng.random(n) < 0.8
    ranges[3, 1] = np.nan
    log_var = np.full(n, 2.0 * math.log(PARAMS.tof_sigma)) + rng.normal(0, 0.3, n)
    weight = rng.integers(1, 40, n).astype(float)

    def single(i: int) -> FusedEstimator:
        s = FusedEstimator(lambda r: (np.zeros((4, 2)), np.ones(4, bool)), RIG, TAG, params=PARAMS)
        s._log_var, s._var_weight = float(log_var[i]), float(weight[i])
        return s

    singles = [single(i) for i in range(n)]
    for i in np.flatnonzero(take):
        singles[i]._update_range_noise(SensorFrame(0.0, None, ranges[i], valid[i]))
    glv, gw = jax.jit(V(lambda r, v, t, lv, w: fb.range_noise(C, r, v, t, lv, w)))(
        ranges, valid, take, log_var, weight
    )
    want_w = np.array([s._var_weight for s in singles])
    assert np.array_equal(np.asarray(gw), want_w) and (want_w != weight).sum() > 50
    assert rel_err(glv, np.array([s._log_var for s in singles])) < 1e-12
    # the range offset: IHRCF's and ATDA's positions a few cm apart in depth
    p_atda = p_bd + rng.normal(0.0, 0.02, p_bd.shape)
    bias = rng.normal(0.0, 0.01, (n, 2))
    P0 = np.diag([PARAMS.range_offset_sigma**2, PARAMS.atda_depth_bias_sigma**2])
    bias_P = np.tile(P0, (n, 1, 1)) * rng.uniform(0.2, 1.0, (n, 1, 1))
    for i, s in enumerate(singles):
        s._log_var = 2.0 * math.log(float(sigma_r[i]))  # range_sigma = sigma_r
        s._bias, s._bias_P = bias[i].copy(), bias_P[i].copy()
        if take[i]:
            s._update_range_offset(pose(R_bd[i], p_bd[i]), corners(used[i]), pose(R_bd[i], p_atda[i]))
    gb, gP = jax.jit(V(lambda t, a, u, b, s, x, P: fb.range_offset(C, t, a, u, b, s, x, P)))(
        take, p_bd, used, p_atda, sigma_r, bias, bias_P
    )
    want_b = np.stack([s._bias for s in singles])
    assert (np.abs(want_b - bias).max(axis=1) > 0).sum() > 50
    assert rel_err(gb, want_b) < 1e-12 and rel_err(gP, np.stack([s._bias_P for s in singles])) < 1e-12
