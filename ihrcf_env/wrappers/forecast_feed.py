"""The deck-motion forecast of the landing observation (``deck_forecast``): the fused estimate in,
the ``forecast.*`` fields out.

:class:`ForecastFeed` feeds a :class:`~ihrcf_env.core.forecast.DeckForecaster` with the fused
filter's deck pose (never the truth), one sample per new camera frame on which the fused estimate
is valid, in a level, gravity-aligned frame of fixed heading (the IMU's world axes):

* **heave**: the height (m) of the deck origin relative to the drone's altitude at reset, as the
  env's sensors give it: the fused deck position in the body frame, turned into the level frame by
  the IMU attitude, plus the drone's *navigation altitude*, the integral since reset of the
  navigation vertical velocity (``nav_velocity``, trapezoids over the control steps). That altitude
  wanders with the navigation's velocity error (slowly against the deck's period; the forecaster
  removes the window mean).
* **roll**, **pitch** (rad): the deck normal's small rotations about the level frame's x and y axes
  (``roll = atan2(-n_y, n_z)``, ``pitch = atan2(n_x, n_z)``), from the fused deck attitude and the
  IMU attitude.

The fields (:data:`FORECAST_FIELDS`, one value per horizon) show the forecast with the heave about
the forecaster's window mean (the deck's mean height) and roll and pitch turned into the drone's
heading frame (the rest of the observation's frame); ``quiet`` is the probability that the
touchdown window :attr:`~ihrcf_env.core.forecast.ForecastOptions.quiet_lead` s ahead is quiet under
:class:`~ihrcf_env.core.quiescence.QuiescenceThresholds` at the deck's Froude scale. Until the
forecaster's first fit every field is 0 and ``valid`` is 0.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.estimators import PoseEstimate
from ihrcf_env.core.forecast import DeckForecaster, ForecastOptions
from ihrcf_env.core.frames import matrix_from_euler, matrix_from_quat
from ihrcf_env.core.landing_layout import FORECAST, FORECAST_OUTPUTS, FORECAST_SCALES, forecast_fields
from ihrcf_env.core.quiescence import QuiescenceThresholds

__all__ = [
    "FORECAST",
    "HEAVE_SCALE",
    "TILT_SCALE",
    "ForecastFeed",
    "forecast_fields",
]

HEAVE_SCALE, RATE_SCALE, TILT_SCALE = FORECAST_SCALES[0], FORECAST_SCALES[1], FORECAST_SCALES[2]
_SCALES = FORECAST_SCALES
_NAMES = FORECAST_OUTPUTS


class ForecastFeed:
    """The forecaster of one wrapped env and its input (module docstring).

    Args:
        options: the forecast options.
        length_scale: the deck's Froude scale (the quiescence thresholds are scaled by it).
    """

    def __init__(self, options: ForecastOptions, length_scale: float) -> None:
        self.forecaster = DeckForecaster(options)
        self.thresholds = QuiescenceThresholds().scaled(length_scale)
        self.horizons = np.asarray(options.horizons, dtype=np.float64)
        self.reset()

    def reset(self) -> None:
        """Forget every sample (the start of an episode; the navigation altitude restarts at 0)."""
        self.forecaster.reset()
        self.altitude = 0.0  # m, navigation altitude relative to the drone's at reset
        self._last: tuple[float, float] | None = None  # (time s, vertical nav velocity m/s)
        self._frame: object = None
        #: samples fed to the forecaster since reset
        self.samples = 0

    def observe(
        self,
        time: float,
        nav_velocity_z: float,
        frame: object,
        fused: PoseEstimate,
        R_lb: NDArray[np.float64],
        R_lw: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """One observation at ``time`` (s): integrate the navigation altitude, feed the fused
        estimate when ``frame`` (the camera frame behind it) is new and it is valid, and return the
        scaled block and the ``info["forecast"]`` dict (physical units, the block's frames)."""
        vz = float(nav_velocity_z) if math.isfinite(float(nav_velocity_z)) else 0.0
        if self._last is not None and time > self._last[0]:
            self.altitude += 0.5 * (self._last[1] + vz) * (time - self._last[0])
        self._last = (time, vz)
        fresh = frame is not None and frame is not self._frame
        self._frame = frame
        if fresh and fused.valid:
            sample = self._sample(fused, R_lb, R_lw)
            if np.all(np.isfinite(sample)):
                self.forecaster.update(time, sample, True)
                self.samples += 1
        return self._output(R_lw)

    def observe_imu(
        self, time: float, nav_velocity_z: float, frame: object, fused: PoseEstimate, quaternion: Any
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """:meth:`observe` with the rotations of the IMU attitude ``quaternion`` (x, y, z, w; world
        from body): the heading frame is the level frame turned by the drone's yaw."""
        R_wb = matrix_from_quat(np.asarray(quaternion, dtype=np.float64))
        yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
        c, s = math.cos(yaw), math.sin(yaw)
        R_lw = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        return self.observe(time, nav_velocity_z, frame, fused, R_lw @ R_wb, R_lw)

    def _sample(
        self, fused: PoseEstimate, R_lb: NDArray[np.float64], R_lw: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """(heave m, roll rad, pitch rad) of a fused deck pose in the level frame of fixed heading."""
        R_wb = R_lw.T @ R_lb
        p = R_wb @ np.asarray(fused.position, dtype=np.float64)
        n = R_wb @ matrix_from_euler(*(float(v) for v in fused.euler))[:, 2]
        return np.array([self.altitude + p[2], math.atan2(-n[1], n[2]), math.atan2(n[0], n[2])])

    def _output(self, R_lw: NDArray[np.float64]) -> tuple[NDArray[np.float64], dict[str, Any]]:
        h = self.horizons.size
        fc = self.forecaster
        mean, std = np.zeros((h, 4)), np.zeros((h, 4))
        quiet, valid = 0.0, False
        if fc.fitted:
            f = fc.forecast()
            mean, std = f.mean.copy(), f.std.copy()
            mean[:, 0] -= fc.mu[0]
            R2 = R_lw[:2, :2]  # the level frame's axes turned into the heading frame's
            mean[:, 2:4] = mean[:, 2:4] @ R2.T
            std[:, 2:4] = np.sqrt(std[:, 2:4] ** 2 @ (R2**2).T)
            quiet = fc.quiet_probability(self.thresholds)
            valid = bool(np.all(np.isfinite(mean)) and np.all(np.isfinite(std)) and math.isfinite(quiet))
            if not valid:
                mean, std, quiet = np.zeros((h, 4)), np.zeros((h, 4)), 0.0
        scales = np.asarray(_SCALES)
        block = np.concatenate(
            [(mean / scales).T.reshape(-1), (std / scales).T.reshape(-1), [quiet, float(valid)]]
        )
        info = {
            "horizons": self.horizons.copy(),
            "mean": mean,
            "std": std,
            "quiet_probability": float(quiet),
            "valid": valid,
            "samples": self.samples,
            "outputs": _NAMES,
        }
        return block, info
