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
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_fields, check_real, check_reals, set_field
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

#: IMU noise presets.
IMU_NOISE_PRESETS: tuple[str, ...] = ("ideal", "realistic")

_MG = 1e-3 * GRAVITY  # m/s^2 per milli-g
_DEG = math.pi / 180.0


_TAU = (1e-3, 1e4)  # s, correlation times

#: Physical bounds (inclusive) of :class:`IMUNoise`'s fields: generous for any MEMS or tactical IMU
#: and attitude filter.
IMU_NOISE_BOUNDS: dict[str, tuple[float, float]] = {
    "gyro_noise_density": (0.0, 0.1),
    "gyro_bias_instability": (0.0, 1.0),
    "gyro_bias_time_constant": _TAU,
    "gyro_turn_on_bias": (0.0, 1.0),
    "accel_noise_density": (0.0, 1.0),
    "accel_bias_instability": (0.0, 10.0),
    "accel_bias_time_constant": _TAU,
    "accel_turn_on_bias": (0.0, 10.0),
    "tilt_sigma": (0.0, 0.5),
    "tilt_time_constant": _TAU,
    "yaw_drift_rate": (0.0, 0.1),
}
IMU_NOISE_UNITS = {
    "gyro_noise_density": "rad/s/sqrt(Hz)",
    "gyro_bias_instability": "rad/s",
    "gyro_bias_time_constant": "s",
    "gyro_turn_on_bias": "rad/s",
    "accel_noise_density": "m/s^2/sqrt(Hz)",
    "accel_bias_instability": "m/s^2",
    "accel_bias_time_constant": "s",
    "accel_turn_on_bias": "m/s^2",
    "tilt_sigma": "rad",
    "tilt_time_constant": "s",
    "yaw_drift_rate": "rad/s",
}


@dataclass(frozen=True)
class IMUNoise:
    """Noise figures of the IMU and of its attitude filter. SI units: rad/s, m/s^2, rad, s.

    Sensor: Bosch **BMI088** data sheet (BST-BMI088-DS001, rev. 1.x), typical values:

    ========================  ===================================  ====================================
    field                     value                                source
    ========================  ===================================  ====================================
    gyro_noise_density        0.014 deg/s/sqrt(Hz)                 BMI088 gyro output noise density
    gyro_bias_instability     2 deg/h                              BMI088 gyro bias stability
    gyro_bias_time_constant   100 s                                assumption (Allan minimum region)
    gyro_turn_on_bias         1 deg/s (1 sigma)                    BMI088 zero-rate offset +-1 deg/s
    accel_noise_density       160, 160, 190 ug/sqrt(Hz) (x, y, z)  BMI088 accel output noise density
    accel_bias_instability    0.2 mg                               BMI088 TCO 0.2 mg/K x 1 K in flight
                                                                   (no instability figure is given)
    accel_bias_time_constant  100 s                                assumption
    accel_turn_on_bias        20 mg (1 sigma)                      BMI088 zero-g offset +-20 mg
    ========================  ===================================  ====================================

    Attitude filter: Xsens MTi user manual (MT0605P, sec. 4.3), MTi-30 AHRS typical dynamic
    roll/pitch error 0.5 deg (1 sigma RMS), and "based on the rate gyros the attitude and heading
    estimates will degrade slowly (typically a degree every minute)" without a heading reference
    (a magnetometer is unusable next to a steel deck): ``tilt_sigma`` 0.5 deg, ``tilt_time_constant``
    5 s (assumption: the filter's accelerometer-correction time scale), ``yaw_drift_rate`` 1 deg/min
    (1 sigma).

    The datasheet's typical offsets are taken as one standard deviation (a flight controller that
    calibrates its gyro at boot would leave less: set the turn-on fields to what it leaves).
    """

    gyro_noise_density: float = 0.014 * _DEG
    gyro_bias_instability: float = 2.0 * _DEG / 3600.0
    gyro_bias_time_constant: float = 100.0
    gyro_turn_on_bias: float = 1.0 * _DEG
    accel_noise_density: float | tuple[float, float, float] = (0.160 * _MG, 0.160 * _MG, 0.190 * _MG)
    accel_bias_instability: float = 0.2 * _MG
    accel_bias_time_constant: float = 100.0
    accel_turn_on_bias: float = 20.0 * _MG
    tilt_sigma: float = 0.5 * _DEG
    tilt_time_constant: float = 5.0
    yaw_drift_rate: float = 1.0 * _DEG / 60.0

    def __post_init__(self) -> None:
        density = self.accel_noise_density
        if isinstance(density, tuple | list | np.ndarray):
            if len(density) != 3:
                raise ValueError(
                    f"IMUNoise.accel_noise_density must be one number or 3 (x, y, z), got {density!r}"
                )
            lo, hi = IMU_NOISE_BOUNDS["accel_noise_density"]
            set_field(
                self,
                "accel_noise_density",
                check_reals("IMUNoise.accel_noise_density", density, 3, "m/s^2/sqrt(Hz)", low=lo, high=hi),
            )
            bounds = {k: v for k, v in IMU_NOISE_BOUNDS.items() if k != "accel_noise_density"}
        else:
            bounds = IMU_NOISE_BOUNDS
        check_fields(self, lambda f: f"IMUNoise.{f}", bounds, IMU_NOISE_UNITS)


#: Accepted ``IMUConfig.rate_hz`` (Hz).
IMU_RATE_BOUNDS = (1.0, 10_000.0)


@dataclass(frozen=True)
class IMUConfig:
    """``noise``: a key of :data:`IMU_NOISE_PRESETS` or an :class:`IMUNoise` (custom figures)."""

    noise: str | IMUNoise = "ideal"
    #: output data rate (Hz) on the IMU's own clock (the latest sample is shown); None: one sample
    #: per control step
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        if self.rate_hz is not None:
            lo, hi = IMU_RATE_BOUNDS
            set_field(self, "rate_hz", check_real("imu_hz", self.rate_hz, "Hz", low=lo, high=hi))
        if not isinstance(self.noise, IMUNoise) and self.noise not in IMU_NOISE_PRESETS:
            raise ValueError(
                f"imu_noise must be one of {IMU_NOISE_PRESETS} or an IMUNoise, got {self.noise!r}"
            )

    @property
    def model(self) -> IMUNoise | None:
        """The noise figures, or None for the ideal IMU."""
        if isinstance(self.noise, IMUNoise):
            return self.noise
        return None if self.noise == "ideal" else IMUNoise()


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
