"""The numpy free-flight dynamics (ihrcf_env.sim.batched) against PyBullet: the same rotor commands,
ground-effect factors and wind forces, open loop and closed loop (the scalar VelocityController
flying both), give the same trajectory. The numpy step reproduces Bullet's btMultiBody scheme and
rounding, so the trajectories agree to the last bits; the bounds leave room for another PyBullet
build's floating-point contraction, and a wrong integrator (explicit Euler) is shown to exceed them."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.vehicle import QuadParams, VelocityGains
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.batched import integrator
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor
from ihrcf_env.sim.batched.floatmath import matrices_from_quaternions, quaternions_from_matrices
from ihrcf_env.sim.drone import Quadrotor, VelocityController

DT = 1.0 / 240
#: m and rotation-matrix elements: agreement required between PyBullet and numpy
BOUND = 1e-9


@pytest.fixture()
def bullet():
    cid = p.connect(p.DIRECT)
    p.setGravity(0, 0, -GRAVITY, physicsClientId=cid)
    p.setTimeStep(DT, physicsClientId=cid)
    try:
        yield cid
    finally:
        p.disconnect(cid)


def _wind(t: float) -> tuple[float, float, float]:
    """A steady wind force plus gusts (N, world)."""
    return (2.0 + 1.5 * math.sin(1.3 * t), -1.0 + 0.8 * math.cos(2.1 * t), 0.4 * math.sin(5.0 * t))


def _scale(t: float) -> list[float]:
    """Per-rotor thrust factors (ground-effect-like, >= 1)."""
    return [1.0 + 0.08 * (1.0 + math.sin(0.7 * t + i)) for i in range(4)]


def _fly(cid, seconds, closed_loop, start=(0.3, -0.2, 5.0), yaw=0.7):
    """Fly PyBullet and numpy side by side; return the largest position and rotation differences."""
    params = QuadParams()
    quad = Quadrotor(cid, params)
    quad.reset(np.array(start), yaw)
    bq = BatchedQuadrotor(params, 1)
    bq.reset(start, yaw)
    gains = VelocityGains(wind_hold=True)
    ctrl_pb, ctrl_np = VelocityController(quad, gains), VelocityController(quad, gains)
    for c in (ctrl_pb, ctrl_np):
        c.reset(np.array(start), yaw)
    w_hover = float(bq.rotor_speed[0, 0])
    dpos = drot = 0.0
    for k in range(int(round(seconds / DT))):
        t = k * DT
        wind, scale = _wind(t), _scale(t)
        pos, quat, vel, omega = quad.state()
        q_np = bq.reported_quaternion()[0]
        if closed_loop:
            sp = (1.5 * math.sin(0.9 * t), 1.0 * math.cos(0.6 * t), 0.3 * math.sin(0.4 * t), 0.5)
            cmd = ctrl_pb.compute(sp, DT, pos, quat, vel, omega)
            cmd_np = ctrl_np.compute(
                sp,
                DT,
                tuple(bq.position[0]),
                tuple(q_np),
                tuple(bq.velocity[0]),
                tuple(bq.angular_velocity[0]),
            )
        else:
            cmd = cmd_np = [w_hover * (1.0 + 0.04 * math.sin(3.0 * t + i) + 0.01 * i) for i in range(4)]
        quad.apply(cmd, DT, pos, quat, vel, thrust_scale=scale)
        p.applyExternalForce(quad.body, -1, wind, pos, p.WORLD_FRAME, physicsClientId=cid)
        p.stepSimulation(physicsClientId=cid)
        bq.step(np.array([cmd_np]), DT, thrust_scale=np.array([scale]), force=np.array([wind]))
        pos, quat, _, _ = quad.state()
        dpos = max(dpos, float(np.abs(np.asarray(pos) - bq.position[0]).max()))
        r_pb = np.asarray(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        drot = max(drot, float(np.abs(r_pb - matrices_from_quaternions(bq.quaternion)[0]).max()))
    return dpos, drot, np.asarray(pos)


def test_open_loop_matches_pybullet(bullet):
    dpos, drot, pos = _fly(bullet, 3.0, closed_loop=False)
    assert np.abs(pos - (0.3, -0.2, 5.0)).max() > 1.0  # it tumbled away: the test is not trivial
    assert dpos <= BOUND and drot <= BOUND, (dpos, drot)


def test_closed_loop_matches_pybullet(bullet):
    dpos, drot, _ = _fly(bullet, 4.0, closed_loop=True)
    assert dpos <= BOUND and drot <= BOUND, (dpos, drot)


def test_explicit_euler_would_fail(bullet, monkeypatch):
    """The bound catches a wrong scheme: positions from the old velocity (explicit Euler)."""
    real = integrator.bullet_step

    def explicit(position, quaternion, velocity, angular_velocity, *args, **kwargs):
        v_old = velocity.copy()
        real(position, quaternion, velocity, angular_velocity, *args, **kwargs)
        position += DT * (v_old - velocity)

    monkeypatch.setattr("ihrcf_env.sim.batched.dynamics.bullet_step", explicit)
    dpos, _, _ = _fly(bullet, 1.0, closed_loop=False)
    assert dpos > 1e-6


def test_reported_pose_equals_pybullet_after_reset(bullet):
    params = QuadParams()
    quad = Quadrotor(bullet, params)
    bq = BatchedQuadrotor(params, 4)
    yaws = [0.0, 1.0, -2.5, math.pi]
    bq.reset([[0, 0, 1], [1, 2, 3], [-1, 0, 2], [0, 5, 1]], yaws, hover=False)
    for i, yaw in enumerate(yaws):
        quad.reset(bq.position[i], yaw, hover=False)
        pos, quat, vel, omega = quad.state()
        assert np.array_equal(pos, bq.position[i]) and np.array_equal(quat, bq.reported_quaternion()[i])
    assert np.array_equal(bq.rotor_speed, np.zeros((4, 4)))


def test_velocity_clamp_as_bullet(bullet):
    """Bullet clamps every world velocity component to +-100 (m/s, rad/s)."""
    params = QuadParams()
    quad = Quadrotor(bullet, params)
    quad.reset(np.zeros(3), 0.0, hover=False)
    bq = BatchedQuadrotor(params, 1)
    bq.reset(np.zeros(3), 0.0, hover=False)
    push = (3000.0, -2500.0, 200.0)
    for _ in range(40):
        pos, quat, vel, _ = quad.state()
        quad.apply([0.0] * 4, DT, pos, quat, vel)  # drag only
        p.applyExternalForce(quad.body, -1, push, pos, p.WORLD_FRAME, physicsClientId=bullet)
        p.stepSimulation(physicsClientId=bullet)
        bq.step(np.zeros((1, 4)), DT, force=np.array([push]))
    _, _, vel, _ = quad.state()
    assert max(abs(v) for v in vel[:2]) == 100.0
    assert np.array_equal(vel, bq.velocity[0])


def test_rows_do_not_depend_on_n():
    rng = np.random.default_rng(2)
    params = QuadParams()
    n = 8
    batch = BatchedQuadrotor(params, n)
    batch.reset(rng.normal(size=(n, 3)), rng.uniform(-3, 3, n))
    singles = [BatchedQuadrotor(params, 1) for _ in range(n)]
    for i, s in enumerate(singles):
        s.reset(batch.position[i], 0.0)
        s.quaternion[:] = batch.quaternion[i]
        s.invalidate()
    for _ in range(100):
        cmd = rng.uniform(300.0, 900.0, (n, 4))
        scale = rng.uniform(1.0, 1.3, (n, 4))
        force = rng.normal(size=(n, 3))
        batch.step(cmd, DT, scale, force)
        for i, s in enumerate(singles):
            s.step(cmd[i : i + 1], DT, scale[i : i + 1], force[i : i + 1])
    for i, s in enumerate(singles):
        for name in ("position", "quaternion", "velocity", "angular_velocity", "rotor_speed"):
            assert np.array_equal(getattr(s, name)[0], getattr(batch, name)[i]), name


def test_reported_orientation_any_rotation(bullet):
    """PyBullet reports a body's orientation through a rotation matrix (Shepperd's method): the
    same bits for random rotations, every branch (rotations beyond 120 degrees included)."""
    quad = Quadrotor(bullet, QuadParams())
    rng = np.random.default_rng(4)
    q = rng.normal(size=(300, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ours = quaternions_from_matrices(matrices_from_quaternions(q))
    m = matrices_from_quaternions(q)
    assert (np.trace(m, axis1=1, axis2=2) <= 0).sum() > 50
    for i in range(q.shape[0]):
        p.resetBasePositionAndOrientation(quad.body, [0, 0, 1], q[i].tolist(), physicsClientId=bullet)
        _, reported = p.getBasePositionAndOrientation(quad.body, physicsClientId=bullet)
        assert np.array_equal(reported, ours[i]), i
