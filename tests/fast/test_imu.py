"""The IMU (ihrcf_env.fast.imu) against sim.sensors.imu.IMU over a sequence of samples, float64."""

from __future__ import annotations

import copy

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.sensors import IMUConfig, IMUNoise
from ihrcf_env.fast.imu import RESET_DRAWS, imu_params, imu_read, imu_reset, read_draws, reset_draws
from ihrcf_env.sim.sensors.base import BodyState
from ihrcf_env.sim.sensors.imu import IMU

from .fast_helpers import rel_err, rotations

DT = 1.0 / 60.0


def states(seed: int, n: int) -> list[BodyState]:
    rng = np.random.default_rng(seed)
    R = rotations(rng, n, 0.5)
    q = Rotation.from_matrix(R).as_quat()
    return [
        BodyState(
            k * DT,
            rng.normal(0, 1, 3),
            R[k],
            q[k],
            rng.normal(0, 1, 3),
            rng.normal(0, 2, 3),
            rng.normal(0, 3, 3),
        )
        for k in range(n)
    ]


NOISES = {
    "realistic": IMUNoise(),
    "large": IMUNoise(
        tilt_sigma=0.2,
        yaw_drift_rate=0.05,
        gyro_bias_instability=0.01,
        accel_noise_density=(0.01, 0.02, 0.03),
    ),
    "no_tilt": IMUNoise(tilt_sigma=0.0, yaw_drift_rate=0.0),
}


@pytest.mark.parametrize("name", list(NOISES))
def test_imu_matches_reference(name: str) -> None:
    noise = NOISES[name]
    ref = IMU.from_config(IMUConfig(noise=noise))
    prm = imu_params(noise)
    rng = np.random.default_rng(21)
    mine = copy.deepcopy(rng)
    ref.reset(rng)
    rd = reset_draws(prm, mine)
    assert rd.shape == (RESET_DRAWS,)
    seq = states(22, 120)
    want = []
    for s in seq:
        out = ref.read(s, DT, rng)
        want.append(np.concatenate([out["quaternion"], out["angular_velocity"], out["linear_acceleration"]]))
    draws = np.stack([read_draws(prm, mine) for _ in seq])
    assert mine.bit_generator.state == rng.bit_generator.state  # the same numbers drawn

    def body(st, x):
        R, w, a, q, d = x
        st, qm, g, acc = imu_read(prm, st, R, w, a, q, d, DT)
        return st, (qm, g, acc)

    run = jax.jit(lambda r, xs: jax.lax.scan(body, imu_reset(prm, r), xs)[1])
    xs = tuple(
        np.stack([getattr(s, f) for s in seq])
        for f in ("rotation", "angular_velocity", "acceleration", "quaternion")
    )
    got = np.concatenate([np.asarray(a) for a in run(rd, (*xs, draws))], axis=1)
    assert rel_err(got, np.stack(want)) < 1e-12
    truth = np.concatenate([xs[3], np.einsum("nji,nj->ni", xs[0], xs[1])], axis=1)
    assert np.max(np.abs(got[:, :7] - truth)) > 1e-4  # the noise is there


def test_ideal_imu_is_the_truth() -> None:
    ref = IMU.from_config(IMUConfig(noise="ideal"))
    s = states(3, 1)[0]
    out = ref.read(s, DT, np.random.default_rng(0))
    st = imu_reset(imu_params(IMUNoise()), np.zeros(RESET_DRAWS))
    _, q, g, a = imu_read(
        None, st, s.rotation, s.angular_velocity, s.acceleration, s.quaternion, np.zeros(14), DT
    )
    assert rel_err(q, out["quaternion"]) < 1e-15
    assert rel_err(g, out["angular_velocity"]) < 1e-15
    assert rel_err(a, out["linear_acceleration"]) < 1e-15
