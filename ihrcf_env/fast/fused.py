"""The IMU-fused deck-pose filter for one environment: the port of
:class:`ihrcf_env.core.estimators.fused.FusedEstimator` (one filter per environment, its reasons as
the codes of :mod:`ihrcf_env.core.estimators.fused_reasons`): time checks, bad IMU samples, timeouts, the IMM
prediction on the IMU, IHRCF and ATDA with the filter's flip prior, the gated sequential blocks in
the single filter's order, the rejection counters, the range-noise and range-offset estimates, the
position reseed at agreeing measurements, the numerical reset, the delay compensation and the
convergence latch. Every branch is a ``jnp.where`` selection.

Configuration is host-side (:func:`fused_setup`); the filter's state is a :class:`FusedState`
pytree (:func:`fused_init`, :func:`fused_reset`) and a step is :func:`fused_update`
(:func:`fused_update_with_ihrcf`: with IHRCF's estimate of a second reading of the frame's
corners, made in the same call as the filter's own IHRCF). The
range-only update (``FusedParams.range_only_update``) is not ported: :func:`fused_setup` refuses
it. Frames and units as :mod:`ihrcf_env.fast.fused_blocks`.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax, tree_util

from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import fused_reasons as fr
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.fast import fused_blocks as fb
from ihrcf_env.fast import imm
from ihrcf_env.fast.ihrcf import IHRCFSetup, Pose, ihrcf_parts, ihrcf_setup
from ihrcf_env.fast.linalg3 import euler_from_matrix, matrix_from_euler
from ihrcf_env.fast.pnp import Candidates, pnp_candidates, pnp_choose
from ihrcf_env.fast.table import touch_table

__all__ = [
    "Bank",
    "FusedFrame",
    "FusedOutput",
    "FusedSetup",
    "FusedState",
    "fused_init",
    "fused_reset",
    "fused_setup",
    "fused_update",
    "fused_update_with_ihrcf",
]


class FusedSetup(NamedTuple):
    """Host-side configuration: the blocks' constants, the two banks' models, IHRCF's setup, the
    camera (``K`` (3, 3) and ``dist`` (5,), None: no ATDA) and the camera's position on the body."""

    consts: fb.FusedConsts
    pos: imm.ImmConfig
    att: imm.ImmConfig
    ihrcf: IHRCFSetup
    K: np.ndarray | None
    dist: np.ndarray
    camera_position: np.ndarray


class Bank(NamedTuple):
    """One filter bank and its counters: ``alive``, accepted ``frames``, ``rejected_run`` (frames
    in a row with every measurement rejected), ``last_accepted`` (s)."""

    imm: imm.ImmState
    alive: Array
    frames: Array
    rejected_run: Array
    last_accepted: Array


class FusedOutput(NamedTuple):
    """The filter's output for one environment: the :class:`PoseEstimate` of
    :meth:`FusedEstimator.update <ihrcf_env.core.estimators.fused.FusedEstimator.update>` and its
    ``motion()`` as arrays, and its reason as codes (``outer`` / ``inner`` of
    :mod:`ihrcf_env.core.estimators.fused_reasons`, IHRCF's and ATDA's of
    :mod:`ihrcf_env.core.estimators.reasons`) with the numbers the templates need."""

    position: Array
    euler: Array
    rotation: Array
    valid: Array
    residual: Array
    velocity: Array
    normal_rate: Array
    motion_valid: Array
    frame_time: Array
    outer: Array
    outer_num: Array
    inner: Array
    inner_num: Array
    ihrcf_code: Array
    ihrcf_rms: Array
    atda_code: Array


class FusedState(NamedTuple):
    """The filter's state (the :class:`~ihrcf_env.core.estimators.fused.FusedEstimator`'s as arrays)
    and its last output."""

    pos: Bank
    att: Bank
    pos_ahead: Bank
    att_ahead: Bank
    time: Array
    has_time: Array
    R_wb: Array
    a_world: Array
    log_var: Array
    var_weight: Array
    atda_prior: Array
    has_prior: Array
    bias: Array
    bias_P: Array
    converged: Array
    has_ahead: Array
    out: FusedOutput


class FusedFrame(NamedTuple):
    """One sensor frame (the fields of a :class:`~ihrcf_env.core.estimators.base.SensorFrame` as
    arrays, without the reason text: ``detected`` for corners present, ``imu_present`` /
    ``arrival_present`` for the IMU samples, unknown times NaN)."""

    time: Array
    detected: Array
    corners: Array
    ranges: Array
    ranges_valid: Array
    ranges_time: Array
    imu_present: Array
    quaternion: Array
    angular_velocity: Array
    specific_force: Array
    arrival_time: Array
    arrival_present: Array
    arrival_quaternion: Array
    arrival_angular_velocity: Array
    arrival_specific_force: Array


def fused_setup(
    table: RangePixelTable,
    rig: SensorRig,
    tag_size: float,
    K: Any = None,
    dist: Any = None,
    max_residual: float = 0.01,
    params: FusedParams | None = None,
) -> FusedSetup:
    """The :class:`FusedSetup` of a filter (arguments as :class:`BatchFused`'s, the table a
    :class:`RangePixelTable`); ValueError for an option the port does not have."""
    p = params if params is not None else FusedParams()
    if not isinstance(p, FusedParams):
        raise TypeError(f"params must be a FusedParams, got {type(p).__name__}")
    if p.range_only_update:
        raise ValueError("FusedParams.range_only_update is not supported by the JAX fused filter")
    if p.deck_model != "kinematic":
        raise ValueError(f"FusedParams.deck_model={p.deck_model!r} is not supported by the JAX fused filter")
    if not (math.isfinite(max_residual) and max_residual > 0):
        raise ValueError(f"max_residual must be positive (m), got {max_residual!r}")
    walk2 = p.imu_attitude_walk**2
    leak = GRAVITY * p.imu_attitude_walk
    pos = imm.imm_config(
        (10.0, p.init_velocity_sigma, p.init_accel_sigma),
        [np.array([math.hypot(d, leak), math.hypot(d, leak), d]) for d in p.accel_drift],
        np.full(3, p.accel_noise),
        p.model_switch_time,
    )
    att = imm.imm_config(
        (math.pi, p.init_rate_sigma, p.init_angle_accel_sigma),
        [np.full(3, d) for d in p.angle_drift],
        np.full(3, p.angle_accel_noise),
        p.model_switch_time,
        angles=True,
        q_value=np.diag([walk2, walk2, 0.0]),
    )
    d = np.zeros(5)
    if dist is not None:
        dd = np.asarray(dist, dtype=np.float64).ravel()
        d[: dd.size] = dd
    return FusedSetup(
        fb.fused_consts(p, rig, tag_size, max_residual),
        pos,
        att,
        ihrcf_setup(touch_table(table), rig, tag_size, max_residual),
        None if K is None else np.asarray(K, dtype=np.float64).reshape(3, 3),
        d,
        np.array(rig.camera_position, dtype=np.float64),
    )


def _bank(cfg: imm.ImmConfig) -> Bank:
    z = jnp.zeros((), jnp.int32)
    return Bank(imm.imm_start(cfg), jnp.zeros((), bool), z, z, jnp.zeros(()))


def fused_init(setup: FusedSetup) -> FusedState:
    """A filter that has seen nothing (as :meth:`BatchFused.reset`)."""
    p = setup.consts.params
    eye = jnp.eye(3)
    _F = jnp.result_type(float)  # the default float dtype, not weakly typed
    out = FusedOutput(
        jnp.zeros(3), jnp.zeros(3), eye, jnp.zeros((), bool), jnp.zeros(()), jnp.zeros(3), jnp.zeros(3),
        jnp.zeros((), bool), jnp.full((), jnp.nan, _F), jnp.full((), fr.NOT_INITIALISED, jnp.int32),
        jnp.zeros(2), jnp.zeros((), jnp.int32), jnp.zeros(()), jnp.zeros((), jnp.int32), jnp.zeros(()),
        jnp.zeros((), jnp.int32),
    )  # fmt: skip
    return FusedState(
        _bank(setup.pos), _bank(setup.att), _bank(setup.pos), _bank(setup.att),
        jnp.zeros(()), jnp.zeros((), bool), eye, jnp.full(3, jnp.nan, _F),
        jnp.full((), 2.0 * math.log(p.tof_sigma), _F), jnp.ones(()), eye, jnp.zeros((), bool),
        jnp.zeros(2), jnp.diag(jnp.array([p.range_offset_sigma**2, p.atda_depth_bias_sigma**2])),
        jnp.zeros((), bool), jnp.zeros((), bool), out,
    )  # fmt: skip


def _sel(m: Array, a: Any, b: Any) -> Any:
    """``a`` where ``m`` else ``b``, leaf by leaf (scalar ``m``)."""
    from jax import tree_util

    return tree_util.tree_map(lambda x, y: jnp.where(m, x, y), a, b)


def fused_reset(setup: FusedSetup, st: FusedState, mask: Array) -> FusedState:
    """The state forgotten where ``mask`` (as :meth:`BatchFused.reset` of a row)."""
    return _sel(mask, fused_init(setup), st)


def _drop(b: Bank, m: Array) -> Bank:
    return b._replace(alive=b.alive & ~m)


def _start(b: Bank, m: Array, t: Array, cfg: imm.ImmConfig) -> Bank:
    new = Bank(imm.imm_start(cfg), jnp.ones((), bool), jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32), t)
    return _sel(m, new, b)


def _finite(b: Bank) -> Array:
    return jnp.all(jnp.isfinite(b.imm.X)) & jnp.all(jnp.isfinite(b.imm.Ps)) & jnp.all(jnp.isfinite(b.imm.mu))


def _filtered_R_bd(att: Bank, cfg: imm.ImmConfig, R_wb: Array) -> Array:
    return R_wb.T @ matrix_from_euler(imm.x(att.imm, cfg)[0:3])


def _inv3(A: Array) -> Array:
    a, b, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, h, i = A[2, 0], A[2, 1], A[2, 2]
    adj = jnp.array(
        [
            [e * i - f * h, c * h - b * i, b * f - c * e],
            [f * g - d * i, a * i - c * g, c * d - a * f],
            [d * h - e * g, b * g - a * h, a * e - b * d],
        ]
    )
    return adj / (a * adj[0, 0] + b * adj[1, 0] + c * adj[2, 0])


class _Apply(NamedTuple):
    bank: Bank
    first: Array
    tried: Array
    ok: Array


def _apply(
    a: _Apply,
    m: Array,
    z: Array,
    R: Array,
    lo: int,
    hi: int,
    cfg: imm.ImmConfig,
    gates: tuple[float, ...],
    listed: bool = True,
) -> _Apply:
    gate = jnp.where(a.first, jnp.inf, gates[hi - lo - 1])
    new, ok, _ = imm.update(a.bank.imm, z, lo, hi, R, gate, cfg)
    return _Apply(
        a.bank._replace(imm=_sel(m, new, a.bank.imm)),
        a.first & ~m,
        a.tried + (m & listed).astype(jnp.int32),
        a.ok + (m & ok).astype(jnp.int32),
    )


def _apply_all(
    a: _Apply,
    items: list[tuple[Array, Array, Array]],
    lo: int,
    hi: int,
    cfg: imm.ImmConfig,
    gates: tuple[float, ...],
) -> _Apply:
    """:func:`_apply` of the measurements ``items`` ((mask, z, R) of the same values ``lo:hi``) in
    order: one update under ``lax.scan`` for more than one."""
    if len(items) == 1:
        m, z, R = items[0]
        return _apply(a, m, z, R, lo, hi, cfg, gates)
    xs = tuple(jnp.stack([jnp.asarray(it[k]) for it in items]) for k in range(3))

    def one(carry: _Apply, x: tuple[Array, ...]) -> tuple[_Apply, None]:
        return _apply(carry, x[0], x[1], x[2], lo, hi, cfg, gates), None

    return lax.scan(one, a, xs)[0]


def _predict(b: Bank, m: Array, dt: Array, cfg: imm.ImmConfig, u: Array | None, q: Array | None) -> Bank:
    new = imm.predict(b.imm, dt, cfg, u, q)
    return b._replace(imm=_sel(m, new, b.imm))


def _predict_pair(
    pos: Bank,
    att: Bank,
    m: tuple[Array, Array],
    dt: tuple[Array, Array],
    setup: FusedSetup,
    u: Array,
    q: Array,
) -> tuple[Bank, Bank]:
    """A position bank (input ``u``, value noise ``q``) and an attitude bank predicted where ``m``
    over ``dt`` (s): one call over a bank axis when they have the same number of models."""
    if setup.pos.drifts.shape != setup.att.drifts.shape:
        return _predict(pos, m[0], dt[0], setup.pos, u, q), _predict(att, m[1], dt[1], setup.att, None, None)
    both = tree_util.tree_map(lambda a, b: jnp.stack([a, b]), pos.imm, att.imm)
    uu = jnp.stack([u, jnp.full_like(u, jnp.nan)])  # the attitude bank has no input
    qq = jnp.stack([q, jnp.zeros_like(q)])
    new = imm.predict_banks(both, jnp.stack(dt), (setup.pos, setup.att), uu, qq)
    new_pos = tree_util.tree_map(lambda a: a[0], new)
    new_att = tree_util.tree_map(lambda a: a[1], new)
    return pos._replace(imm=_sel(m[0], new_pos, pos.imm)), att._replace(imm=_sel(m[1], new_att, att.imm))


def _measure(
    setup: FusedSetup,
    st: FusedState,
    f: FusedFrame,
    go: Array,
    t: Array,
    R_wb: Array,
    cands: Candidates | None,
    other: tuple[Array, Array, Array] | None = None,
) -> tuple[FusedState, Array, Array, Array, Array, Pose | None]:
    """The frame's measurement step (``FusedEstimator._measure``): (state, inner, ihrcf code,
    ihrcf RMS, ATDA code, IHRCF's pose of the ``other`` reading (ranges, their validity,
    detected) of the frame's corners, computed in the same call as the filter's own; None without
    it)."""
    c = setup.consts
    p = c.params
    pos, att = st.pos, st.att
    converged, atda_prior, has_prior = st.converged, st.atda_prior, st.has_prior
    det = go & f.detected
    inner = jnp.where(go & ~f.detected, fr.CORNERS, 0)
    use_K = setup.K is not None
    offset_state = p.range_offset_sigma > 0 and use_K and p.use_atda_position
    ranges = f.ranges - st.bias[0] if offset_state else f.ranges
    shift = t - f.ranges_time
    sel = det & pos.alive & (shift != 0.0) & ~jnp.isnan(shift)
    v = imm.x(pos.imm, setup.pos)[3:6]
    v_cam = jnp.asarray(R_BODY_CAM).T @ (R_wb.T @ v)
    ranges = jnp.where(sel, ranges + v_cam[2] * jnp.where(sel, shift, 0.0), ranges)
    # IHRCF
    other_pose = None
    if other is None:
        one = jnp.ones((), bool)
        pose, corners_cam, used = ihrcf_parts(f.corners, ranges, f.ranges_valid, one, setup.ihrcf)
    else:  # both readings in one call over a leading pair axis
        o_ranges, o_valid, o_det = other
        both = jax.vmap(ihrcf_parts, in_axes=(None, 0, 0, 0, None))(
            f.corners,
            jnp.stack([ranges, jnp.asarray(o_ranges, ranges.dtype)]),
            jnp.stack([f.ranges_valid, o_valid]),
            jnp.stack([jnp.ones((), bool), jnp.asarray(o_det, bool)]),
            setup.ihrcf,
        )
        pose, corners_cam, used = tree_util.tree_map(lambda a: a[0], both)
        other_pose = tree_util.tree_map(lambda a: a[1], both[0])
    ih_valid = det & pose.valid
    ihrcf_code = jnp.where(det, pose.code.astype(jnp.int32), 0)
    ihrcf_rms = jnp.where(det, pose.fit_rms, 0.0)
    ih_R, ih_p = pose.rotation, pose.position
    log_var, var_weight = fb.range_noise(c, f.ranges, f.ranges_valid, ih_valid, st.log_var, st.var_weight)
    # ATDA with the filter's prediction (else its last estimate) as the flip prior
    at_valid = jnp.zeros((), bool)
    at_R, at_p = jnp.eye(3), jnp.zeros(3)
    atda_code = jnp.where(det, fr.ATDA_NOT_USED, 0)
    if use_K and (p.use_atda_attitude or p.use_atda_position):
        assert setup.K is not None
        alive = att.alive
        prior = jnp.where(alive, _filtered_R_bd(att, setup.att, R_wb), atda_prior)
        has = has_prior | alive
        if cands is None:
            cands = pnp_candidates(
                f.corners, jnp.ones((), bool), jnp.asarray(setup.K), jnp.asarray(setup.dist), c.tag_size,
                jnp.asarray(setup.camera_position),
            )  # fmt: skip
        est = pnp_choose(cands, prior, has)
        at_valid = det & est.valid
        atda_code = jnp.where(det, est.code.astype(jnp.int32), 0)
        at_R, at_p = est.rotation, est.position
        atda_prior = jnp.where(at_valid, est.rotation, atda_prior)
        has_prior = has_prior | at_valid
    fail = det & ~ih_valid & ~at_valid
    inner = jnp.where(fail, fr.BOTH_FAILED, inner)
    cont = det & ~fail
    for name in ("att", "pos"):
        b = att if name == "att" else pos
        m = cont & b.alive & (b.rejected_run >= p.max_rejections)
        b = _drop(b, m)
        converged &= ~m
        att, pos = (b, pos) if name == "att" else (att, b)
    idle = cont & ~att.alive & ~pos.alive & ~ih_valid & (not p.use_atda_position)
    inner = jnp.where(idle, fr.IHRCF_FAILED, inner)
    cont &= ~idle
    new_att = cont & ~att.alive
    att = _start(att, new_att, t, setup.att)
    new_pos = cont & ~pos.alive & (ih_valid | (at_valid & p.use_atda_position))
    pos = _start(pos, new_pos, t, setup.pos)
    sigma_r = jnp.exp(0.5 * log_var)
    zi = jnp.zeros((), jnp.int32)
    A, P = _Apply(att, new_att, zi, zi), _Apply(pos, new_pos, zi, zi)
    use_at_att = use_K and p.use_atda_attitude
    use_at_pos = use_K and p.use_atda_position
    gates = c.gate
    # 1. attitude
    z, R = fb.ihrcf_attitude(c, ih_R, ih_p, used, R_wb, sigma_r, True)
    first_att = [(new_att & ih_valid, z, R)]
    if use_at_att:
        z, R = fb.atda_attitude(c, at_R, at_p, R_wb)
        first_att.append((cont & at_valid, z, R))
    yaw = not p.refit
    z, R = fb.ihrcf_attitude(c, ih_R, ih_p, used, R_wb, sigma_r, yaw)
    if yaw:  # the same values: one more of the same update
        A = _apply_all(A, [*first_att, (cont & ~new_att & ih_valid, z, R)], 0, 3, setup.att, gates)
    else:
        A = _apply_all(A, first_att, 0, 3, setup.att, gates)
        A = _apply(A, cont & ~new_att & ih_valid, z, R, 0, 2, setup.att, gates)
    # 2. refit on the updated normal, its yaw, then the positions
    hv = cont & ih_valid
    ref_ok = jnp.zeros((), bool)
    src_R, src_p = ih_R, ih_p
    if p.refit:
        R_r, p_r, ok = fb.refit(c, corners_cam, used, ranges, _filtered_R_bd(A.bank, setup.att, R_wb))
        ref_ok = hv & ok
        src_R, src_p = jnp.where(ref_ok, R_r, ih_R), jnp.where(ref_ok, p_r, ih_p)
        z, R = fb.refit_yaw(c, src_R, src_p, sigma_r, R_wb)
        A = _apply(A, ref_ok & ~new_att, z, R, 2, 3, setup.att, gates, listed=False)
    C = imm.value_cov(A.bank.imm, setup.att)
    z_r, R_r1 = fb.refit_position(c, src_p, used, R_wb, sigma_r, jnp.maximum(C[0, 0], C[1, 1]))
    z_i, R_i1 = fb.ihrcf_position(c, ih_p, used, R_wb, sigma_r)
    z1, R1 = jnp.where(ref_ok, z_r, z_i), jnp.where(ref_ok, R_r1, R_i1)
    bias, bias_P = st.bias, st.bias_P
    if offset_state:
        bias, bias_P = fb.range_offset(c, hv & at_valid, src_p, used, at_p, sigma_r, bias, bias_P)
    if use_at_pos:
        m = cont & at_valid
        z2, R2 = fb.atda_position(c, at_p, R_wb)
        P = _apply_all(P, [(hv, z1, R1), (m, z2, R2)], 0, 3, setup.pos, gates)
        if p.reseed_agreeing:  # both positions rejected: FusedEstimator._reseed
            k = m & hv & P.bank.alive & (P.ok == 0) & (P.bank.rejected_run > 0)
            d = z1 - z2
            S_inv = _inv3(R1 + R2)
            agree = ~(d @ (S_inv @ d) > gates[2])
            info_a, info_b = _inv3(R1), _inv3(R2)
            Rc = _inv3(info_a + info_b)
            Rc = 0.5 * (Rc + Rc.T)
            zc = Rc @ (info_a @ z1 + info_b @ z2)
            do = k & agree
            new = imm.reseed(P.bank.imm, zc, Rc, p.init_velocity_sigma**2)
            P = P._replace(
                bank=P.bank._replace(imm=_sel(do, new, P.bank.imm)), ok=P.ok + do.astype(jnp.int32)
            )
    else:
        P = _apply(P, hv, z1, R1, 0, 3, setup.pos, gates)
    # counters
    banks = []
    for ap in (A, P):
        b = ap.bank
        m = cont & b.alive & (ap.tried > 0)
        acc = ap.ok > 0
        b = b._replace(
            frames=b.frames + (m & acc).astype(jnp.int32),
            rejected_run=jnp.where(m, jnp.where(acc, 0, b.rejected_run + 1), b.rejected_run),
            last_accepted=jnp.where(m & acc, t, b.last_accepted),
        )
        if p.drop_lost_track:
            m = cont & b.alive & (b.rejected_run >= p.max_rejections)
            b = _drop(b, m)
            converged &= ~m
        banks.append(b)
    att, pos = banks
    rejected = cont & (A.ok + P.ok == 0)
    inner = jnp.where(rejected, fr.ALL_REJECTED, inner)
    inner = jnp.where(cont & ~rejected & ~ih_valid, fr.IHRCF_FAILED, inner)
    st = st._replace(
        pos=pos, att=att, converged=converged, atda_prior=atda_prior, has_prior=has_prior,
        log_var=log_var, var_weight=var_weight, bias=bias, bias_P=bias_P,
    )  # fmt: skip
    return st, inner, ihrcf_code, ihrcf_rms, atda_code, other_pose


class _View(NamedTuple):
    """What the output reads of a pair of banks (position, attitude): the largest 1-sigmas, the
    pose in the body frame of ``R_wb``, the residual and the motion (velocity, normal rate)."""

    pos_sigma: Array
    ang_sigma: Array
    R_bd: Array
    euler: Array
    position: Array
    residual: Array
    velocity: Array
    normal_rate: Array


def _view(setup: FusedSetup, pos: imm.ImmState, att: imm.ImmState, R_wb: Array, horizon: float) -> _View:
    xp, xa = imm.x(pos, setup.pos), imm.x(att, setup.att)
    C = imm.value_cov(pos, setup.pos)
    pos_sigma = jnp.sqrt(jnp.maximum(imm.largest_eigenvalue(C), 0.0))
    ang_sigma = imm.value_sigma(att, setup.att)
    # the filtered attitude and the two ends of the normal's central difference, in one call
    a, w = xa[0:3], horizon * xa[3:6]
    Rs = jax.vmap(matrix_from_euler)(jnp.stack([a, a + w, a - w]))
    R_bd = R_wb.T @ Rs[0]
    return _View(
        pos_sigma,
        ang_sigma,
        R_bd,
        euler_from_matrix(R_bd),
        R_wb.T @ xp[0:3],
        jnp.sqrt(jnp.trace(C)),
        xp[3:6],
        (Rs[1][:, 2] - Rs[2][:, 2]) / (2.0 * horizon),
    )


def _views(setup: FusedSetup, st: FusedState, R_wb: Array, horizon: float = 0.01) -> _View:
    """The :class:`_View` of the banks (index 0) and of their arrival-time copies (index 1), in
    one call over a leading pair axis."""
    pos = tree_util.tree_map(lambda a, b: jnp.stack([a, b]), st.pos.imm, st.pos_ahead.imm)
    att = tree_util.tree_map(lambda a, b: jnp.stack([a, b]), st.att.imm, st.att_ahead.imm)
    return jax.vmap(lambda p, a: _view(setup, p, a, R_wb, horizon))(pos, att)


def _output(
    setup: FusedSetup,
    st: FusedState,
    m: Array,
    view: _View,
    pos: Bank,
    att: Bank,
    outer: Array,
    num: Array,
) -> tuple[FusedState, Array, Array]:
    """The filters' pose (``view``, of the banks ``pos`` and ``att``) where ``m``, or why not (in
    ``outer``)."""
    p = setup.consts.params
    outer = jnp.where(m & ~att.alive, fr.NOT_INITIALISED, outer)
    outer = jnp.where(m & att.alive & ~pos.alive, fr.POSITION_NOT_INITIALISED, outer)
    m = m & att.alive & pos.alive
    pos_sigma, ang_sigma = view.pos_sigma, view.ang_sigma
    frames = jnp.minimum(pos.frames, att.frames)
    new = ~st.converged
    c1 = new & (frames < p.min_updates)
    c2 = new & ~c1 & (pos_sigma > p.valid_position_sigma)
    c3 = new & ~c1 & ~c2 & (ang_sigma > p.valid_angle_sigma)
    outer = jnp.where(m & c1, fr.CONVERGING_UPDATES, outer)
    num = jnp.where(m & c1, jnp.stack([frames.astype(num.dtype), jnp.asarray(float(p.min_updates))]), num)
    outer = jnp.where(m & c2, fr.CONVERGING_POSITION, outer)
    num = jnp.where(m & c2, jnp.stack([pos_sigma, jnp.asarray(p.valid_position_sigma)]), num)
    outer = jnp.where(m & c3, fr.CONVERGING_ANGLE, outer)
    num = jnp.where(
        m & c3, jnp.stack([jnp.degrees(ang_sigma), jnp.asarray(math.degrees(p.valid_angle_sigma))]), num
    )
    ok = m & ~(c1 | c2 | c3)
    o = st.out
    o = o._replace(
        rotation=jnp.where(ok, view.R_bd, o.rotation),
        euler=jnp.where(ok, view.euler, o.euler),
        position=jnp.where(ok, view.position, o.position),
        residual=jnp.where(ok, view.residual, o.residual),
    )
    return st._replace(converged=st.converged | ok, out=o), outer, num


def _motion(st: FusedState, views: _View) -> tuple[Array, Array, Array]:
    vel, rate, okk = jnp.zeros(3), jnp.zeros(3), jnp.zeros((), bool)
    for i, ahead in enumerate((False, True)):
        pos, att = (st.pos_ahead, st.att_ahead) if ahead else (st.pos, st.att)
        sel = (st.has_ahead == ahead) & st.converged & pos.alive & att.alive
        vel = jnp.where(sel, views.velocity[i], vel)
        rate = jnp.where(sel, views.normal_rate[i], rate)
        okk = okk | sel
    return vel, rate, okk


def fused_update(
    setup: FusedSetup, st: FusedState, f: FusedFrame, active: Array, cands: Candidates | None = None
) -> FusedState:
    """The filter after fusing frame ``f`` when ``active`` (unchanged, its output held, otherwise);
    ``cands``: ATDA's candidates of the frame (default: :func:`~ihrcf_env.fast.pnp.pnp_candidates`).
    The output is ``state.out``."""
    return _update(setup, st, f, active, cands, None)[0]


def fused_update_with_ihrcf(
    setup: FusedSetup,
    st: FusedState,
    f: FusedFrame,
    active: Array,
    cands: Candidates | None,
    ranges: Array,
    ranges_valid: Array,
    detected: Array,
) -> tuple[FusedState, Pose]:
    """:func:`fused_update` and IHRCF's pose (:func:`~ihrcf_env.fast.ihrcf.ihrcf`) of the frame's
    corners with ``ranges`` (4,) m, ``ranges_valid`` (4,) and ``detected``, computed in one call
    with the filter's own IHRCF (on its delay-compensated ranges) over a leading pair axis."""
    state, pose = _update(setup, st, f, active, cands, (ranges, ranges_valid, detected))
    assert pose is not None
    return state, pose


def _update(
    setup: FusedSetup,
    st: FusedState,
    f: FusedFrame,
    active: Array,
    cands: Candidates | None,
    other: tuple[Array, Array, Array] | None,
) -> tuple[FusedState, Pose | None]:
    p = setup.consts.params
    act = active
    has_ahead = jnp.where(act, False, st.has_ahead)
    t = jnp.where(jnp.isnan(f.time), jnp.where(st.has_time, st.time + p.nominal_dt, 0.0), f.time)
    back = act & st.has_time & (t < st.time)
    outer = jnp.where(back, fr.TIME_BACKWARDS, 0)
    outer_num = jnp.where(back, jnp.stack([t, st.time]), jnp.zeros(2))
    go = act & ~back
    # the frame's IMU sample and the arrival's, in one call over a pair axis
    imu = jax.vmap(fb.imu_sample)(
        jnp.stack([f.quaternion, f.arrival_quaternion]),
        jnp.stack([f.specific_force, f.arrival_specific_force]),
        jnp.stack([f.angular_velocity, f.arrival_angular_velocity]),
    )
    R_imu, a_imu, code = (x[0] for x in imu)
    imu_p = f.imu_present
    bad = go & imu_p & (code != 0)
    outer = jnp.where(bad, code, outer)
    go &= ~bad
    good = go & imu_p
    R_wb = jnp.where(good, R_imu, st.R_wb)
    a_world = jnp.where(imu_p, a_imu, jnp.nan)
    dt = jnp.where(st.has_time, t - st.time, 0.0)
    time = jnp.where(go, t, st.time)
    has_time = st.has_time | go
    # timeouts, then the prediction on the IMU
    lost, lost_t = jnp.zeros((), jnp.int32), jnp.zeros(())
    att, pos, converged = st.att, st.pos, st.converged
    for name, code_k in (("att", fr.NO_ATT), ("pos", fr.NO_POS)):
        b = att if name == "att" else pos
        since = t - b.last_accepted
        m = go & b.alive & (since > p.lost_timeout)
        lost = jnp.where(m, jnp.where(f.detected, code_k, fr.TAG_LOST), lost)
        lost_t = jnp.where(m, since, lost_t)
        b = _drop(b, m)
        converged &= ~m
        att, pos = (b, pos) if name == "att" else (att, b)
    has_prior = jnp.where(go & ~att.alive & ~pos.alive, False, st.has_prior)
    u = a_world
    if p.accel_hold == "trapezoid":
        u = jnp.where(jnp.isfinite(st.a_world), 0.5 * (a_world + st.a_world), a_world)
    a_state = jnp.where(go, a_world, st.a_world)
    walk2 = p.imu_attitude_walk**2
    q = fb.q_tilt(walk2, imm.x(pos.imm, setup.pos)[0:3])
    mp, ma = go & pos.alive, go & att.alive
    dts = (jnp.where(mp, dt, 1.0), jnp.where(ma, dt, 1.0))
    pos, att = _predict_pair(pos, att, (mp, ma), dts, setup, -u, q)
    st = st._replace(
        pos=pos, att=att, converged=converged, has_prior=has_prior, time=time, has_time=has_time,
        R_wb=R_wb, a_world=a_state, has_ahead=has_ahead,
    )  # fmt: skip
    st, inner, ihrcf_code, ihrcf_rms, atda_code, other_pose = _measure(
        setup, st, f, go, t, R_wb, cands, other
    )
    inner = jnp.where(lost != 0, lost, inner)
    inner_num = jnp.where(lost != 0, lost_t, 0.0)
    # numerical failure: both filters dropped
    broken = go & ((st.pos.alive & ~_finite(st.pos)) | (st.att.alive & ~_finite(st.att)))
    st = st._replace(
        pos=_drop(st.pos, broken), att=_drop(st.att, broken), converged=st.converged & ~broken,
        has_prior=st.has_prior & ~broken,
    )  # fmt: skip
    outer = jnp.where(broken, fr.NUMERICAL, outer)
    go &= ~broken
    # a late frame: copies of the filters predicted to its arrival
    late = go & jnp.isfinite(f.arrival_time) & (f.arrival_time > t)
    R_arr, a_arr, code = (x[1] for x in imu)
    arr_p = f.arrival_present
    bad = late & arr_p & (code != 0)
    outer = jnp.where(bad, jnp.where(code == fr.IMU_ZERO, fr.ARRIVAL_ZERO, fr.ARRIVAL_NONFINITE), outer)
    late &= ~bad
    go &= ~bad
    R_now = jnp.where(arr_p, R_arr, R_wb)
    a_now = jnp.where(arr_p, a_arr, a_world)
    u = a_now
    if p.accel_hold == "trapezoid":
        u = jnp.where(jnp.isfinite(a_world), 0.5 * (a_now + a_world), a_now)
    dt_a = jnp.where(late, f.arrival_time - t, 1.0)
    q = fb.q_tilt(walk2, imm.x(st.pos.imm, setup.pos)[0:3])
    pa = _sel(late, st.pos, st.pos_ahead)
    aa = _sel(late, st.att, st.att_ahead)
    pa, aa = _predict_pair(pa, aa, (late & st.pos.alive, late & st.att.alive), (dt_a, dt_a), setup, -u, q)
    st = st._replace(pos_ahead=pa, att_ahead=aa, has_ahead=st.has_ahead | late)
    R_out = jnp.where(late, R_now, R_wb)
    views = _views(setup, st, R_out)
    now_view, late_view = (tree_util.tree_map(lambda a, i=i: a[i], views) for i in (0, 1))
    st, outer, outer_num = _output(setup, st, go & ~late, now_view, st.pos, st.att, outer, outer_num)
    st, outer, outer_num = _output(setup, st, late, late_view, st.pos_ahead, st.att_ahead, outer, outer_num)
    # the held outputs of an active frame
    o = st.out
    valid = act & (outer == fr.OK)
    invalid = act & ~valid
    o = o._replace(
        valid=jnp.where(act, valid, o.valid),
        position=jnp.where(invalid, 0.0, o.position),
        euler=jnp.where(invalid, 0.0, o.euler),
        rotation=jnp.where(invalid, jnp.eye(3), o.rotation),
        residual=jnp.where(invalid, 0.0, o.residual),
        outer=jnp.where(act, outer, o.outer),
        outer_num=jnp.where(act, outer_num, o.outer_num),
        inner=jnp.where(act, inner, o.inner),
        inner_num=jnp.where(act, inner_num, o.inner_num),
        ihrcf_code=jnp.where(act, ihrcf_code, o.ihrcf_code),
        ihrcf_rms=jnp.where(act, ihrcf_rms, o.ihrcf_rms),
        atda_code=jnp.where(act, atda_code, o.atda_code),
        frame_time=jnp.where(act, f.time, o.frame_time),
    )
    vel, rate, okm = _motion(st, views)
    o = o._replace(
        velocity=jnp.where(act, vel, o.velocity),
        normal_rate=jnp.where(act, rate, o.normal_rate),
        motion_valid=jnp.where(act, okm, o.motion_valid),
    )
    return st._replace(out=o), other_pose
