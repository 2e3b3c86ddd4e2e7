"""The physics tick (ihrcf_env.fast.dynamics) against the simulator's numpy twins
(sim.batched.dynamics / integrator / floatmath / mixer / surface), float64."""

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
    mixer_speeds,
    quaternion_from_matrix,
    rotor_positions,
    thrust_scale,
    tick,
    ticks,
)
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor
from ihrcf_env.sim.batched.floatmath import quaternions_from_matrices
from ihrcf_env.sim.batched.mixer import BatchedMixer
from ihrcf_env.sim.batched.surface import rotor_positions_batch, thrust_scale_batch
from ihrcf_env.sim.ground_effect import GroundEffect

from .fast_helpers import Counted, rel_err, rotations

QP = QuadParams()
P = drone_params(QP)
DT = 1.0 / 240.0
N = 256
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


def reference(s: DroneState) -> BatchedQuadrotor:
    b = BatchedQuadrotor(QP, len(s.position))
    b.position[:] = s.position
    b.quaternion[:] = s.quaternion
    b.velocity[:] = s.velocity
    b.angular_velocity[:] = s.angular_velocity
    b.rotor_speed[:] = s.rotor_speed
    b.invalidate()
    return b


def compare(got: DroneState, b: BatchedQuadrotor) -> float:
    return max(
        rel_err(got.position, b.position),
        rel_err(got.quaternion, b.quaternion),
        rel_err(got.velocity, b.velocity),
        rel_err(got.angular_velocity, b.angular_velocity),
        rel_err(got.rotor_speed, b.rotor_speed),
    )


def test_one_tick_matches_numpy_twin() -> None:
    s, rng = states(0)
    cmd = rng.uniform(0, 1000, (N, 4))
    k = rng.uniform(0.9, 1.3, (N, 4))
    f = rng.normal(0, 2, (N, 3))
    s.angular_velocity[:4] = [[0, 0, 1e-5], [0, 0, 0], [300.0, 0, 0], [0, 0, 250.0]]  # tiny, zero, capped
    b = reference(s)
    b.step(cmd, DT, k, f)
    assert compare(TICK(s, cmd, k, f), b) < 1e-12


def test_sixty_ticks_match_numpy_twin() -> None:
    s, rng = states(1)
    cmd = rng.uniform(400, 800, (N, 4))
    b = reference(s)
    for _ in range(60):
        b.step(cmd, DT)
    assert compare(TICKS(s, cmd), b) < 1e-9


def test_quaternion_branches_match() -> None:
    rng = np.random.default_rng(2)
    R = Rotation.random(N, random_state=3).as_matrix()
    R[0] = np.diag([1.0, -1.0, -1.0])  # half turns: the three diagonal branches
    R[1] = np.diag([-1.0, 1.0, -1.0])
    R[2] = np.diag([-1.0, -1.0, 1.0])
    R[3] = np.eye(3)
    got = QUAT(R)
    want = quaternions_from_matrices(R)
    assert rel_err(got, want) < 1e-15
    assert rng is not None


def test_mixer_matches_including_saturation() -> None:
    rng = np.random.default_rng(4)
    thrust = rng.uniform(-2, 30, N)
    tx, ty, tz = rng.normal(0, 1.0, (3, N)) * np.array([[0.15], [0.15], [0.03]])
    tz[:8] = 0.0  # no yaw torque
    thrust[8:16] = 60.0  # all saturated high
    want = BatchedMixer(QP).speeds(thrust, tx, ty, tz)
    got = np.asarray(MIX(thrust, tx, ty, tz))
    # compared as motor thrusts (N): a speed is the square root of a thrust, which magnifies the
    # rounding of a thrust near 0 (XLA may fuse a multiply-add where numpy rounds twice)
    assert rel_err(QP.kf * got**2, QP.kf * want**2) < 1e-12
    f = QP.kf * want**2
    sat = (f <= 1e-12).any(axis=1) | (f >= QP.max_thrust * (1 - 1e-12)).any(axis=1)
    assert sat.sum() > 20 and (~sat).sum() > 20


def test_ground_effect_matches_over_deck_edge_and_ground() -> None:
    rng = np.random.default_rng(5)
    R = rotations(rng, N, 0.3)
    dR = rotations(rng, N, 0.25)
    dp = np.column_stack([rng.uniform(-0.1, 0.1, (N, 2)), rng.uniform(0.6, 1.2, N)])
    p = dp + np.column_stack([rng.uniform(-0.8, 0.8, (N, 2)), rng.uniform(-0.1, 0.6, N)])
    p[:8, :2] = dp[:8, :2] + [0.5, 0.0]  # straddling the edge
    p[8:16, 2] = 0.01  # near the ground, off the deck
    want = thrust_scale_batch(GE_MODEL, rotor_positions_batch(p, R, QP.motor_xy), dp, dR, 0.5)
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
