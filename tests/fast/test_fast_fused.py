"""The fused filter (ihrcf_env.fast.fused) against BatchFused over the histories of
tests/core/test_batch_fused.py (held frames, resets, lost tags, outliers, bad IMU samples, late
frames), float64."""

from __future__ import annotations

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "core"))
from test_batch_fused import STEPS, history  # noqa: E402
from test_fused import RIG, TAG, K  # noqa: E402

from ihrcf_env.core.batch.fused import BatchFused  # noqa: E402
from ihrcf_env.core.batch.fused_frames import stack_atda_candidates, stack_frames  # noqa: E402
from ihrcf_env.core.calibration.tables import RangePixelTable  # noqa: E402
from ihrcf_env.core.estimators import FusedParams  # noqa: E402
from ihrcf_env.core.estimators.atda import atda_candidates  # noqa: E402
from ihrcf_env.fast.fused import FusedFrame, fused_init, fused_reset, fused_setup, fused_update  # noqa: E402
from ihrcf_env.fast.pnp import Candidates  # noqa: E402

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
FIELDS = ("position", "euler", "rotation", "residual", "velocity", "normal_rate")
CODES = ("valid", "outer", "inner", "ihrcf_code", "atda_code", "motion_valid")


def _frame(b) -> FusedFrame:
    return FusedFrame(
        b.time, b.detected, b.corners, b.ranges, b.ranges_valid, b.ranges_time, b.imu_present,
        b.quaternion, b.angular_velocity, b.specific_force, b.arrival_time, b.arrival_present,
        b.arrival_quaternion, b.arrival_angular_velocity, b.arrival_specific_force,
    )  # fmt: skip


#: Configurations whose compile is left to the slow run (``pytest -m slow``, in CI after the default run).
SLOW = ("options", "ihrcf_only")


@pytest.mark.parametrize(
    "config", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW else c for c in CONFIGS]
)
def test_fused_matches_batch_fused(config: str) -> None:
    params, Km = CONFIGS[config]
    n = 6
    hist = [history(e) for e in range(n)]
    ref = BatchFused(n, TABLE, RIG, TAG, Km, params=params)
    setup = fused_setup(TABLE, RIG, TAG, Km, params=params)
    traces = []

    def one(st, f, active, reset, cands):
        traces.append(1)
        st = fused_reset(setup, st, reset)
        return fused_update(setup, st, f, active, cands if Km is not None else None)

    step = jax.jit(jax.vmap(one))
    st = jax.vmap(lambda _: fused_init(setup))(jnp.arange(n))
    worst, valid_rows, outers = 0.0, 0, set()
    for k in range(STEPS):
        resets = np.array([k in hist[e][1] for e in range(n)])
        ref.reset(resets)
        row = [hist[e][0][k] for e in range(n)]
        active = np.array([f is not None for f in row])
        cands = stack_atda_candidates(
            [
                atda_candidates(f.corners, Km, None, TAG, RIG)
                if (f is not None and f.corners is not None and Km is not None)
                else "tag not found"
                for f in row
            ]
        )
        frames = stack_frames(row)
        out = ref.update(frames, active, cands)
        st = step(
            st,
            _frame(frames),
            active,
            resets,
            Candidates(cands.rotation, cands.position, cands.error, cands.usable, cands.code),
        )
        o = st.out
        for name in CODES:
            assert np.array_equal(np.asarray(getattr(o, name)), getattr(out, name)), (config, k, name)
        for name in FIELDS:
            d = float(np.max(np.abs(np.asarray(getattr(o, name)) - getattr(out, name))))
            worst = max(worst, d)
            assert d < 1e-8, (config, k, name, d)
        assert np.max(np.abs(np.exp(0.5 * np.asarray(st.log_var)) - ref.range_sigma)) < 1e-10
        valid_rows += int(out.valid.sum())
        outers.update(out.outer.tolist())
    print(f"{config}: max |fast - batched| = {worst:.3g} over {valid_rows} valid outputs")
    assert len(traces) == 1
    assert valid_rows > n * STEPS * 0.4
    assert len(outers) >= 5


def test_range_only_update_is_refused() -> None:
    with pytest.raises(ValueError, match="range_only_update"):
        fused_setup(TABLE, RIG, TAG, K, params=FusedParams(range_only_update=True))


def test_oscillator_deck_model_is_refused() -> None:
    with pytest.raises(ValueError, match="deck_model"):
        fused_setup(TABLE, RIG, TAG, K, params=FusedParams(deck_model="oscillator"))
