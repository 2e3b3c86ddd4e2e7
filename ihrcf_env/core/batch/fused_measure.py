"""The measurement step of the batched fused filter (``FusedEstimator._measure`` per row).

:func:`measure` runs IHRCF (batched, on the offset- and time-corrected ranges) and ATDA (with the
filter's flip prior) on the rows with corners, then updates or starts each row's filters with the
single filter's blocks in the single filter's order, each block a masked batched update: the
attitude (a new filter: IHRCF's attitude first, ungated; then ATDA's; an existing one: ATDA's,
then IHRCF's tilt), the refit's yaw, the position (refit or IHRCF, then ATDA), the rejection
counters and the range-noise and range-offset estimates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch import fused_result as fr
from ihrcf_env.core.batch.fused_frames import BatchFrames
from ihrcf_env.core.batch.geometry import matrix_from_euler_batch
from ihrcf_env.core.batch.ihrcf import ihrcf_measure_batch
from ihrcf_env.core.batch.imm import BatchImm
from ihrcf_env.core.batch.pnp import PnPCandidates, pnp_candidates, pnp_choose
from ihrcf_env.core.estimators.fused_ranges import ranges_distance, ranges_plane, ranges_tilt
from ihrcf_env.core.frames import R_BODY_CAM

if TYPE_CHECKING:
    from ihrcf_env.core.batch.fused import BatchFused
    from ihrcf_env.core.estimators.fused_params import FusedParams

F64 = NDArray[np.float64]
Rows = NDArray[np.intp]
#: E[ln X] for X ~ chi-square(1) (as the single filter).
_LOG_CHI2_1_MEAN = -1.2703628454614782


@dataclass
class MeasureParts:
    """Per row (N,): the inner reason code, IHRCF's code and fit RMS, ATDA's code."""

    inner: NDArray[np.int8]
    ihrcf_code: NDArray[np.int8]
    ihrcf_rms: F64
    atda_code: NDArray[np.int8]


def _rows_of(c: PnPCandidates, i: Rows) -> PnPCandidates:
    return PnPCandidates(c.rotation[i], c.position[i], c.error[i], c.usable[i], c.code[i])


class _Apply:
    """Sequential masked block updates of one filter bank, with its per-row counters."""

    def __init__(self, kf: BatchImm, first: NDArray[np.bool_], gate: dict[int, float]) -> None:
        self.kf, self.first, self.gate = kf, first, gate
        n = len(first)
        self.tried = np.zeros(n, dtype=np.int64)
        self.ok = np.zeros(n, dtype=np.int64)

    def __call__(self, i: Rows, z: F64, R: F64, rows: tuple[int, int], listed: bool = True) -> None:
        if i.size == 0:
            return
        gate = np.where(self.first[i], np.inf, self.gate[rows[1] - rows[0]])
        ok, _ = self.kf.update(i, z, rows, R, gate)
        self.first[i] = False
        self.tried[i] += listed
        self.ok[i] += ok


def _filtered_R_bd(att: BatchImm, i: Rows, R_wb: F64) -> F64:
    return R_wb[i].transpose(0, 2, 1) @ matrix_from_euler_batch(att.x(i)[:, 0:3])


def measure(
    bf: BatchFused, frames: BatchFrames, go: NDArray[np.bool_], t: F64, R_wb: F64, atda: PnPCandidates | None
) -> MeasureParts:
    """``FusedEstimator._measure`` of the rows ``go`` (state of ``bf`` updated in place)."""
    p, n, blocks = bf.params, bf.n, bf.blocks
    parts = MeasureParts(np.zeros(n, np.int8), np.zeros(n, np.int8), np.zeros(n), np.zeros(n, np.int8))
    det = go & frames.detected
    parts.inner[go & ~frames.detected] = fr.CORNERS
    pos, att = bf.pos, bf.att
    offset_state = p.range_offset_sigma > 0 and bf.K is not None and p.use_atda_position
    ranges = frames.ranges - bf.bias[:, 0:1] if offset_state else frames.ranges.copy()
    shift = t - frames.ranges_time
    moved = det | (go & p.range_only_update)
    i = np.flatnonzero(moved & pos.alive & (shift != 0.0) & ~np.isnan(shift))
    if i.size:
        v = pos.x(i)[:, 3:6]
        v_cam = np.einsum("ji,nkj,nk->ni", R_BODY_CAM, R_wb[i], v)
        ranges[i] += v_cam[:, 2:3] * shift[i, None]
    if p.range_only_update:
        range_only(bf, frames, go & ~frames.detected, ranges, t, R_wb)
    D = np.flatnonzero(det)
    if D.size == 0:
        return parts
    # IHRCF up to its corners, then its rigid fit
    ih = ihrcf_measure_batch(
        frames.corners[D], ranges[D], frames.ranges_valid[D], np.ones(D.size, bool),
        bf.table, bf.rig, bf.tag_size, bf.max_residual,
    )  # fmt: skip
    ih_valid = np.zeros(n, dtype=bool)
    ih_valid[D] = ih.poses.valid
    parts.ihrcf_code[D], parts.ihrcf_rms[D] = ih.poses.code, ih.poses.fit_rms
    ih_R, ih_p = np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3))
    ih_R[D], ih_p[D] = ih.poses.rotation, ih.poses.position
    corners_cam, used = np.zeros((n, 4, 3)), np.zeros((n, 4), dtype=bool)
    corners_cam[D], used[D] = ih.corners_cam, ih.ranges_used
    _range_noise(bf, frames, ih_valid)
    # ATDA with the filter's prediction (else its last estimate) as the flip prior
    at_valid = np.zeros(n, dtype=bool)
    at_R, at_p = np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3))
    parts.atda_code[D] = fr.ATDA_NOT_USED
    if bf.K is not None and (p.use_atda_attitude or p.use_atda_position):
        prior = bf.atda_prior[D].copy()
        has = bf.has_prior[D].copy()
        alive = att.alive[D]
        if alive.any():
            prior[alive] = _filtered_R_bd(att, D[alive], R_wb)
            has |= alive
        if atda is None:
            cands = pnp_candidates(
                frames.corners[D], np.ones(D.size, bool), bf.K, bf.dist, bf.tag_size, bf.rig
            )
        else:
            cands = _rows_of(atda, D)
        est = pnp_choose(cands, prior, has)
        at_valid[D] = est.valid
        parts.atda_code[D] = est.code
        at_R[D], at_p[D] = est.rotation, est.position
        took = D[est.valid]
        bf.atda_prior[took], bf.has_prior[took] = est.rotation[est.valid], True
    fail = det & ~ih_valid & ~at_valid
    parts.inner[fail] = fr.BOTH_FAILED
    if p.range_only_update:
        range_only(bf, frames, fail, ranges, t, R_wb)
    cont = det & ~fail
    # a filter whose every measurement was rejected for max_rejections frames has lost track
    for kf in (att, pos):
        m = cont & kf.alive & (kf.rejected_run >= p.max_rejections)
        kf.drop(m)
        bf.converged[m] = False
    idle = cont & ~att.alive & ~pos.alive & ~ih_valid & (not p.use_atda_position)
    parts.inner[idle] = fr.IHRCF_FAILED
    cont &= ~idle
    new_att = cont & ~att.alive
    att.start(np.flatnonzero(new_att), t[new_att])
    new_pos = cont & ~pos.alive & (ih_valid | (at_valid & p.use_atda_position))
    pos.start(np.flatnonzero(new_pos), t[new_pos])
    sigma_r = bf.range_sigma
    A, P = _Apply(att, new_att.copy(), bf.gate), _Apply(pos, new_pos.copy(), bf.gate)
    use_at_att = bf.K is not None and p.use_atda_attitude
    use_at_pos = bf.K is not None and p.use_atda_position

    # 1. attitude
    i = np.flatnonzero(new_att & ih_valid)
    if i.size:
        A(i, *blocks.ihrcf_attitude(ih_R[i], ih_p[i], used[i], R_wb[i], sigma_r[i], True), (0, 3))
    if use_at_att:
        i = np.flatnonzero(cont & at_valid)
        if i.size:
            A(i, *blocks.atda_attitude(at_R[i], at_p[i], R_wb[i]), (0, 3))
    i = np.flatnonzero(cont & ~new_att & ih_valid)
    if i.size:
        yaw = not p.refit
        A(
            i,
            *blocks.ihrcf_attitude(ih_R[i], ih_p[i], used[i], R_wb[i], sigma_r[i], yaw),
            (0, 3 if yaw else 2),
        )
    # 2. refit on the updated normal, its yaw, then the positions
    hv = cont & ih_valid
    ref_ok = np.zeros(n, dtype=bool)
    src_R, src_p = ih_R.copy(), ih_p.copy()
    if p.refit:
        i = np.flatnonzero(hv)
        if i.size:
            R_r, p_r, ok = blocks.refit(corners_cam[i], used[i], ranges[i], _filtered_R_bd(att, i, R_wb))
            ref_ok[i[ok]] = True
            src_R[i[ok]], src_p[i[ok]] = R_r[ok], p_r[ok]
        j = np.flatnonzero(ref_ok & ~new_att)
        if j.size:
            A(j, *blocks.refit_yaw(src_R[j], src_p[j], sigma_r[j], R_wb[j]), (2, 3), listed=False)
    z1, R1 = np.zeros((n, 3)), np.zeros((n, 3, 3))
    i = np.flatnonzero(ref_ok)
    if i.size:
        C = att.value_cov(i)
        tilt_var = np.maximum(C[:, 0, 0], C[:, 1, 1])
        z1[i], R1[i] = blocks.refit_position(src_p[i], used[i], R_wb[i], sigma_r[i], tilt_var)
    i = np.flatnonzero(hv & ~ref_ok)
    if i.size:
        z1[i], R1[i] = blocks.ihrcf_position(ih_p[i], used[i], R_wb[i], sigma_r[i])
    if offset_state:
        _range_offset(bf, np.flatnonzero(hv & at_valid), src_p, used, at_p)
    i = np.flatnonzero(hv)
    P(i, z1[i], R1[i], (0, 3))
    if use_at_pos:
        i = np.flatnonzero(cont & at_valid)
        if i.size:
            z2, R2 = blocks.atda_position(at_p[i], R_wb[i])
            P(i, z2, R2, (0, 3))
            if p.reseed_agreeing:  # both positions rejected: FusedEstimator._reseed
                k = np.flatnonzero(hv[i] & pos.alive[i] & (P.ok[i] == 0) & (pos.rejected_run[i] > 0))
                if k.size:
                    P.ok[i[k]] += _reseed(pos, i[k], z1[i[k]], R1[i[k]], z2[k], R2[k], bf.gate[3], p)
    # counters
    for kf, ap in ((att, A), (pos, P)):
        m = cont & kf.alive & (ap.tried > 0)
        acc = ap.ok > 0
        kf.frames[m] += acc[m]
        kf.rejected_run[m] = np.where(acc[m], 0, kf.rejected_run[m] + 1)
        kf.last_accepted[m & acc] = t[m & acc]
    if p.drop_lost_track:  # a filter that lost track is not coasted on
        for kf in (att, pos):
            m = cont & kf.alive & (kf.rejected_run >= p.max_rejections)
            kf.drop(m)
            bf.converged[m] = False
    rejected = cont & (A.ok + P.ok == 0)
    parts.inner[rejected] = fr.ALL_REJECTED
    parts.inner[cont & ~rejected & ~ih_valid] = fr.IHRCF_FAILED
    return parts


def _reseed(
    kf: BatchImm, i: Rows, za: F64, Ra: F64, zb: F64, Rb: F64, gate: float, p: FusedParams
) -> NDArray[np.int64]:
    """``FusedEstimator._reseed`` of rows ``i`` (measurements ``a`` and ``b``); 1 where it did."""
    d = za - zb
    agree = ~(np.einsum("ni,ni->n", d, np.linalg.solve(Ra + Rb, d[:, :, None])[:, :, 0]) > gate)
    j = np.flatnonzero(agree)
    if j.size:
        info_a, info_b = np.linalg.inv(Ra[j]), np.linalg.inv(Rb[j])
        R = np.linalg.inv(info_a + info_b)
        R = 0.5 * (R + R.transpose(0, 2, 1))
        z = np.einsum(
            "nij,nj->ni", R, np.einsum("nij,nj->ni", info_a, za[j]) + np.einsum("nij,nj->ni", info_b, zb[j])
        )
        kf.reseed(i[j], z, R, p.init_velocity_sigma**2)
    return agree.astype(np.int64)


def _range_noise(bf: BatchFused, frames: BatchFrames, rows: NDArray[np.bool_]) -> None:
    """One range-variance sample per row of ``rows`` with four valid, finite, positive ranges."""
    r = frames.ranges
    with np.errstate(invalid="ignore"):
        ok = rows & frames.ranges_valid.all(axis=1) & np.isfinite(r).all(axis=1) & (r.min(axis=1) > 0)
    if not ok.any():
        return
    p = bf.params
    ssr = (r[ok] @ bf.residual_direction) ** 2
    sample = np.log(np.maximum(ssr, p.tof_sigma_min**2)) - _LOG_CHI2_1_MEAN
    w = np.minimum(bf.var_weight[ok] + 1.0, float(p.tof_sigma_window))
    bf.var_weight[ok] = w
    bf.log_var[ok] += (sample - bf.log_var[ok]) / w


def _range_offset(bf: BatchFused, i: Rows, p_ihrcf: F64, used: NDArray[np.bool_], p_atda: F64) -> None:
    """``FusedEstimator._update_range_offset`` of rows ``i``."""
    if i.size == 0:
        return
    p, blocks = bf.params, bf.blocks
    X, Y = blocks.cam_point(p_ihrcf[i]), blocks.cam_point(p_atda[i])
    d = blocks.depth_scale(Y[:, 2])
    m = used[i].sum(axis=1)
    var = (
        bf.range_sigma[i] ** 2 / np.maximum(m, 1) + (p.atda_depth_sigma * d * d) ** 2 + p.ihrcf_depth_floor**2
    )
    bias, P = bf.bias[i], bf.bias_P[i]
    H = np.array([1.0, -1.0])
    nu = (X[:, 2] - Y[:, 2]) - bias @ H + bias[:, 0]
    S = np.einsum("i,nij,j->n", H, P, H) + var
    ok = ~(nu * nu / S > bf.gate[1])
    i, nu, S, bias, P = i[ok], nu[ok], S[ok], bias[ok], P[ok]
    Kg = (P @ H) / S[:, None]
    bf.bias[i] = bias + Kg * nu[:, None]
    P = P - Kg[:, :, None] * (H @ P)[:, None, :]
    bf.bias_P[i] = 0.5 * (P + P.transpose(0, 2, 1))


def range_only(
    bf: BatchFused, frames: BatchFrames, rows: NDArray[np.bool_], ranges: F64, t: F64, R_wb: F64
) -> None:
    """``FusedEstimator._range_only`` of the rows ``rows`` (frames without a tag measurement):
    the tilt and the distance along the normal of the ranges' plane; no counter changes."""
    p, pos, att, xy = bf.params, bf.pos, bf.att, bf.rig.sensor_xy_cam
    cand = np.flatnonzero(rows & pos.alive & att.alive)
    normals, used = np.zeros((bf.n, 3)), np.zeros((bf.n, 4), dtype=bool)
    has = np.zeros(bf.n, dtype=bool)
    for k in cand:
        plane = ranges_plane(ranges[k], frames.ranges_valid[k], xy)
        if plane is not None:
            normals[k], used[k], has[k] = plane[0], plane[1], True
    full = has & used.all(axis=1)
    _range_noise(bf, frames, full)
    with np.errstate(invalid="ignore"):
        twist = (ranges @ bf.residual_direction) ** 2
    has &= ~(full & (twist > bf.gate[1] * bf.range_sigma**2))
    i = np.flatnonzero(has)
    if i.size == 0:
        return
    sigma_r = bf.range_sigma[i]
    tilt_var = bf.blocks.plane(used[i], sigma_r)[1] + p.ihrcf_tilt_floor**2
    yaw = att.x(i)[:, 2]
    z = np.array([ranges_tilt(normals[k], R_wb[k], float(w)) for k, w in zip(i, yaw, strict=True)])
    R = np.zeros((i.size, 2, 2))
    R[:, 0, 0] = R[:, 1, 1] = tilt_var
    att.update(i, z, (0, 2), R, np.full(i.size, bf.gate[2]))
    C = att.value_cov(i)
    tilt = np.maximum(C[:, 0, 0], C[:, 1, 1])
    R_bd = _filtered_R_bd(att, i, R_wb)
    r = pos.x(i)[:, 0:3]
    cam = np.array(bf.rig.camera_position, dtype=np.float64)
    zd, h, var = np.zeros(i.size), np.zeros((i.size, 3)), np.zeros(i.size)
    for j, k in enumerate(i):
        zd[j], h[j], var[j] = ranges_distance(
            ranges[k], used[k], xy, cam, R_bd[j], R_wb[k], r[j], float(sigma_r[j]), float(tilt[j]),
            p.ihrcf_depth_floor**2,
        )  # fmt: skip
    pos.update_along(i, zd, h, var, np.full(i.size, bf.gate[1]))


__all__ = [
    "MeasureParts",
    "Rows",
    "measure",
    "range_only",
]
