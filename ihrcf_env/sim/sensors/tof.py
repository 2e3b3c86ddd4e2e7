"""Time-of-flight range sensors ps1..ps4: PyBullet ray casts along the optical axis."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.noise import Chain, Dropout, GaussianNoise, NoiseModel
from ihrcf_env.sim.sensors.base import BodyState

#: ToF noise presets: Gaussian sigma (m), dropout probability per reading, minimum range (m).
TOF_PRESETS: dict[str, dict[str, float]] = {
    "ideal": {"sigma": 0.0, "dropout": 0.0, "min_range": 0.0},
    # VL53L1X-like: +-20 mm ranging error taken as 2 sigma, 1 % dropouts, 4 cm minimum range.
    "realistic": {"sigma": 0.01, "dropout": 0.01, "min_range": 0.04},
}


@dataclass(frozen=True)
class ToFConfig:
    """Four ToF beams parallel to the optical axis. ``noise`` is a key of :data:`TOF_PRESETS`."""

    max_range: float = 4.0
    noise: str = "ideal"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise ValueError(f"tof max_range must be positive (m), got {self.max_range!r}")
        if self.noise not in TOF_PRESETS:
            raise ValueError(f"tof_noise must be one of {sorted(TOF_PRESETS)}, got {self.noise!r}")

    @property
    def preset(self) -> dict[str, float]:
        return TOF_PRESETS[self.noise]


class ToFArray:
    """Ray-cast range sensors ps1..ps4 (see :mod:`ihrcf_env.core.rig`): a :class:`Sensor` reading
    ``ranges`` (4,) float32 m and ``ranges_valid`` (4,) int8.

    ``noise`` (default: built from the config's preset, Gaussian then dropouts) corrupts the true
    ranges; readings outside ``[min_range, max_range]`` are then invalid. Invalid readings (miss,
    dropout, out of range) read ``max_range``.
    """

    name = "tof"

    def __init__(
        self, client: int, config: ToFConfig, rig: SensorRig, noise: NoiseModel | None = None
    ) -> None:
        self.client = client
        self.config = config
        self._pos_body = rig.sensor_positions_body
        preset = config.preset
        self._min = preset["min_range"]
        self.noise: NoiseModel = (
            noise
            if noise is not None
            else Chain((GaussianNoise(preset["sigma"]), Dropout(preset["dropout"])))
        )

    def true_ranges(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Noise-free ranges (m) along body -z and hit flags. Misses read ``max_range``."""
        starts = self._pos_body @ R_wb.T + pos
        ends = starts - R_wb[:, 2] * self.config.max_range
        hits = p.rayTestBatch(starts.tolist(), ends.tolist(), physicsClientId=self.client)
        ranges = np.empty(4)
        hit = np.empty(4, dtype=bool)
        for i, h in enumerate(hits):
            hit[i] = h[0] >= 0
            ranges[i] = h[2] * self.config.max_range if hit[i] else self.config.max_range
        return ranges, hit

    def reset(self, rng: np.random.Generator) -> None:
        self.noise.reset(rng)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """Measured ``ranges`` (m, float32 in [0, max_range]) and ``ranges_valid`` (int8 0/1)."""
        ranges, hit = self.true_ranges(state.position, state.rotation)
        ranges, valid = self.noise.apply(ranges, hit, dt, rng)
        valid = valid & (ranges >= self._min) & (ranges <= self.config.max_range)
        ranges = np.where(valid, ranges, self.config.max_range)
        return {"ranges": ranges.astype(np.float32), "ranges_valid": valid.astype(np.int8)}
