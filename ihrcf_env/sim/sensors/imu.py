"""The drone's IMU: attitude, body rates and specific force, with pluggable noise per channel.

Two presets (:class:`IMUConfig` ``noise``): ``"ideal"`` (the true values, nothing drawn) and
``"realistic"`` (:class:`IMUNoise`, the figures of a Bosch BMI088, the IMU of many flight
controllers, and of a commercial attitude filter). Per axis, sampled every ``dt`` s (the control
period), ``n ~ N(0, 1)`` fresh each time:

* gyro and accelerometer: ``y = x + b_on + b_gm + N / sqrt(dt) n`` with the turn-on bias
  ``b_on ~ N(0, sigma_on^2)`` drawn at reset (:class:`~ihrcf_env.sim.noise.ConstantBias`), the bias
  instability ``b_gm`` a first-order Gauss-Markov process of stationary std ``sigma_bi`` and
  correlation time ``tau`` (:class:`~ihrcf_env.sim.noise.GaussMarkov`), and white noise of density
  ``N`` discretised at the sample rate, ``sigma_d = N sqrt(rate)``
  (:class:`~ihrcf_env.sim.noise.WhiteNoise`);
* attitude quaternion (an onboard attitude filter's output, :class:`AttitudeError`):
  ``R_meas = exp([e]_x) R_true`` with the world-frame error rotation ``e = (e_x, e_y, e_z)``: a tilt
  error ``e_x, e_y`` Gauss-Markov (``tilt_sigma``, ``tilt_time_constant``), and a heading drift
  ``e_z = r t``, ``r ~ N(0, yaw_drift_rate^2)`` drawn at reset.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.sensors import IMU_NOISE_BOUNDS, IMUConfig
from ihrcf_env.core.checks import check_real
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.noise import (
    Chain,
    ConstantBias,
    GaussMarkov,
    NoiseModel,
    NoNoise,
    WhiteNoise,
)
from ihrcf_env.sim.sensors.base import BodyState

_GRAVITY_WORLD = np.array([0.0, 0.0, GRAVITY])


def _quat_multiply(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hamilton product ``a b`` of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by + ay * bw + az * bx - ax * bz,
            aw * bz + az * bw + ax * by - ay * bx,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def _quat_from_rotvec(e: NDArray[np.float64]) -> NDArray[np.float64]:
    angle = float(np.linalg.norm(e))
    if angle < 1e-12:
        return np.array([0.5 * e[0], 0.5 * e[1], 0.5 * e[2], 1.0])
    s = math.sin(angle / 2) / angle
    return np.array([e[0] * s, e[1] * s, e[2] * s, math.cos(angle / 2)])


class AttitudeError:
    """Error of an attitude filter's quaternion output (a :class:`~ihrcf_env.sim.noise.NoiseModel` on
    the (4,) quaternion x, y, z, w, world from body): ``q_meas = q_err q_true`` with ``q_err`` the
    rotation by the world-frame vector ``(e_x, e_y, e_z)``; ``e_x, e_y`` a Gauss-Markov tilt error
    (``tilt_sigma`` rad, ``tilt_time_constant`` s), ``e_z = r t`` a heading drift at a rate
    ``r ~ N(0, yaw_drift_rate^2)`` (rad/s) drawn at reset, ``t`` the time since reset."""

    def __init__(self, tilt_sigma: float, tilt_time_constant: float, yaw_drift_rate: float) -> None:
        lo, hi = IMU_NOISE_BOUNDS["tilt_sigma"]
        self._tilt = GaussMarkov(
            check_real("tilt_sigma", tilt_sigma, "rad", low=lo, high=hi), tilt_time_constant, size=2
        )
        lo, hi = IMU_NOISE_BOUNDS["yaw_drift_rate"]
        self._rate_sigma = check_real("yaw_drift_rate", yaw_drift_rate, "rad/s", low=lo, high=hi)
        self.yaw_rate = 0.0
        self.yaw = 0.0

    @property
    def error(self) -> NDArray[np.float64]:
        """The current world-frame error rotation vector (rad)."""
        return np.array([self._tilt.bias[0], self._tilt.bias[1], self.yaw])

    def reset(self, rng: np.random.Generator) -> None:
        self._tilt.reset(rng)
        self.yaw_rate = float(rng.standard_normal()) * self._rate_sigma if self._rate_sigma > 0 else 0.0
        self.yaw = 0.0

    def apply(
        self, value: NDArray[np.float64], valid: NDArray[np.bool_], dt: float, rng: np.random.Generator
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        self._tilt.step(dt, rng)
        self.yaw += self.yaw_rate * dt
        q = _quat_multiply(_quat_from_rotvec(self.error), np.asarray(value, dtype=np.float64))
        return q / np.linalg.norm(q), valid


class IMU:
    """A :class:`Sensor` reading, at the control rate:

    * ``quaternion`` (4,): attitude (x, y, z, w), world from body (an attitude filter's output);
    * ``angular_velocity`` (3,): body rates, rad/s, body frame (gyro);
    * ``linear_acceleration`` (3,): specific force, m/s^2, body frame; +9.81 on z at hover
      (accelerometer).

    ``gyro_noise``, ``accel_noise`` and ``attitude_noise`` corrupt the body-frame vectors and the
    quaternion (default: ideal); :meth:`from_config` builds them from an :class:`IMUConfig`.
    """

    name = "imu"

    def __init__(
        self,
        gyro_noise: NoiseModel | None = None,
        accel_noise: NoiseModel | None = None,
        attitude_noise: NoiseModel | None = None,
    ) -> None:
        self.gyro_noise: NoiseModel = gyro_noise if gyro_noise is not None else NoNoise()
        self.accel_noise: NoiseModel = accel_noise if accel_noise is not None else NoNoise()
        self.attitude_noise: NoiseModel = attitude_noise if attitude_noise is not None else NoNoise()
        self._ok = np.ones(3, dtype=bool)
        self._ok4 = np.ones(4, dtype=bool)

    @classmethod
    def from_config(cls, config: IMUConfig) -> IMU:
        """The ideal IMU, or one with the :class:`IMUNoise` models described in the module docstring."""
        m = config.model
        if m is None:
            return cls()
        gyro = Chain(
            (
                ConstantBias(m.gyro_turn_on_bias),
                GaussMarkov(m.gyro_bias_instability, m.gyro_bias_time_constant),
                WhiteNoise(m.gyro_noise_density),
            )
        )
        accel = Chain(
            (
                ConstantBias(m.accel_turn_on_bias),
                GaussMarkov(m.accel_bias_instability, m.accel_bias_time_constant),
                WhiteNoise(m.accel_noise_density),
            )
        )
        attitude = AttitudeError(m.tilt_sigma, m.tilt_time_constant, m.yaw_drift_rate)
        return cls(gyro, accel, attitude)

    def reset(self, rng: np.random.Generator) -> None:
        self.gyro_noise.reset(rng)
        self.accel_noise.reset(rng)
        self.attitude_noise.reset(rng)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        R = state.rotation
        gyro, _ = self.gyro_noise.apply(R.T @ state.angular_velocity, self._ok, dt, rng)
        accel, _ = self.accel_noise.apply(R.T @ (state.acceleration + _GRAVITY_WORLD), self._ok, dt, rng)
        quat, _ = self.attitude_noise.apply(np.asarray(state.quaternion), self._ok4, dt, rng)
        return {
            "quaternion": quat,
            "angular_velocity": gyro,
            "linear_acceleration": accel,
        }


__all__ = [
    "IMU",
    "AttitudeError",
]
