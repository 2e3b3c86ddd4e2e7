"""The drone's IMU for one environment: attitude quaternion, body rates and specific force with the
realistic noise of :class:`ihrcf_env.config.sensors.IMUNoise`; the port of
:class:`ihrcf_env.sim.sensors.imu.IMU` (gyro and accelerometer: turn-on bias, Gauss-Markov bias
instability, white noise; attitude: Gauss-Markov tilt error and a heading drift).

The draws are inputs: :func:`reset_draws` and :func:`read_draws` take them from a numpy generator
in the reference's order (nothing for a zero standard deviation), so one generator gives the same
noise as the PyBullet env's IMU. Frames: world z up, body (world from body); quaternions (x, y, z,
w) world from body; rad/s, m/s^2.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array
from numpy.typing import NDArray

from ihrcf_env.config.sensors import IMUNoise
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.fast.linalg3 import tmatvec

__all__ = [
    "ImuParams",
    "ImuState",
    "imu_params",
    "imu_read",
    "imu_reset",
    "quat_multiply",
    "quat_of_rotvec",
    "read_draws",
    "reset_draws",
]

#: Draws per reset (gyro turn-on, gyro instability, accel turn-on, accel instability, tilt, yaw rate).
RESET_DRAWS = 15
#: Draws per sample (gyro instability, gyro white, accel instability, accel white, tilt).
READ_DRAWS = 14


class ImuParams(NamedTuple):
    """Per-axis standard deviations (3,) and time constants (s) of :class:`IMUNoise` (host-side,
    :func:`imu_params`)."""

    gyro_density: NDArray[np.float64]
    gyro_instability: NDArray[np.float64]
    gyro_tau: float
    gyro_turn_on: NDArray[np.float64]
    accel_density: NDArray[np.float64]
    accel_instability: NDArray[np.float64]
    accel_tau: float
    accel_turn_on: NDArray[np.float64]
    tilt_sigma: float
    tilt_tau: float
    yaw_drift_rate: float


class ImuState(NamedTuple):
    """The episode's noise state: gyro and accelerometer turn-on biases and Gauss-Markov biases (3,
    each), the tilt error (2,) rad, the heading drift rate (rad/s) and heading error (rad)."""

    gyro_on: Array
    gyro_gm: Array
    accel_on: Array
    accel_gm: Array
    tilt: Array
    yaw_rate: Array
    yaw: Array


def imu_params(noise: IMUNoise) -> ImuParams:
    """The :class:`ImuParams` of a realistic IMU's noise."""

    def three(v: object) -> NDArray[np.float64]:
        return np.broadcast_to(np.asarray(v, dtype=np.float64), (3,)).copy()

    return ImuParams(
        three(noise.gyro_noise_density),
        three(noise.gyro_bias_instability),
        float(noise.gyro_bias_time_constant),
        three(noise.gyro_turn_on_bias),
        three(noise.accel_noise_density),
        three(noise.accel_bias_instability),
        float(noise.accel_bias_time_constant),
        three(noise.accel_turn_on_bias),
        float(noise.tilt_sigma),
        float(noise.tilt_time_constant),
        float(noise.yaw_drift_rate),
    )


def _sized(rng: np.random.Generator, sigma: NDArray[np.float64] | float, n: int) -> NDArray[np.float64]:
    """``n`` standard normals from ``rng`` when ``sigma`` has a non-zero entry (else zeros, none drawn)."""
    return rng.standard_normal(n) if np.any(np.asarray(sigma) != 0.0) else np.zeros(n)


def reset_draws(prm: ImuParams, rng: np.random.Generator) -> NDArray[np.float64]:
    """The (:data:`RESET_DRAWS`,) standard normals of an IMU reset, drawn from ``rng`` as the
    simulator's IMU draws them."""
    return np.concatenate(
        [
            _sized(rng, prm.gyro_turn_on, 3),
            _sized(rng, prm.gyro_instability, 3),
            _sized(rng, prm.accel_turn_on, 3),
            _sized(rng, prm.accel_instability, 3),
            _sized(rng, prm.tilt_sigma, 2),
            _sized(rng, prm.yaw_drift_rate, 1),
        ]
    )


def read_draws(prm: ImuParams, rng: np.random.Generator) -> NDArray[np.float64]:
    """The (:data:`READ_DRAWS`,) standard normals of one IMU sample, drawn from ``rng`` as the
    simulator's IMU draws them."""
    return np.concatenate(
        [
            _sized(rng, prm.gyro_instability, 3),
            _sized(rng, prm.gyro_density, 3),
            _sized(rng, prm.accel_instability, 3),
            _sized(rng, prm.accel_density, 3),
            _sized(rng, prm.tilt_sigma, 2),
        ]
    )


def imu_reset(prm: ImuParams, draws: Array) -> ImuState:
    """The episode's noise state from the reset's draws (:func:`reset_draws`)."""
    return ImuState(
        draws[0:3] * prm.gyro_turn_on,
        draws[3:6] * prm.gyro_instability,
        draws[6:9] * prm.accel_turn_on,
        draws[9:12] * prm.accel_instability,
        draws[12:14] * prm.tilt_sigma,
        draws[14] * prm.yaw_drift_rate,
        jnp.zeros_like(draws[14]),
    )


def _markov(b: Array, sigma: NDArray[np.float64] | float, tau: float, n: Array, dt: float) -> Array:
    phi = math.exp(-dt / tau)
    return phi * b + n * (np.asarray(sigma) * math.sqrt(1.0 - phi * phi))


def quat_multiply(a: Array, b: Array) -> Array:
    """Hamilton product ``a b`` of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    return jnp.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by + ay * bw + az * bx - ax * bz,
            aw * bz + az * bw + ax * by - ay * bx,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def quat_of_rotvec(e: Array) -> Array:
    """The quaternion (x, y, z, w) of the rotation vector ``e`` (3,) rad."""
    angle = jnp.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2])
    small = angle < 1e-12
    safe = jnp.where(small, 1.0, angle)
    s = jnp.where(small, 0.5, jnp.sin(safe / 2) / safe)
    w = jnp.where(small, 1.0, jnp.cos(safe / 2))
    return jnp.stack([e[0] * s, e[1] * s, e[2] * s, w])


def imu_read(
    prm: ImuParams | None,
    state: ImuState,
    rotation: Array,
    angular_velocity: Array,
    acceleration: Array,
    quaternion: Array,
    draws: Array,
    dt: float,
) -> tuple[ImuState, Array, Array, Array]:
    """One sample ``dt`` s after the previous one of the drone with ``rotation`` (3, 3; world from
    body), ``angular_velocity`` and ``acceleration`` (3,; world), ``quaternion`` (4,; its
    attitude), given the sample's draws (:func:`read_draws`). Returns the new noise state, the
    attitude quaternion, the body rates (rad/s, body) and the specific force (m/s^2, body; +g on
    z at hover). ``prm`` None: the ideal IMU (the true values)."""
    gyro = tmatvec(rotation, angular_velocity)
    accel = tmatvec(rotation, acceleration + jnp.array([0.0, 0.0, GRAVITY], dtype=acceleration.dtype))
    if prm is None:
        return state, quaternion, gyro, accel
    g_gm = _markov(state.gyro_gm, prm.gyro_instability, prm.gyro_tau, draws[0:3], dt)
    gyro = gyro + state.gyro_on + g_gm + draws[3:6] * (prm.gyro_density / math.sqrt(dt))
    a_gm = _markov(state.accel_gm, prm.accel_instability, prm.accel_tau, draws[6:9], dt)
    accel = accel + state.accel_on + a_gm + draws[9:12] * (prm.accel_density / math.sqrt(dt))
    tilt = _markov(state.tilt, prm.tilt_sigma, prm.tilt_tau, draws[12:14], dt)
    yaw = state.yaw + state.yaw_rate * dt
    q = quat_multiply(quat_of_rotvec(jnp.stack([tilt[0], tilt[1], yaw])), quaternion)
    q = q / jnp.sqrt(jnp.sum(q * q))
    return state._replace(gyro_gm=g_gm, accel_gm=a_gm, tilt=tilt, yaw=yaw), q, gyro, accel
