"""The physics tick (ihrcf_env.fast.dynamics) against the simulator's reference, float64: PyBullet's
rigid-body step of the simulator's drone (sim.drone.Quadrotor: rotor lag, thrust, drag, the
external force; tests/fast/bullet_ref.py), the scalar mixer (Quadrotor.wrench_to_speeds), the
scalar ground effect (sim.ground_effect) and the orientation PyBullet reports (Shepperd's method).

Tolerances, relative with floor 1 (measured on x86-64: 1.0e-15 after one tick, 6.2e-15 after
sixty ticks of tumbling drones, both in the angular velocity): :data:`TICK_TOL` one tick,
:data:`TICKS_TOL` sixty ticks (the rounding grows through the gyroscopic terms), 1e-12 the mixer's
thrusts and the ground effect, 1e-15 the reported quaternion. A wrong scheme (explicit Euler)
exceeds TICK_TOL by orders of magnitude."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial.transform import Rotation

from ihrcf_env.config.vehicle import QuadParams
from ihrcf_env.fast.dynamics import (
    DroneState,
    GroundEffectParams,
    drone_params,
    matrix_from_quaternion,
    mixer_speeds,
    quaternion_from_matrix,
    rotor_positions,
    thrust_scale,
    tick,
    ticks,
)
from ihrcf_env.sim.ground_effect import GroundEffect
from ihrcf_env.sim.ground_effect import rotor_positions as scalar_rotor_positions

from .bullet_ref import DT, BulletDrone, stack
from .fast_helpers import Counted, rel_err, rotations

QP = QuadParams()
P = drone_params(QP)
N = 256
#: One tick against PyBullet (relative, floor 1).
TICK_TOL = 1e-13
#: Sixty ticks of tumbling drones against PyBullet (relative, floor 1).
TICKS_TOL = 1e-12
GE_MODEL = GroundEffect(QP.rotor_radius)
GE = GroundEffectParams(
    jnp.asarray(GE_MODEL.rotor_radius),
    jnp.asarray(GE_MODEL.ground_height),
    jnp.asarray(GE_MODEL.min_height_ratio),
    jnp.asarray(0.5),
)

TICK = Counted(lambda s, c, k, f: tick(s, c, P, DT, k, f))
TICKS = Counted(lambda s, c: ticks(s, c, P, DT, 60))
MIX = Counted(lambda t, x, y, z: mixer_speeds(P, t, x, y, z))
QUAT = Counted(quaternion_from_matrix)
#: The orientation PyBullet reports for a quaternion state: through its matrix and back.
REPORTED = Counted(lambda q: quaternion_from_matrix(matrix_from_quaternion(q)))


def scale_fn(p, R, dp, dR):
    return thrust_scale(rotor_positions(p, R, P), dp, dR, GE)


SCALE = Counted(scale_fn)


def states(seed: int, n: int = N):
    rng = np.random.default_rng(seed)
    q = Rotation.from_matrix(rotations(rng, n, 0.8)).as_quat()
    s = DroneState(
        rng.uniform(-2, 2, (n, 3)) + [0, 0, 3],
        q,
        rng.normal(0, 2, (n, 3)),
        rng.normal(0, 3, (n, 3)),
        rng.uniform(300, 900, (n, 4)),
    )
    return s, rng


def bullet_flight(s: DroneState, cmd, scale=None, force=None, n_ticks: int = 1) -> dict[str, np.ndarray]:
    """Each row of ``s`` flown ``n_ticks`` physics ticks by PyBullet on its row of ``cmd`` (and of
    ``scale``, ``force``)."""
    drone = BulletDrone(QP)
    try:
        rows = []
        for i in range(len(s.position)):
            drone.place(
                s.position[i], s.quaternion[i], s.velocity[i], s.angular_velocity[i], s.rotor_speed[i]
            )
            for _ in range(n_ticks):
                drone.tick(cmd[i], None if scale is None else scale[i], None if force is None else force[i])
            rows.append(drone.state())
        return stack(rows)
    finally:
        drone.close()


def compare(got: DroneState, want: dict[str, np.ndarray]) -> float:
    """Largest relative difference (floor 1) of the JAX state and PyBullet's (the orientation as
    PyBullet reports it)."""
    return max(
        rel_err(got.position, want["position"]),
        rel_err(REPORTED(got.quaternion), want["quaternion"]),
        rel_err(got.velocity, want["velocity"]),
        rel_err(got.angular_velocity, want["angular_velocity"]),
        rel_err(got.rotor_speed, want["rotor_speed"]),
    )


def test_one_tick_matches_pybullet() -> None:
    s, rng = states(0)
    cmd = rng.uniform(0, 1000, (N, 4))
    k = rng.uniform(0.9, 1.3, (N, 4))
    f = rng.normal(0, 2, (N, 3))
    s.angular_velocity[:4] = [[0, 0, 1e-5], [0, 0, 0], [300.0, 0, 0], [0, 0, 250.0]]  # tiny, zero, capped
    want = bullet_flight(s, cmd, k, f)
    assert np.abs(want["angular_velocity"][2:4]).max() == 100.0  # Bullet's velocity clamp is exercised
    err = compare(TICK(s, cmd, k, f), want)
    print(f"one tick: max relative |JAX - PyBullet| = {err:.3g}")
    assert err < TICK_TOL, err


def test_sixty_ticks_match_pybullet() -> None:
    s, rng = states(1)
    cmd = rng.uniform(400, 800, (N, 4))
    want = bullet_flight(s, cmd, n_ticks=60)
    moved = np.abs(want["position"] - s.position).max(axis=1)
    assert np.median(moved) > 0.05  # a quarter second of flight: the states have changed
    err = compare(TICKS(s, cmd), want)
    print(f"sixty ticks: max relative |JAX - PyBullet| = {err:.3g}")
    assert err < TICKS_TOL, err


def test_a_wrong_tick_exceeds_the_tolerance() -> None:
    """The tolerance catches a wrong scheme: positions advanced with the old velocity (explicit
    Euler) differ from PyBullet's by far more than TICK_TOL."""
    s, rng = states(8)
    cmd = rng.uniform(400, 800, (N, 4))
    want = bullet_flight(s, cmd)
    got = TICK(s, cmd, np.ones((N, 4)), np.zeros((N, 3)))
    euler = got._replace(position=np.asarray(got.position) - DT * (np.asarray(got.velocity) - s.velocity))
    assert compare(euler, want) > 1e3 * TICK_TOL


def test_quaternion_branches_match_pybullet() -> None:
    """The quaternion of a rotation matrix as PyBullet reports a body's orientation (Shepperd's
    method, every branch: half turns and rotations beyond 120 degrees included)."""
    R = Rotation.random(N, random_state=3).as_matrix()
    R[0] = np.diag([1.0, -1.0, -1.0])  # half turns: the three diagonal branches
    R[1] = np.diag([-1.0, 1.0, -1.0])
    R[2] = np.diag([-1.0, -1.0, 1.0])
    R[3] = np.eye(3)
    assert (np.trace(R, axis1=1, axis2=2) <= 0).sum() > 50
    drone = BulletDrone(QP)
    try:
        want = []
        for m in R:
            q = Rotation.from_matrix(m).as_quat()
            drone.place([0, 0, 1], q, [0, 0, 0], [0, 0, 0], [0, 0, 0, 0])
            want.append(drone.state()["quaternion"])
    finally:
        drone.close()
    assert rel_err(QUAT(R), np.array(want)) < 1e-15


def test_mixer_matches_including_saturation() -> None:
    """The saturating mixer against the simulator's (Quadrotor.wrench_to_speeds), row by row."""
    rng = np.random.default_rng(4)
    thrust = rng.uniform(-2, 30, N)
    tx, ty, tz = rng.normal(0, 1.0, (3, N)) * np.array([[0.15], [0.15], [0.03]])
    tz[:8] = 0.0  # no yaw torque
    thrust[8:16] = 60.0  # all saturated high
    drone = BulletDrone(QP)
    try:
        want = np.array(
            [drone.quad.wrench_to_speeds(float(thrust[i]), (tx[i], ty[i], tz[i])) for i in range(N)]
        )
    finally:
        drone.close()
    got = np.asarray(MIX(thrust, tx, ty, tz))
    # compared as motor thrusts (N): a speed is the square root of a thrust, which magnifies the
    # rounding of a thrust near 0 (XLA may fuse a multiply-add where numpy rounds twice)
    assert rel_err(QP.kf * got**2, QP.kf * want**2) < 1e-12
    f = QP.kf * want**2
    sat = (f <= 1e-12).any(axis=1) | (f >= QP.max_thrust * (1 - 1e-12)).any(axis=1)
    assert sat.sum() > 20 and (~sat).sum() > 20


def test_ground_effect_matches_over_deck_edge_and_ground() -> None:
    """Rotor positions and thrust ratios against the simulator's scalar ground effect."""
    rng = np.random.default_rng(5)
    R = rotations(rng, N, 0.3)
    dR = rotations(rng, N, 0.25)
    dp = np.column_stack([rng.uniform(-0.1, 0.1, (N, 2)), rng.uniform(0.6, 1.2, N)])
    p = dp + np.column_stack([rng.uniform(-0.8, 0.8, (N, 2)), rng.uniform(-0.1, 0.6, N)])
    p[:8, :2] = dp[:8, :2] + [0.5, 0.0]  # straddling the edge
    p[8:16, 2] = 0.01  # near the ground, off the deck
    motor_xy = QP.motor_xy.tolist()
    rotors = [scalar_rotor_positions(p[i].tolist(), R[i].ravel().tolist(), motor_xy) for i in range(N)]
    want = np.array([GE_MODEL.thrust_scale(rotors[i], dp[i].tolist(), dR[i].tolist(), 0.5) for i in range(N)])
    assert rel_err(jax.vmap(lambda a, b: rotor_positions(a, b, P))(p, R), np.array(rotors)) < 1e-15
    got = SCALE(p, R, dp, dR)
    assert rel_err(got, want) < 1e-12
    assert (want > 1.01).any() and (np.abs(want - 1.0) < 1e-3).any()


def test_compiled_once_and_vmap_of_scan() -> None:
    before = TICKS.traces
    for seed in (6, 7):
        s, rng = states(seed)
        TICKS(s, rng.uniform(400, 800, (N, 4)))
    assert TICKS.traces - before <= 1
    assert jax.numpy.isfinite(TICKS(s, np.zeros((N, 4))).position).all()
