"""The fused filter's measurement blocks (ihrcf_env.fast.fused_blocks) against BlocksBatch, the IMU
sample, the range-noise and range-offset estimates of core.batch, float64."""

from __future__ import annotations

import math
from types import SimpleNamespace

import jax
import numpy as np
from scipy.stats import chi2

from ihrcf_env.core.batch import fused_measure
from ihrcf_env.core.batch.fused import imu_batch
from ihrcf_env.core.batch.fused_blocks import BlocksBatch
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast import fused_blocks as fb

from .fast_helpers import rel_err, rotations

RIG = SensorRig()
TAG = 0.4
PARAMS = FusedParams()
MAXRES = 0.01
REF = BlocksBatch(PARAMS, RIG, TAG, MAXRES)
C = fb.fused_consts(PARAMS, RIG, TAG, MAXRES)
V = jax.vmap


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


def test_consts_match_batch_fused() -> None:
    assert np.array_equal(C.shape, REF._shape) and np.array_equal(C.tilt, REF._tilt)
    assert C.gate == tuple(float(chi2.ppf(PARAMS.gate_probability, k)) for k in (1, 2, 3))


def test_blocks_match_blocks_batch() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(0, 300)
    checks = [
        (
            V(lambda R, p, W: fb.atda_attitude(C, R, p, W)),
            (R_bd, p_bd, R_wb),
            REF.atda_attitude(R_bd, p_bd, R_wb),
        ),
        (V(lambda p, W: fb.atda_position(C, p, W)), (p_bd, R_wb), REF.atda_position(p_bd, R_wb)),
        (
            V(lambda p, u, W, s: fb.ihrcf_position(C, p, u, W, s)),
            (p_bd, used, R_wb, sigma_r),
            REF.ihrcf_position(p_bd, used, R_wb, sigma_r),
        ),
        (
            V(lambda R, p, s, W: fb.refit_yaw(C, R, p, s, W)),
            (R_bd, p_bd, sigma_r, R_wb),
            REF.refit_yaw(R_bd, p_bd, sigma_r, R_wb),
        ),
        (
            V(lambda p, u, W, s, t: fb.refit_position(C, p, u, W, s, t)),
            (p_bd, used, R_wb, sigma_r, sigma_r**2),
            REF.refit_position(p_bd, used, R_wb, sigma_r, sigma_r**2),
        ),
    ]
    for yaw in (True, False):
        checks.append(
            (
                V(lambda R, p, u, W, s, y=yaw: fb.ihrcf_attitude(C, R, p, u, W, s, y)),
                (R_bd, p_bd, used, R_wb, sigma_r),
                REF.ihrcf_attitude(R_bd, p_bd, used, R_wb, sigma_r, yaw),
            )
        )
    for fn, args, (z, R) in checks:
        gz, gR = jax.jit(fn)(*args)
        assert rel_err(gz, z) < 1e-12
        assert rel_err(gR, R) < 1e-12
        assert np.array_equal(np.asarray(gR), np.asarray(gR).transpose(0, 2, 1))
    pl = V(lambda u, s: fb.plane(C, u, s))(used, sigma_r)
    want = REF.plane(used, sigma_r)
    assert rel_err(pl[0], want[0]) < 1e-15 and rel_err(pl[1], want[1]) < 1e-15


def test_refit_matches_blocks_batch() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(1, 300)
    corners_cam[:5, 0, 2] = -1.0  # a corner behind the plane: not refitted
    ranges[5:10] = -1.0  # negative distance
    R, p, ok = REF.refit(corners_cam, used, ranges, R_bd)
    gR, gp, gok = jax.jit(V(lambda a, u, r, b: fb.refit(C, a, u, r, b)))(corners_cam, used, ranges, R_bd)
    assert np.array_equal(np.asarray(gok), ok) and 100 < ok.sum() < 300
    assert rel_err(np.asarray(gR)[ok], R[ok]) < 1e-9
    assert rel_err(np.asarray(gp)[ok], p[ok]) < 1e-9


def test_imu_sample_matches_imu_batch() -> None:
    rng = np.random.default_rng(2)
    n = 64
    q = rng.normal(size=(n, 4))
    f = rng.normal(0, 9.0, (n, 3))
    w = rng.normal(size=(n, 3))
    q[0], f[1, 2], w[2, 0], q[3] = 0.0, np.nan, np.inf, 1e-7
    R, a, code = imu_batch(q, f, w)
    gR, ga, gc = jax.jit(V(fb.imu_sample))(q, f, w)
    assert np.array_equal(np.asarray(gc), code) and (code != 0).sum() == 4
    assert rel_err(gR, R) < 1e-12 and rel_err(ga, a) < 1e-12


def test_range_noise_and_offset_match_fused_measure() -> None:
    R_wb, R_bd, p_bd, used, sigma_r, corners_cam, ranges = scene(3, 200)
    n = len(ranges)
    rng = np.random.default_rng(4)
    valid = rng.random((n, 4)) < 0.9
    take = rng.random(n) < 0.8
    ranges[3, 1] = np.nan
    log_var = np.full(n, 2.0 * math.log(PARAMS.tof_sigma)) + rng.normal(0, 0.3, n)
    weight = rng.integers(1, 40, n).astype(float)
    bf = SimpleNamespace(
        params=PARAMS,
        residual_direction=C.residual_direction,
        var_weight=weight.copy(),
        log_var=log_var.copy(),
    )
    fused_measure._range_noise(bf, SimpleNamespace(ranges=ranges, ranges_valid=valid), take)  # type: ignore[arg-type]
    glv, gw = jax.jit(V(lambda r, v, t, lv, w: fb.range_noise(C, r, v, t, lv, w)))(
        ranges, valid, take, log_var, weight
    )
    assert np.array_equal(np.asarray(gw), bf.var_weight) and (bf.var_weight != weight).sum() > 50
    assert rel_err(glv, bf.log_var) < 1e-12
    # the range offset: IHRCF's and ATDA's positions a few cm apart in depth
    p_atda = p_bd + rng.normal(0.0, 0.02, p_bd.shape)
    bias = rng.normal(0.0, 0.01, (n, 2))
    P0 = np.diag([PARAMS.range_offset_sigma**2, PARAMS.atda_depth_bias_sigma**2])
    bias_P = np.tile(P0, (n, 1, 1)) * rng.uniform(0.2, 1.0, (n, 1, 1))
    bf = SimpleNamespace(
        params=PARAMS,
        blocks=REF,
        range_sigma=sigma_r,
        bias=bias.copy(),
        bias_P=bias_P.copy(),
        gate=dict(zip((1, 2, 3), C.gate, strict=True)),
    )
    fused_measure._range_offset(bf, np.flatnonzero(take), p_bd, used, p_atda)  # type: ignore[arg-type]
    gb, gP = jax.jit(V(lambda t, a, u, b, s, x, P: fb.range_offset(C, t, a, u, b, s, x, P)))(
        take, p_bd, used, p_atda, sigma_r, bias, bias_P
    )
    assert (np.abs(bf.bias - bias).max(axis=1) > 0).sum() > 50
    assert rel_err(gb, bf.bias) < 1e-12 and rel_err(gP, bf.bias_P) < 1e-12
