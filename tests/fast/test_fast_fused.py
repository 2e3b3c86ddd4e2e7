"""The fused filter (ihrcf_env.fast.fused) against the single filter
(ihrcf_env.core.estimators.fused.FusedEstimator), env by env, over the histories of
tests/core/fused_history.py (held frames, resets, lost tags, outliers, bad IMU samples, late
frames), float64: the same validity and reason text (the codes' text), the outputs within 1e-8;
IHRCF's estimate made in the filter's IHRCF call (``fused_update_with_ihrcf``) is IHRCF's own."""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "core"))
from fused_history import STEPS, history  # noqa: E402
from test_fused import RIG, TAG, K  # noqa: E402

from ihrcf_env.core.calibration.tables import RangePixelTable  # noqa: E402
from ihrcf_env.core.estimators import FusedEstimator, FusedParams, SensorFrame  # noqa: E402
from ihrcf_env.core.estimators import fused_reasons as fr  # noqa: E402
from ihrcf_env.core.estimators import reasons as rs  # noqa: E402
from ihrcf_env.core.estimators.atda import Candidate, atda_candidates  # noqa: E402
from ihrcf_env.fast.fused import (  # noqa: E402
    FusedFrame,
    fused_init,
    fused_reset,
    fused_setup,
    fused_update,
    fused_update_with_ihrcf,
)
from ihrcf_env.fast.ihrcf import ihrcf  # noqa: E402
from ihrcf_env.fast.pnp import Candidates  # noqa: E402

MAX_RESIDUAL = 0.01  # fused_setup's and FusedEstimator's default
XY = RIG.sensor_xy_cam


def _table() -> RangePixelTable:
    d = np.linspace(0.2, 4.0, 120)
    u = K[0, 0] * XY[:, 0] / d[:, None] + K[0, 2]
    v = K[1, 1] * XY[:, 1] / d[:, None] + K[1, 2]
    return RangePixelTable.from_samples(np.tile(d[:, None], 4), np.stack([u, v], axis=2))


TABLE = _table()
CONFIGS = {
    "default": (FusedParams(), K),
    "options": (
        FusedParams(accel_hold="trapezoid", range_offset_sigma=0.003, refit=False, max_rejections=3),
        K,
    ),
    "ihrcf_only": (FusedParams(use_atda_position=False), None),
    "v2": (FusedParams(reseed_agreeing=True, range_offset_sigma=0.00125, drop_lost_track=True), K),
}


def stack(frames: Sequence[SensorFrame | None]) -> tuple[FusedFrame, list[str]]:
    """The :class:`FusedFrame` arrays of one frame per env (None: the env is not stepped) and the
    frames' reasons for an undetected tag."""
    n = len(frames)
    time, ranges_time, arrival_time = np.full(n, math.nan), np.full(n, math.nan), np.full(n, math.nan)
    detected, corners = np.zeros(n, bool), np.zeros((n, 4, 2))
    ranges, valid = np.zeros((n, 4)), np.zeros((n, 4), bool)
    imu_p, arr_p = np.zeros(n, bool), np.zeros(n, bool)
    q, w, f = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))
    aq, aw, af = q.copy(), w.copy(), f.copy()
    reasons = [rs.REASONS[rs.NOT_DETECTED]] * n
    for k, x in enumerate(frames):
        if x is None:
            continue
        time[k], ranges_time[k], arrival_time[k] = x.time, x.ranges_time, x.arrival_time
        if x.corners is not None:
            detected[k], corners[k] = True, x.corners
        reasons[k] = x.corners_reason if x.corners is None else ""
        ranges[k], valid[k] = x.ranges, x.ranges_valid
        if x.imu is not None:
            imu_p[k] = True
            q[k], w[k], f[k] = x.imu.quaternion, x.imu.angular_velocity, x.imu.specific_force
        if x.arrival_imu is not None:
            arr_p[k] = True
            a = x.arrival_imu
            aq[k], aw[k], af[k] = a.quaternion, a.angular_velocity, a.specific_force
    frame = FusedFrame(
        time, detected, corners, ranges, valid, ranges_time, imu_p, q, w, f, arrival_time, arr_p, aq, aw, af
    )
    return frame, reasons


def candidates(results: Sequence[list[Candidate] | str]) -> Candidates:
    """ATDA's candidates (atda_candidates: up to two, or the reason there are none) as arrays: the
    JAX filter then chooses among the single ATDA's own poses."""
    n = len(results)
    rot, pos = np.tile(np.eye(3), (n, 2, 1, 1)), np.zeros((n, 2, 3))
    err, usable, code = np.full((n, 2), np.inf), np.zeros((n, 2), bool), np.zeros(n, np.int8)
    for k, res in enumerate(results):
        if isinstance(res, str):
            code[k] = rs.REASONS.index(res)
            continue
        for s, (e, R, p) in enumerate(res[:2]):
            err[k, s], rot[k, s], pos[k, s], usable[k, s] = e, R, p, True
    return Candidates(rot, pos, err, usable, code)


def reason(o, e: int, corners_reason: str, params: FusedParams) -> str:
    """The reason text of env ``e``'s output ``o`` (its codes and numbers, the frame's reason for an
    undetected tag), written with the templates of ihrcf_env.core.estimators.fused_reasons."""
    c = int(o.outer[e])
    if c == fr.OK:
        return ""
    ic, a = int(o.inner[e]), int(o.atda_code[e])
    ihrcf = rs.reason_text(int(o.ihrcf_code[e]), float(o.ihrcf_rms[e]), MAX_RESIDUAL)
    inner = fr.INNER[ic].format(
        corners=corners_reason,
        t=float(o.inner_num[e]),
        timeout=params.lost_timeout,
        ihrcf=ihrcf if ic in (fr.BOTH_FAILED, fr.IHRCF_FAILED) else "",
        atda="ATDA not used" if a == fr.ATDA_NOT_USED else rs.REASONS[a],
    )
    if c in (fr.NOT_INITIALISED, fr.POSITION_NOT_INITIALISED):
        return fr.OUTER[c].format(inner=inner or "no measurement yet")
    x, y = (float(v) for v in o.outer_num[e])
    text = fr.OUTER[c].format(a=x, b=y)
    if c in (fr.CONVERGING_UPDATES, fr.CONVERGING_POSITION, fr.CONVERGING_ANGLE) and inner:
        text += f" ({inner})"
    return text


#: Configurations whose compile is left to the slow run (``pytest -m slow``, in CI after the default run).
SLOW = ("options", "ihrcf_only")


@pytest.mark.parametrize(
    "config", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW else c for c in CONFIGS]
)
def test_fused_matches_the_single_filters(config: str) -> None:
    params, Km = CONFIGS[config]
    n = 6
    hist = [history(e) for e in range(n)]
    singles = [FusedEstimator(TABLE, RIG, TAG, Km, params=params) for _ in range(n)]
    setup = fused_setup(TABLE, RIG, TAG, Km, params=params)
    traces = []

    def one(st, f, active, reset, cands):
        traces.append(1)
        st = fused_reset(setup, st, reset)
        c = cands if Km is not None else None
        # the frame's IHRCF estimate on the raw ranges, beside the filter's on its compensated ones
        st, pose = fused_update_with_ihrcf(setup, st, f, active, c, f.ranges, f.ranges_valid, f.detected)
        return st, pose, ihrcf(f.corners, f.ranges, f.ranges_valid, f.detected, setup.ihrcf)

    step = jax.jit(jax.vmap(one))
    st = jax.vmap(lambda _: fused_init(setup))(jnp.arange(n))
    worst, valid_rows, outers, reasons_seen = 0.0, 0, set(), set()
    for k in range(STEPS):
        resets = np.array([k in hist[e][1] for e in range(n)])
        for e in np.flatnonzero(resets):
            singles[e].reset()
        row = [hist[e][0][k] for e in range(n)]
        active = np.array([f is not None for f in row])
        cands = [
            atda_candidates(f.corners, Km, None, TAG, RIG)
            if (f is not None and f.corners is not None and Km is not None)
            else rs.REASONS[rs.NOT_DETECTED]
            for f in row
        ]
        frame, corners_reason = stack(row)
        st, pose, own = step(st, frame, active, resets, candidates(cands))
        for got, want in zip(pose, own, strict=True):
            np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=0, atol=1e-12)
        o = jax.tree_util.tree_map(np.asarray, st.out)
        sigma = np.exp(0.5 * np.asarray(st.log_var))
        for e in np.flatnonzero(active):
            s = singles[e].update(row[e])
            assert s.valid == bool(o.valid[e]), (config, k, e, s.reason)
            assert s.reason == reason(o, e, corners_reason[e], params), (config, k, e)
            reasons_seen.add(s.reason)
            diff = max(
                float(np.max(np.abs(s.position - o.position[e]))),
                float(np.max(np.abs(s.euler - o.euler[e]))),
                float(np.max(np.abs(s.rotation - o.rotation[e]))),
                abs(s.residual - float(o.residual[e])),
            )
            m = singles[e].motion()
            assert (m is not None) == bool(o.motion_valid[e]), (config, k, e)
            if m is not None:
                diff = max(
                    diff,
                    float(np.max(np.abs(m[0] - o.velocity[e]))),
                    float(np.max(np.abs(m[1] - o.normal_rate[e]))),
                )
            assert diff < 1e-8, (config, k, e, diff)
            worst = max(worst, diff)
            assert abs(sigma[e] - singles[e].range_sigma) < 1e-10
            valid_rows += s.valid
            outers.add(int(o.outer[e]))
    print(f"{config}: max |fast - single| = {worst:.3g} over {valid_rows} valid outputs")
    assert len(traces) == 1
    assert valid_rows > n * STEPS * 0.4
    assert len(outers) >= 5
    text = " | ".join(reasons_seen)
    for part in ("tag lost for", "tag occluded", "time went backwards", "converging: ", "not initialised"):
        assert part in text, part


def test_range_only_update_is_refused() -> None:
    with pytest.raises(ValueError, match="range_only_update"):
        fused_setup(TABLE, RIG, TAG, K, params=FusedParams(range_only_update=True))


def test_oscillator_deck_model_is_refused() -> None:
    with pytest.raises(ValueError, match="deck_model"):
        fused_setup(TABLE, RIG, TAG, K, params=FusedParams(deck_model="oscillator"))


def test_banks_of_different_model_counts_are_predicted_one_by_one() -> None:
    """Position and attitude banks of different model counts (no shared bank axis) still step."""
    setup = fused_setup(TABLE, RIG, TAG, K, params=FusedParams(accel_drift=(0.001, 0.1)))
    assert setup.pos.drifts.shape[0] == 2 and setup.att.drifts.shape[0] == 3
    frame, _ = stack([history(0)[0][k] for k in range(1)])
    one = jax.tree_util.tree_map(lambda a: a[0], frame)
    out = jax.eval_shape(lambda st: fused_update(setup, st, one, jnp.ones((), bool)), fused_init(setup))
    assert out.pos.imm.X.shape == (2, 9) and out.att.imm.X.shape == (3, 9)
