"""The velocity controller (ihrcf_env.fast.autopilot) against the simulator's numpy twin
(sim.batched.autopilot), float64, both loops (classic and wind-holding with the disturbance
observer): one control step within 1e-9 relative, and 1 s of closed-loop flight with the physics
tick within CLOSED_LOOP_TOL (the loop feeds rounding differences back for 240 steps; rotor speeds
are compared as thrusts, since a speed is the square root of a thrust, which magnifies the rounding
of a thrust near 0)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.vehicle import QuadParams, VelocityGains
from ihrcf_env.fast.autopilot import controller_reset, gains_of, velocity_control
from ihrcf_env.fast.dynamics import (
    DroneState,
    drone_params,
    hover_state,
    matrix_from_quaternion,
    quaternion_from_matrix,
    tick,
)
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor

from .fast_helpers import rel_err

QP = QuadParams()
P = drone_params(QP)
DT = 1.0 / 240.0
N = 64
STEPS = 240  # 1 s of flight
CLOSED_LOOP_TOL = 1e-8
GAINS = {False: VelocityGains(), True: dataclasses.replace(VelocityGains(), wind_hold=True)}


def _flight(wind_hold: bool):
    g = gains_of(GAINS[wind_hold])

    def one(pos0, yaw0, setpoints, force):
        st = hover_state(P, pos0, yaw0)
        ctl = controller_reset(P, pos0, yaw0)

        def body(carry, sp):
            s, c = carry
            q_rep = quaternion_from_matrix(matrix_from_quaternion(s.quaternion))
            R = matrix_from_quaternion(q_rep)
            c, cmd = velocity_control(c, sp, DT, s.position, q_rep, s.velocity, s.angular_velocity, P, g, R)
            s = tick(s, cmd, P, DT, None, force)
            return (s, c), None

        (s, c), _ = jax.lax.scan(body, (st, ctl), setpoints)
        return s, c

    return jax.jit(jax.vmap(one))


FLIGHT = {k: _flight(k) for k in (False, True)}


def reference(pos0, yaw0, setpoints, force, wind_hold: bool):
    quad = BatchedQuadrotor(QP, N)
    quad.reset(pos0, yaw0)
    ctl = BatchedVelocityController(QP, GAINS[wind_hold], N)
    ctl.reset(pos0, yaw0)
    for k in range(STEPS):
        quat, rot = quad.reported_quaternion(), quad.reported_rotation()
        cmd = ctl.compute(setpoints[:, k], DT, quad.position, quat, quad.velocity, quad.angular_velocity, rot)
        quad.step(cmd, DT, None, force)
    return quad, ctl


@pytest.mark.parametrize("wind_hold", [False, True])
def test_closed_loop_matches_numpy_twin(wind_hold: bool) -> None:
    rng = np.random.default_rng(int(wind_hold))
    pos0 = np.column_stack([rng.uniform(-1, 1, (N, 2)), rng.uniform(1, 3, N)])
    yaw0 = rng.uniform(-np.pi, np.pi, N)
    sp = np.repeat(rng.uniform(-1.5, 1.5, (N, 1, 4)), STEPS, axis=1)
    sp[:, STEPS // 2 :] *= -1.0  # a reversal half way
    sp[:4] *= 4.0  # hard commands: tilt limit and mixer saturation
    force = rng.normal(0, 3.0, (N, 3))  # steady side loads (the observer's job)
    s, c = FLIGHT[wind_hold](pos0, yaw0, sp, force)
    quad, ctl = reference(pos0, yaw0, sp, force, wind_hold)
    err = max(
        rel_err(s.position, quad.position),
        rel_err(s.velocity, quad.velocity),
        rel_err(s.quaternion, quad.quaternion),
        rel_err(s.angular_velocity, quad.angular_velocity),
        rel_err(QP.kf * np.asarray(s.rotor_speed) ** 2, QP.kf * quad.rotor_speed**2),
        rel_err(c.p_ref, ctl.p_ref),
        rel_err(c.integral, ctl.integral),
        rel_err(c.disturbance, ctl.disturbance),
    )
    assert err < CLOSED_LOOP_TOL, err
    assert isinstance(s, DroneState) and jnp.isfinite(s.position).all()


def _one_step(wind_hold: bool):
    g = gains_of(GAINS[wind_hold])

    def one(ctl, sp, pos, quat, vel, omega):
        return velocity_control(ctl, sp, DT, pos, quat, vel, omega, P, g)

    return jax.jit(jax.vmap(one))


STEP = {k: _one_step(k) for k in (False, True)}


@pytest.mark.parametrize("wind_hold", [False, True])
def test_one_step_matches_numpy_twin(wind_hold: bool) -> None:
    """Three control steps from random flight states and controller states (integrals,
    observer, leash pulled), outputs and states within 1e-9."""
    rng = np.random.default_rng(10 + int(wind_hold))
    ref = BatchedVelocityController(QP, GAINS[wind_hold], N)
    pos = rng.uniform(-1, 1, (N, 3)) + [0, 0, 2]
    ref.reset(pos + rng.normal(0, 0.4, (N, 3)), rng.uniform(-3, 3, N))
    ref.trim(rng.normal(0, 2.0, (N, 3)))
    ctl = controller_reset(P, np.zeros(3), 0.0)
    ctl = jax.tree.map(lambda a: np.broadcast_to(np.asarray(a), (N, *np.shape(a))).copy(), ctl)
    ctl = ctl._replace(
        p_ref=ref.p_ref.copy(),
        yaw_ref=ref.yaw_ref.copy(),
        integral=ref.integral.copy(),
        disturbance=ref.disturbance.copy(),
        v_prev=ref._v_prev.copy(),
        has_v_prev=ref._has_v_prev.copy(),
        thrust_model=ref._thrust_model.copy(),
        a_model=ref._a_model.copy(),
    )
    for _ in range(3):
        quat = Rotation.from_euler("ZYX", rng.uniform(-0.5, 0.5, (N, 3))).as_quat()
        vel, omega = rng.normal(0, 1, (N, 3)), rng.normal(0, 1, (N, 3))
        sp = rng.uniform(-2, 2, (N, 4))
        want = ref.compute(sp, DT, pos, quat, vel, omega)
        ctl, got = STEP[wind_hold](ctl, sp, pos, quat, vel, omega)
        assert rel_err(QP.kf * np.asarray(got) ** 2, QP.kf * want**2) < 1e-9
    assert rel_err(ctl.p_ref, ref.p_ref) < 1e-9
    assert rel_err(ctl.integral, ref.integral) < 1e-9
    assert rel_err(ctl.disturbance, ref.disturbance) < 1e-9
    assert rel_err(ctl.thrust_model, ref._thrust_model) < 1e-9
