"""The drone's IMU: attitude, body rates and specific force, with pluggable noise per channel."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.noise import NoiseModel, NoNoise
from ihrcf_env.sim.sensors.base import BodyState

_GRAVITY_WORLD = np.array([0.0, 0.0, GRAVITY])


class IMU:
    """A :class:`Sensor` reading, at the control rate:

    * ``quaternion`` (4,): attitude (x, y, z, w), world from body (an attitude filter's output);
    * ``angular_velocity`` (3,): body rates, rad/s, body frame (gyro);
    * ``linear_acceleration`` (3,): specific force, m/s^2, body frame; +9.81 on z at hover
      (accelerometer).

    ``gyro_noise`` and ``accel_noise`` corrupt the body-frame vectors (default: ideal).
    """

    name = "imu"

    def __init__(self, gyro_noise: NoiseModel | None = None, accel_noise: NoiseModel | None = None) -> None:
        self.gyro_noise: NoiseModel = gyro_noise if gyro_noise is not None else NoNoise()
        self.accel_noise: NoiseModel = accel_noise if accel_noise is not None else NoNoise()
        self._ok = np.ones(3, dtype=bool)

    def reset(self, rng: np.random.Generator) -> None:
        self.gyro_noise.reset(rng)
        self.accel_noise.reset(rng)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        R = state.rotation
        gyro, _ = self.gyro_noise.apply(R.T @ state.angular_velocity, self._ok, dt, rng)
        accel, _ = self.accel_noise.apply(R.T @ (state.acceleration + _GRAVITY_WORLD), self._ok, dt, rng)
        return {
            "quaternion": np.asarray(state.quaternion),
            "angular_velocity": gyro,
            "linear_acceleration": accel,
        }
