"""The deck-motion forecaster (ihrcf_env.fast.forecast) against core.forecast.DeckForecaster and
the forecast block (ihrcf_env.fast.forecast_feed) against wrappers.forecast_feed.ForecastFeed,
float64: seeded ship records at the three levels' sea states, observed like a camera (irregular
times, noise, lost frames in bursts, a gap longer than max_gap)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.core.estimators import PoseEstimate
from ihrcf_env.core.forecast import DeckForecaster, ForecastOptions
from ihrcf_env.core.quiescence import QuiescenceThresholds
from ihrcf_env.core.ship import ship_profile
from ihrcf_env.fast import forecast as F
from ihrcf_env.fast import forecast_feed as FF
from ihrcf_env.fast.fused import FusedOutput
from ihrcf_env.wrappers.forecast_feed import ForecastFeed, forecast_fields

from .fast_helpers import Counted

SEAS = ((3, 30.0), (4, 30.0), (5, 40.0))  # calm, moderate, rough: sea state, length scale
DURATION = 65.0  # s
FLOORS = np.array([1e-3, 1e-2, 1e-4, 1e-4])  # m, m/s, rad, rad: relative errors below these are absolute


def _stream(seed: int, sea_state: int, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-like samples of a seeded ship record: times (n,), (n, 3) heave/roll/pitch with
    noise, validity (bursts of lost frames, a few non-finite channels, a 3.5 s gap)."""
    rng = np.random.default_rng([seed, 4040])
    prof = ship_profile(rng, {"sea_state": sea_state, "length_scale": scale})
    n = int(DURATION * 30)
    t = np.sort(np.arange(n) / 30.0 + rng.uniform(-0.004, 0.004, n))
    t -= t[0]
    off, rpy = prof.sample(t)
    y = np.column_stack([off[:, 2], rpy[:, 0], rpy[:, 1]])
    y += rng.normal(0.0, [0.015, math.radians(0.9), math.radians(0.9)], (n, 3))
    lost = np.zeros(n, bool)
    state = False
    for k, u in enumerate(rng.uniform(size=n)):
        state = (u >= 1 / 3) if state else (u < 0.1 / 3 / 0.9)
        lost[k] = state
    lost |= (t > 40.0) & (t < 43.5)  # longer than max_gap: the state resets
    y[rng.uniform(size=n) < 0.01, 1] = np.nan
    return t, y, ~lost


def _errors(mean: np.ndarray, std: np.ndarray, f_mean: np.ndarray, f_std: np.ndarray) -> float:
    e_m = np.abs(mean - f_mean) / np.maximum(np.abs(f_mean), FLOORS)
    e_s = np.abs(std - f_std) / np.maximum(np.abs(f_std), FLOORS)
    return float(max(e_m.max(), e_s.max()))


def _run_jax(prm: F.ForecastParams, t: np.ndarray, y: np.ndarray, v: np.ndarray):
    def run(t, y, v):
        def body(st, inp):
            st = F.forecast_update(prm, st, *inp)
            return st, F.forecast_out(prm, st)

        _, outs = jax.lax.scan(body, F.forecast_init(prm), (t, y, v))
        return outs

    return jax.jit(jax.vmap(run))(jnp.asarray(t), jnp.asarray(y), jnp.asarray(v))


@pytest.mark.parametrize("noise_std", [None, pytest.param((0.015, 0.016, 0.016), marks=pytest.mark.slow)])
def test_forecaster_matches_reference(noise_std):
    opts = ForecastOptions(noise_std=noise_std)
    streams = [_stream(i, *sea) for i, sea in enumerate(SEAS)]
    th = QuiescenceThresholds().scaled(35.0)
    prm = F.forecast_params(opts, th)
    n = min(s[0].size for s in streams)
    outs = _run_jax(prm, *(np.stack([s[i][:n] for s in streams]) for i in range(3)))
    worst, worst_q, fitted = 0.0, 0.0, 0
    for b, (t, y, v) in enumerate(streams):
        fc = DeckForecaster(opts)
        for k in range(n):
            fc.update(t[k], y[k], bool(v[k]))
            if k % 7 and k != n - 1:
                continue
            f = fc.forecast()
            assert bool(outs.valid[b, k]) == f.ready, (b, k)
            worst = max(
                worst, _errors(np.asarray(outs.mean[b, k]), np.asarray(outs.std[b, k]), f.mean, f.std)
            )
            worst_q = max(worst_q, abs(float(outs.quiet[b, k]) - fc.quiet_probability(th)))
            fitted += f.ready
    assert fitted > 3 * n // 7 // 2  # most of the record is forecast from a fitted model
    # the same equations, solved by Cholesky where the reference uses LU: rounding differences
    assert worst < 1e-8, worst
    assert worst_q < 1e-9, worst_q


def _feed_inputs(seed: int, steps: int):
    """A hovering drone over a rough deck: per control step (50 Hz) the time, navigation vertical
    velocity, whether a new camera frame arrived (30 Hz), the fused estimate (body frame) and the
    IMU's heading rotations."""
    rng = np.random.default_rng(seed)
    prof = ship_profile(rng, {"sea_state": 5, "length_scale": 40.0})
    t = np.arange(steps) * 0.02
    frame_idx = np.floor(t * 30.0 + 1e-9).astype(int)
    fresh = np.r_[True, np.diff(frame_idx) > 0]
    off, rpy = prof.sample(t)
    yaw = 0.3 + 0.2 * np.sin(0.1 * t)
    tilt = rng.normal(0.0, 0.03, (steps, 2))
    R_wb = Rotation.from_euler("ZYX", np.column_stack([yaw, tilt[:, 1], tilt[:, 0]])).as_matrix()
    R_wd = Rotation.from_euler("ZYX", np.column_stack([0.1 + rpy[:, 2], rpy[:, 1], rpy[:, 0]])).as_matrix()
    drone = np.array([0.1, -0.05, 2.0])
    pos = np.einsum("nji,nj->ni", R_wb, off - drone) + rng.normal(0.0, 0.01, (steps, 3))
    R_bd = np.einsum("nji,njk->nik", R_wb, R_wd)
    euler = Rotation.from_matrix(R_bd).as_euler("ZYX")[:, ::-1]
    valid = rng.uniform(size=steps) > 0.1
    vz = rng.normal(0.0, 0.01, steps)
    c, s = np.cos(yaw), np.sin(yaw)
    R_lw = np.zeros((steps, 3, 3))
    R_lw[:, 0, 0], R_lw[:, 0, 1], R_lw[:, 1, 0], R_lw[:, 1, 1], R_lw[:, 2, 2] = c, s, -s, c, 1.0
    R_lb = R_lw @ R_wb
    return t, vz, fresh, pos, euler, valid, R_lb, R_lw


def test_feed_block_matches_reference():
    steps = 1500  # 30 s
    t, vz, fresh, pos, euler, valid, R_lb, R_lw = _feed_inputs(3, steps)
    opts = ForecastOptions(horizons=(0.25, 1.0, 2.0))
    fp = FF.feed_params(opts, 40.0)
    ref = ForecastFeed(opts, 40.0)
    fields = forecast_fields(3)
    low = np.concatenate([np.full(f.size, f.low) for f in fields])
    high = np.concatenate([np.full(f.size, f.high) for f in fields])
    np.testing.assert_array_equal(fp.low, low)
    np.testing.assert_array_equal(fp.high, high)
    zero = jnp.zeros(())

    def run(t, vz, fresh, pos, euler, valid, R_lb, R_lw):
        def body(st, inp):
            tk, vk, fk, pk, ek, ok, lb, lw = inp
            fused = FusedOutput(*([zero] * len(FusedOutput._fields)))._replace(
                position=pk, euler=ek, valid=ok
            )
            st, out = FF.feed_step(fp, st, tk, vk, fk, fused, lb, lw)
            return st, out

        st, outs = jax.lax.scan(body, FF.feed_init(fp), (t, vz, fresh, pos, euler, valid, R_lb, R_lw))
        return st.samples, outs

    samples, outs = jax.jit(run)(t, vz, fresh, pos, euler, valid, R_lb, R_lw)
    frame = object()
    worst, n_valid = 0.0, 0
    for k in range(steps):
        if fresh[k]:
            frame = object()
        est = PoseEstimate(
            pos[k], euler[k], Rotation.from_euler("ZYX", euler[k, ::-1]).as_matrix(), bool(valid[k]), 0.0
        )
        block, info = ref.observe(t[k], vz[k], frame, est, R_lb[k], R_lw[k])
        want = np.clip(block, low, high)
        assert bool(outs.valid[k]) == info["valid"], k
        n_valid += info["valid"]
        worst = max(
            worst, float(np.max(np.abs(np.asarray(outs.block[k]) - want) / np.maximum(np.abs(want), 1.0)))
        )
    assert int(samples) == ref.samples
    assert n_valid > steps // 3
    assert worst < 1e-8, worst


def test_compiled_once():
    prm = F.forecast_params(ForecastOptions(window=20.0, order=8))
    upd = Counted(lambda st, t, y, v: F.forecast_update(prm, st, t, y, v))
    out = Counted(lambda st: F.forecast_out(prm, st))
    st = jax.vmap(lambda _: F.forecast_init(prm))(jnp.arange(2))
    for k in range(4):
        st = upd(st, jnp.full(2, 0.05 * k), jnp.ones((2, 3)) * k, jnp.ones(2, bool))
        res = out(st)
    assert upd.traces == 1 and out.traces == 1
    assert res.mean.shape == (2, 5, 4) and not bool(res.valid.any())
