"""The batched autopilot (ihrcf_env.sim.batched) against the scalar VelocityController: each row
equals the scalar controller's output bit for bit over sequences of steps (so the integrals, the
disturbance observer, the yaw reference and the tilt-limit memory are exercised), whatever N."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.vehicle import QuadParams, VelocityGains
from ihrcf_env.sim import drone
from ihrcf_env.sim.batched import autopilot as batched_autopilot
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.sim.batched.floatmath import atan2, hypot2, hypot_over, remainder, yaw_quaternions
from ihrcf_env.sim.batched.mixer import BatchedMixer
from ihrcf_env.sim.drone import Quadrotor, VelocityController

DT = 1.0 / 240


@pytest.fixture(scope="module")
def quad():
    cid = p.connect(p.DIRECT)
    try:
        yield Quadrotor(cid, QuadParams())
    finally:
        p.disconnect(cid)


def _inputs(rng, ctrl, n):
    """One step's inputs for N rows: 'calm' rows near the held pose and heading (mixer unsaturated),
    'rough' rows with random attitudes, rates and large set-points (tilt limit, mixer saturated)."""
    calm = rng.uniform(size=n) < 0.5
    sp = rng.normal(size=(n, 4)) * np.array([2.0, 2.0, 1.0, 1.0])
    sp[calm] *= 0.05
    sp[rng.uniform(size=n) < 0.15] *= 8.0
    pos = ctrl.p_ref + rng.normal(size=(n, 3)) * np.where(calm, 0.02, 0.4)[:, None]
    vel = rng.normal(size=(n, 3)) * np.where(calm, 0.05, 3.0)[:, None]
    q = rng.normal(size=(n, 4))
    level = yaw_quaternions(ctrl.yaw_ref + rng.normal(size=n) * 0.01)
    tilt = rng.normal(size=(n, 4)) * 0.01
    q[calm] = level[calm] + tilt[calm]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    omega = rng.normal(size=(n, 3)) * np.where(calm, 0.02, 3.0)[:, None]
    return sp, pos, q, vel, omega


def _scalar_row(c, sp, pos, q, vel, omega, i):
    return c.compute(tuple(sp[i]), DT, tuple(pos[i]), tuple(q[i]), tuple(vel[i]), tuple(omega[i]))


@pytest.mark.parametrize("wind_hold", [False, True])
@pytest.mark.parametrize("n", [1, 64])
def test_rows_equal_the_scalar_controller(quad, wind_hold, n):
    rng = np.random.default_rng(7 + n + wind_hold)
    params, gains = quad.params, VelocityGains(wind_hold=wind_hold)
    steps = 40 if n > 1 else 300
    scalar = [VelocityController(quad, gains) for _ in range(n)]
    batch = BatchedVelocityController(params, gains, n)
    p0, yaw0 = rng.normal(size=(n, 3)), rng.uniform(-3.0, 3.0, n)
    acc = rng.normal(size=(n, 3)) * np.where(rng.uniform(size=n) < 0.3, 5.0, 1.0)[:, None]
    for i, c in enumerate(scalar):
        c.reset(p0[i], yaw0[i])
        c.trim(acc[i])
    batch.reset(p0, yaw0)
    batch.trim(acc)
    clipped = mixer_saturated = unsaturated = 0
    for _ in range(steps):
        sp, pos, q, vel, omega = _inputs(rng, batch, n)
        out = batch.compute(sp, DT, pos, q, vel, omega)
        ref = np.array([_scalar_row(c, sp, pos, q, vel, omega, i) for i, c in enumerate(scalar)])
        np.testing.assert_allclose(out, ref, rtol=0.0, atol=1e-12)
        assert np.array_equal(out, ref)
        assert np.array_equal(batch.p_ref, [c.p_ref for c in scalar])
        assert np.array_equal(batch.integral, [c.integral for c in scalar])
        assert np.array_equal(batch.disturbance, [c.disturbance for c in scalar])
        assert np.array_equal(batch.yaw_ref, [c.yaw_ref for c in scalar])
        clipped += int(sum(c._saturated for c in scalar))
        at_limit = (ref >= params.max_rotor_speed * (1 - 1e-12)) | (ref == 0.0)
        mixer_saturated += int(at_limit.any(axis=1).sum())
        unsaturated += int((~at_limit.any(axis=1)).sum())
    # the sequences reached the branches under test
    assert mixer_saturated > 0 and unsaturated > 0
    if wind_hold:
        assert clipped > 0


def test_rows_do_not_depend_on_n(quad):
    """Row i of a 64-batch equals the same inputs run at N = 1, bit for bit."""
    rng = np.random.default_rng(3)
    params, gains = quad.params, VelocityGains(wind_hold=True)
    n, steps = 64, 30
    batch = BatchedVelocityController(params, gains, n)
    singles = [BatchedVelocityController(params, gains, 1) for _ in range(n)]
    p0, yaw0, acc = rng.normal(size=(n, 3)), rng.uniform(-3, 3, n), rng.normal(size=(n, 3)) * 4
    batch.reset(p0, yaw0)
    batch.trim(acc)
    for i, s in enumerate(singles):
        s.reset(p0[i], yaw0[i])
        s.trim(acc[i])
    for _ in range(steps):
        sp, pos, q, vel, omega = _inputs(rng, batch, n)
        out = batch.compute(sp, DT, pos, q, vel, omega)
        for i, s in enumerate(singles):
            row = s.compute(sp[i : i + 1], DT, pos[i : i + 1], q[i : i + 1], vel[i : i + 1], omega[i : i + 1])
            assert np.array_equal(row[0], out[i])
            assert np.array_equal(s.disturbance[0], batch.disturbance[i])


def test_reset_and_trim_rows_only(quad):
    params, gains = quad.params, VelocityGains(wind_hold=True)
    b = BatchedVelocityController(params, gains, 3)
    b.trim(np.array([1.0, -2.0, 0.5]))
    before = b.disturbance.copy()
    b.reset(np.array([[1.0, 2.0, 3.0]]), 0.5, rows=[1])
    assert np.array_equal(b.disturbance[[0, 2]], before[[0, 2]])
    assert np.array_equal(b.disturbance[1], [0.0, 0.0])
    assert np.array_equal(b.p_ref[1], [1.0, 2.0, 3.0]) and b.yaw_ref[1] == 0.5
    with pytest.raises(ValueError, match="n must be"):
        BatchedVelocityController(params, gains, 0)


def test_mixer_equals_wrench_to_speeds(quad):
    rng = np.random.default_rng(11)
    n = 2000
    thrust = rng.uniform(-5.0, 30.0, n)
    torque = rng.normal(size=(n, 3)) * np.array([1.0, 1.0, 0.2]) * rng.choice([0.01, 1.0, 5.0], (n, 1))
    out = BatchedMixer(quad.params).speeds(thrust, torque[:, 0], torque[:, 1], torque[:, 2])
    ref = np.array([quad.wrench_to_speeds(float(t), tuple(q)) for t, q in zip(thrust, torque, strict=True)])
    assert np.array_equal(out, ref)


def test_float_helpers_match_python_math():
    rng = np.random.default_rng(5)
    x = rng.normal(size=20000) * rng.choice([1e-6, 1.0, 1e4], 20000)
    y = rng.normal(size=20000) * rng.choice([0.0, 1e-9, 1.0, 10.0], 20000)
    assert np.array_equal(hypot2(x, y), [math.hypot(a, b) for a, b in zip(x, y, strict=True)])
    r = rng.uniform(-40.0, 40.0, 20000)
    r[:4] = [math.pi, -math.pi, 3 * math.pi, -0.0]
    ref = np.array([math.remainder(v, 2 * math.pi) for v in r])
    got = remainder(r, 2 * math.pi)
    assert np.array_equal(got, ref) and np.array_equal(np.signbit(got), np.signbit(ref))


def test_constants_and_no_pybullet():
    assert batched_autopilot.CLASSIC_I_CLAMP == drone.CLASSIC_I_CLAMP
    code = (
        "import sys, ihrcf_env.sim.batched.autopilot, ihrcf_env.sim.batched.dynamics; "
        "assert 'pybullet' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).resolve().parents[2])


def test_hypot_over_decides_as_math_hypot():
    """Limits at the exact hypot and one ulp either side: the comparison is math.hypot's."""
    rng = np.random.default_rng(9)
    x, y = rng.normal(size=3000), rng.normal(size=3000)
    h = np.array([math.hypot(a, b) for a, b in zip(x, y, strict=True)])
    for lim in (h, np.nextafter(h, 0.0), np.nextafter(h, 10.0), h * 2.0, h * 0.5):
        over, got = hypot_over(x, y, lim)
        assert np.array_equal(over, h > lim)
        assert np.array_equal(got[over], h[over])
    assert hypot_over(np.array([1e-170]), np.array([0.0]), 0.0)[0][0]


def test_atan2_is_math_atan2_on_this_cpu():
    """Quadrants, axes, signed zeros and wide magnitudes: the same bits as ``math.atan2`` (numpy's
    SIMD ``arctan2`` on AVX-512 CPUs is not)."""
    rng = np.random.default_rng(11)
    y = np.concatenate([rng.normal(size=5000) * 10.0 ** rng.integers(-8, 8, 5000), [0.0, -0.0, 1.0, -1.0]])
    x = np.concatenate([rng.normal(size=5000) * 10.0 ** rng.integers(-8, 8, 5000), [-0.0, 0.0, 0.0, -0.0]])
    ref = np.array([math.atan2(a, b) for a, b in zip(y, x, strict=True)])
    got = atan2(y, x)
    assert got.dtype == np.float64 and got.shape == y.shape
    assert np.array_equal(got.view(np.int64), ref.view(np.int64))
    assert atan2(np.ones((2, 3)), np.ones((2, 3))).shape == (2, 3)
