"""The velocity controller (ihrcf_env.fast.autopilot) against the simulator's
(sim.drone.VelocityController, scalar), float64, both loops (classic and wind-holding with the
disturbance observer): three control steps from random flight and controller states within 1e-9
relative, and 1 s of closed-loop flight against the simulator's drone flown by PyBullet
(tests/fast/bullet_ref.py) within :data:`CLOSED_LOOP_TOL` (the loop feeds rounding differences
back for 240 steps; measured on x86-64: 1.1e-9, in the rotor thrusts). Rotor speeds are compared as thrusts,
since a speed is the square root of a thrust, which magnifies the rounding of a thrust near 0."""

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
from ihrcf_env.sim.drone import VelocityController

from .bullet_ref import DT, BulletDrone, controller_state, stack
from .fast_helpers import rel_err

QP = QuadParams()
P = drone_params(QP)
N = 64
STEPS = 240  # 1 s of flight
#: 1 s of closed-loop flight against PyBullet and the scalar controller (relative, floor 1).
CLOSED_LOOP_TOL = 1e-8
GAINS = {False: VelocityGains(), True: dataclasses.replace(VelocityGains(), wind_hold=True)}


def _flight(wind_hold: bool):
    g = gains_of(GAINS[wind_hold])

    def one(st, ctl, setpoints, force):
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
HOVER = jax.jit(jax.vmap(lambda p, y: hover_state(P, p, y)))
RESET = jax.jit(jax.vmap(lambda p, y: controller_reset(P, p, y)))
#: The orientation PyBullet reports for a quaternion state: through its matrix and back.
REPORTED = jax.jit(jax.vmap(lambda q: quaternion_from_matrix(matrix_from_quaternion(q))))


def reference(start: DroneState, yaw0, setpoints, force, wind_hold: bool):
    """Each drone flown by the simulator's controller and PyBullet from its hover state ``start``
    (heading ``yaw0``): the final states (as PyBullet reports them) and controllers."""
    drone = BulletDrone(QP)
    rows, ctls = [], []
    try:
        for i in range(N):
            drone.place(*(np.asarray(a[i]) for a in start))
            c = VelocityController(drone.quad, GAINS[wind_hold])
            c.reset(np.asarray(start.position[i]), float(yaw0[i]))
            for k in range(STEPS):
                pos, quat, vel, omega = drone.quad.state()
                cmd = c.compute(tuple(setpoints[i, k].tolist()), DT, pos, quat, vel, omega)
                drone.tick(cmd, None, force[i])
            rows.append(drone.state())
            ctls.append(c)
    finally:
        drone.close()
    return stack(rows), ctls


@pytest.mark.parametrize("wind_hold", [False, True])
def test_closed_loop_matches_pybullet(wind_hold: bool) -> None:
    rng = np.random.default_rng(int(wind_hold))
    pos0 = np.column_stack([rng.uniform(-1, 1, (N, 2)), rng.uniform(1, 3, N)])
    yaw0 = rng.uniform(-np.pi, np.pi, N)
    sp = np.repeat(rng.uniform(-1.5, 1.5, (N, 1, 4)), STEPS, axis=1)
    sp[:, STEPS // 2 :] *= -1.0  # a reversal half way
    sp[:4] *= 4.0  # hard commands: tilt limit and mixer saturation
    force = rng.normal(0, 3.0, (N, 3))  # steady side loads (the observer's job)
    start = jax.tree.map(np.asarray, HOVER(pos0, yaw0))
    s, c = FLIGHT[wind_hold](start, RESET(pos0, yaw0), sp, force)
    want, ctls = reference(start, yaw0, sp, force, wind_hold)
    ref = jax.tree.map(lambda *a: np.stack(a), *(controller_state(k) for k in ctls))
    err = max(
        rel_err(s.position, want["position"]),
        rel_err(s.velocity, want["velocity"]),
        rel_err(REPORTED(s.quaternion), want["quaternion"]),
        rel_err(s.angular_velocity, want["angular_velocity"]),
        rel_err(QP.kf * np.asarray(s.rotor_speed) ** 2, QP.kf * want["rotor_speed"] ** 2),
        rel_err(c.p_ref, ref.p_ref),
        rel_err(c.integral, ref.integral),
        rel_err(c.disturbance, ref.disturbance),
    )
    print(f"1 s closed loop (wind_hold={wind_hold}): max relative |JAX - PyBullet| = {err:.3g}")
    assert err < CLOSED_LOOP_TOL, err
    assert np.abs(want["position"] - pos0).max() > 0.5  # the drones flew
    assert isinstance(s, DroneState) and jnp.isfinite(s.position).all()


def _one_step(wind_hold: bool):
    g = gains_of(GAINS[wind_hold])

    def one(ctl, sp, pos, quat, vel, omega):
        return velocity_control(ctl, sp, DT, pos, quat, vel, omega, P, g)

    return jax.jit(jax.vmap(one))


STEP = {k: _one_step(k) for k in (False, True)}


@pytest.mark.parametrize("wind_hold", [False, True])
def test_one_step_matches_the_simulators_controller(wind_hold: bool) -> None:
    """Three control steps from random flight states and controller states (integrals,
    observer, leash pulled), outputs and states within 1e-9 of the scalar controller's."""
    rng = np.random.default_rng(10 + int(wind_hold))
    pos = rng.uniform(-1, 1, (N, 3)) + [0, 0, 2]
    held = pos + rng.normal(0, 0.4, (N, 3))
    yaw = rng.uniform(-3, 3, N)
    acc = rng.normal(0, 2.0, (N, 3))
    drone = BulletDrone(QP)
    try:
        ref = [VelocityController(drone.quad, GAINS[wind_hold]) for _ in range(N)]
        for i, c in enumerate(ref):
            c.reset(held[i], float(yaw[i]))
            c.trim(acc[i])
        ctl = jax.tree.map(lambda *a: np.stack(a), *(controller_state(c) for c in ref))
        for _ in range(3):
            quat = Rotation.from_euler("ZYX", rng.uniform(-0.5, 0.5, (N, 3))).as_quat()
            vel, omega = rng.normal(0, 1, (N, 3)), rng.normal(0, 1, (N, 3))
            sp = rng.uniform(-2, 2, (N, 4))
            want = np.array(
                [
                    c.compute(tuple(sp[i]), DT, tuple(pos[i]), tuple(quat[i]), tuple(vel[i]), tuple(omega[i]))
                    for i, c in enumerate(ref)
                ]
            )
            ctl, got = STEP[wind_hold](ctl, sp, pos, quat, vel, omega)
            assert rel_err(QP.kf * np.asarray(got) ** 2, QP.kf * want**2) < 1e-9
    finally:
        drone.close()
    want_state = jax.tree.map(lambda *a: np.stack(a), *(controller_state(c) for c in ref))
    assert rel_err(ctl.p_ref, want_state.p_ref) < 1e-9
    assert rel_err(ctl.integral, want_state.integral) < 1e-9
    assert rel_err(ctl.disturbance, want_state.disturbance) < 1e-9
    assert rel_err(ctl.thrust_model, want_state.thrust_model) < 1e-9
    assert rel_err(ctl.yaw_ref, want_state.yaw_ref) < 1e-9
