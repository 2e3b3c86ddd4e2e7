"""Time-of-flight range sensors ps1..ps4: PyBullet ray casts along the optical axis.

Two models (:class:`ToFConfig` ``noise``):

* ``"ideal"``: one ray per sensor along body -z; the reading is the distance to the first hit,
  noise-free (a miss reads ``max_range``, invalid).
* ``"realistic"``: an ST **VL53L1X** (:class:`VL53L1X`, the sensor of the paper's rig class). Its
  receiver sees a cone, 27 deg full field of view (ST datasheet DS12385), so each sensor casts a
  fixed pattern of ``rays`` rays spread uniformly over the cone's solid angle (a Vogel spiral;
  one ``rayTestBatch`` for all four sensors). The sensor "averages all the photon times it gets
  back" (ST's imaging-sensor support, community.st.com, on a VL53L1X seeing a 100 mm and a 3 m
  target at once: it can report about 2 m), so the reading is the **signal-weighted mean** of the
  ray distances, each ray's return signal that of a Lambertian patch, ``s_i = rho cos(i_i) / r_i^2``
  (``r_i`` the ray's length, ``i_i`` its incidence angle), divided by the factor that makes a
  perpendicular flat target read its true distance (the sensor's calibration). A beam straddling
  the deck edge therefore reads between deck and ground, nearer the deck (its returns are
  stronger).

  Noise and limits follow a photon-counting model calibrated on ST's figures (VL53L1X user manual
  UM2356/UM2510 and datasheet, long distance mode): the total signal ``S = mean_i s_i`` (relative
  units) against an ambient level ``A``; ``SNR = S / sqrt(S + A)``. A reading needs ``SNR >=
  SNR_min`` (else no target: invalid, as the sensor's signal-fail range status), with ``SNR_min``
  set so an 88 % target is seen to ``dark_range`` = 3.6 m in the dark, and ``A_strong`` so it is
  seen to ``ambient_range`` = 0.73 m in strong ambient light (200 kcps/SPAD, "direct sunlight
  behind glass"); ``ambient`` in [0, 1] scales ``A = ambient A_strong``. A 54 % grey target
  (``reflectance``, ST's grey test card) is then seen to 2.8 m in the dark, 17 % to 1.6 m (ST: 1.7
  m). The repeatability is ``sigma = sqrt(sigma_floor^2 + (sigma_at_limit SNR_min / SNR)^2)``: it
  grows like ``d`` in the dark (shot noise of the signal) and like ``d^2`` in ambient light (shot
  noise of the background), reaching ``sigma_at_limit`` = 10 mm at the range limit (ST: ranging
  error +-20 mm dark, +-25 mm in strong ambient, as 2 sigma). Each sensor also has a constant
  offset ``N(0, offset_sigma^2)`` drawn at reset (2.5 mm: SparkFun measured +-5 mm accuracy), and
  a reading is lost with probability ``dropout`` (1 %, assumption: sigma/wrap-around fails).
  Readings below ``min_range`` (40 mm, ST) or above ``max_range`` are invalid; invalid readings
  read ``max_range`` with ``ranges_valid = 0``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_fields, check_int, check_real, set_field
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.noise import NoiseModel, NoNoise
from ihrcf_env.sim.sensors.base import BodyState, poses_key

if TYPE_CHECKING:
    from ihrcf_env.sim.batched.ranging import BatchedToF
    from ihrcf_env.sim.deck import Deck

#: Ranges of ST's long distance mode used to calibrate :class:`VL53L1X`'s SNR model: an 88 %
#: (white) target, 33 ms timing budget, full 16x16 SPAD region of interest.
REFERENCE_REFLECTANCE = 0.88

#: Physical bounds (inclusive) of :class:`VL53L1X`'s real-valued fields: any real ToF sensor fits.
VL53L1X_BOUNDS: dict[str, tuple[float, float]] = {
    "fov": (math.radians(1.0), math.radians(90.0)),
    "reflectance": (0.01, 1.0),
    "ambient": (0.0, 1.0),
    "dark_range": (0.05, 50.0),
    "ambient_range": (0.01, 20.0),
    "sigma_at_limit": (1e-4, 1.0),
    "sigma_floor": (0.0, 1.0),
    "offset_sigma": (0.0, 1.0),
    "min_range": (0.0, 10.0),
    "dropout": (0.0, 1.0),
}
VL53L1X_UNITS = {
    "fov": "rad",
    "dark_range": "m",
    "ambient_range": "m",
    "sigma_at_limit": "m",
    "sigma_floor": "m",
    "offset_sigma": "m",
    "min_range": "m",
}
#: Bounds (m) of :class:`ToFConfig` ``max_range``.
MAX_RANGE_BOUNDS = (0.1, 100.0)


@dataclass(frozen=True)
class VL53L1X:
    """The realistic ToF model (see the module docstring). Metres, radians; ``ambient`` in [0, 1]
    (0 dark, 1 strong ambient light), ``reflectance`` in (0, 1], ``dropout`` a probability."""

    fov: float = math.radians(27.0)
    rays: int = 16
    reflectance: float = 0.54
    ambient: float = 0.0
    dark_range: float = 3.6
    ambient_range: float = 0.73
    sigma_at_limit: float = 0.010
    sigma_floor: float = 0.001
    offset_sigma: float = 0.0025
    min_range: float = 0.04
    dropout: float = 0.01

    def __post_init__(self) -> None:
        set_field(self, "rays", check_int("VL53L1X.rays", self.rays, low=1, high=256))
        check_fields(self, lambda f: f"VL53L1X.{f}", VL53L1X_BOUNDS, VL53L1X_UNITS)
        if not self.ambient_range < self.dark_range:
            raise ValueError(
                f"ambient_range ({self.ambient_range:g} m) must be shorter than dark_range "
                f"({self.dark_range:g} m)"
            )

    def directions(self) -> NDArray[np.float64]:
        """(rays, 3) unit vectors in the sensor frame (beam axis +z), uniform over the cone's solid
        angle: a Vogel (golden-angle) spiral."""
        return self._directions.copy()

    @functools.cached_property
    def _directions(self) -> NDArray[np.float64]:
        k = np.arange(self.rays) + 0.5
        cos_a = 1.0 - k / self.rays * (1.0 - math.cos(self.fov / 2))
        sin_a = np.sqrt(1.0 - cos_a**2)
        phi = k * math.pi * (3.0 - math.sqrt(5.0))
        return np.column_stack([sin_a * np.cos(phi), sin_a * np.sin(phi), cos_a])

    @functools.cached_property
    def _mean_cos3(self) -> float:
        return float(np.mean(self._directions[:, 2] ** 3))

    @functools.cached_property
    def flat_gain(self) -> float:
        """Weighted mean ray length over distance for a perpendicular flat target (weights
        ``cos^3``): the reading is divided by it, so such a target reads its true distance."""
        c = self._directions[:, 2]
        return float(np.sum(c**2) / np.sum(c**3))

    @functools.cached_property
    def snr_min(self) -> float:
        """SNR at the range limit (relative units: ``S = 1`` for a perpendicular rho = 1 target at 1 m)."""
        return math.sqrt(REFERENCE_REFLECTANCE * self._mean_cos3 / self.dark_range**2)

    @functools.cached_property
    def strong_ambient(self) -> float:
        """Ambient level ``A`` of strong ambient light (``ambient = 1``), same units as the signal."""
        s = REFERENCE_REFLECTANCE * self._mean_cos3 / self.ambient_range**2
        return (s / self.snr_min) ** 2 - s

    def sigma(self, signal: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Repeatability (m, 1 sigma) at total signal ``signal`` (see the module docstring)."""
        s = np.maximum(np.asarray(signal, dtype=np.float64), 1e-12)
        snr = s / np.sqrt(s + self.ambient * self.strong_ambient)
        return np.sqrt(self.sigma_floor**2 + (self.sigma_at_limit * self.snr_min / snr) ** 2)


#: Accepted ``ToFConfig.rate_hz`` (Hz): the VL53L1X ranges at up to 50 Hz (timing budget 20 ms).
TOF_RATE_BOUNDS = (1.0, 100.0)

#: ToF presets: ``"ideal"`` (one noise-free ray) and ``"realistic"`` (:class:`VL53L1X` defaults).
TOF_PRESETS: dict[str, VL53L1X | None] = {"ideal": None, "realistic": VL53L1X()}


@dataclass(frozen=True)
class ToFConfig:
    """Four ToF sensors looking along the optical axis. ``noise`` is a key of :data:`TOF_PRESETS` or a
    :class:`VL53L1X` (custom parameters); ``max_range`` (m) caps the readings."""

    max_range: float = 4.0
    noise: str | VL53L1X = "ideal"
    #: ranging frequency (Hz) on the sensor's own clock (the VL53L1X's timing budget plus its
    #: inter-measurement period: 20-50 Hz in practice); None: one reading per control step
    rate_hz: float | None = None

    def __post_init__(self) -> None:
        lo, hi = MAX_RANGE_BOUNDS
        set_field(self, "max_range", check_real("tof max_range", self.max_range, "m", low=lo, high=hi))
        if self.rate_hz is not None:
            lo, hi = TOF_RATE_BOUNDS
            set_field(self, "rate_hz", check_real("tof_hz", self.rate_hz, "Hz", low=lo, high=hi))
        if not isinstance(self.noise, VL53L1X) and self.noise not in TOF_PRESETS:
            raise ValueError(
                f"tof_noise must be one of {sorted(TOF_PRESETS)} or a VL53L1X, got {self.noise!r}"
            )

    @property
    def model(self) -> VL53L1X | None:
        """The cone model, or None for the ideal single ray."""
        return self.noise if isinstance(self.noise, VL53L1X) else TOF_PRESETS[self.noise]


class ToFArray:
    """Range sensors ps1..ps4 (see :mod:`ihrcf_env.core.rig`): a :class:`Sensor` reading ``ranges``
    (4,) float32 m and ``ranges_valid`` (4,) int8.

    Ideal: one ray per sensor, then ``noise`` (default: none) corrupts the ranges. Realistic: the
    :class:`VL53L1X` cone model (its own noise and validity), then ``noise`` (default: none).
    Readings outside ``[min_range, max_range]`` are invalid; invalid readings read ``max_range``.

    The rays are cast with PyBullet's ``rayTestBatch`` against the client's bodies, or, given the
    world's ``deck`` (its plate and base are then the scene, with the ground and the drone's own
    collision boxes), in closed form (:mod:`ihrcf_env.sim.batched.ranging`), the deck's pose read
    from its body at each reading. Closed-form rays cast for many worlds at once
    (:func:`~ihrcf_env.sim.batched.ranging.prefetch`) are taken by the next reading at the same
    drone and deck poses.
    """

    name = "tof"

    def __init__(
        self,
        client: int,
        config: ToFConfig,
        rig: SensorRig,
        noise: NoiseModel | None = None,
        deck: Deck | None = None,
    ) -> None:
        self.client = client
        self.deck = deck
        self.closed_form: BatchedToF | None = None
        #: closed-form rays cast ahead (ranging.prefetch): (poses key, (a, b) of the one world)
        self.prefetched: tuple[bytes, tuple[NDArray[np.float64], NDArray[np.float64]]] | None = None
        if deck is not None:
            from ihrcf_env.sim.batched.ranging import BatchedToF
            from ihrcf_env.sim.batched.rays import RayScene

            g = deck.geometry
            scene = RayScene.of(deck.config.size, deck.config.thickness, g.base_radius, g.base_height)
            self.closed_form = BatchedToF(rig.sensor_positions_body, config.max_range, scene, config.model)
        self.config = config
        self._pos_body = rig.sensor_positions_body
        self.model = config.model
        self._min = self.model.min_range if self.model is not None else 0.0
        if self.model is None:
            self.noise: NoiseModel = noise if noise is not None else NoNoise()
        else:
            self.noise = noise if noise is not None else NoNoise()
            m = self.model
            dirs = m.directions()  # sensor frame, +z along the beam = body -z
            self._dirs_body = np.column_stack([dirs[:, 0], dirs[:, 1], -dirs[:, 2]])
            self._gain = m.flat_gain
            self._sigma_offset = m.offset_sigma
            self._dropout = m.dropout
            self._snr_min = m.snr_min
            self._ambient = m.ambient * m.strong_ambient
        self.offset = np.zeros(4)

    def true_ranges(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Noise-free ranges (m) of the four beam axes (one ray each, along body -z) and hit flags.
        Misses read ``max_range``."""
        if self.closed_form is not None:
            ranges, hit = self._closed(pos, R_wb, cone=False)
            return ranges, hit.astype(bool)
        starts = self._pos_body @ R_wb.T + pos
        ends = starts - R_wb[:, 2] * self.config.max_range
        hits = p.rayTestBatch(starts.tolist(), ends.tolist(), physicsClientId=self.client)
        ranges = np.empty(4)
        hit = np.empty(4, dtype=bool)
        for i, h in enumerate(hits):
            hit[i] = h[0] >= 0
            ranges[i] = h[2] * self.config.max_range if hit[i] else self.config.max_range
        return ranges, hit

    def cone_returns(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Realistic model only: ``(lengths, signals)``, each (4, rays): every ray's length (m;
        ``nan`` for a miss) and return signal ``rho cos(incidence) / length^2`` (0 for a miss)."""
        if self.model is None:
            raise RuntimeError("cone_returns needs the realistic ToF model (tof_noise='realistic')")
        if self.closed_form is not None:
            return self._closed(pos, R_wb, cone=True)
        n = self.model.rays
        length = self.config.max_range
        starts = np.repeat(self._pos_body @ R_wb.T + pos, n, axis=0)
        dirs_w = np.tile(self._dirs_body @ R_wb.T, (4, 1))
        ends = starts + dirs_w * length
        hits = p.rayTestBatch(starts.tolist(), ends.tolist(), physicsClientId=self.client)
        h = np.array([(o, f, *nrm) for o, _, f, _, nrm in hits], dtype=np.float64)  # id, fraction, normal
        hit = h[:, 0] >= 0
        r = np.where(hit, np.maximum(h[:, 1] * length, 1e-4), 1.0)
        cos_i = np.abs(np.einsum("ij,ij->i", h[:, 2:], dirs_w))
        signal = np.where(hit, self.model.reflectance * cos_i / r**2, 0.0)
        return np.where(hit, r, np.nan).reshape(4, n), signal.reshape(4, n)

    def _closed(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64], cone: bool
    ) -> tuple[NDArray, NDArray]:
        """The closed-form rays at this drone pose and the deck's pose now, of this world:
        :meth:`BatchedToF.cone_returns` (``cone``) or :meth:`BatchedToF.true_ranges`; the
        prefetched ones when cast at the same poses."""
        cf = self.closed_form
        assert cf is not None
        deck_pos, deck_R = self._deck_pose()
        ahead, self.prefetched = self.prefetched, None
        if ahead is not None and ahead[0] == poses_key(np.array([cone]), pos, R_wb, deck_pos[0], deck_R[0]):
            return ahead[1]
        cast = cf.cone_returns if cone else cf.true_ranges
        a, b = cast(pos[None], R_wb[None], deck_pos, deck_R)
        return a[0], b[0]

    def _deck_pose(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The deck frame's pose now, stacked for one world: ((1, 3), (1, 3, 3))."""
        assert self.deck is not None
        pos, R = self.deck.pose()
        return pos[None], R[None]

    def cone_ranges(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Realistic model only: the noise-free readings (m; ``nan`` where nothing is hit) and total
        signals ``S`` (relative units) of the four sensors."""
        r, s = self.cone_returns(pos, R_wb)
        total = s.sum(axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.nansum(s * r, axis=1) / total / self._gain
        return np.where(total > 0, mean, np.nan), total / r.shape[1]

    def reset(self, rng: np.random.Generator) -> None:
        if self.model is not None and self._sigma_offset > 0:
            self.offset = rng.standard_normal(4) * self._sigma_offset
        self.noise.reset(rng)

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """Measured ``ranges`` (m, float32 in [0, max_range]) and ``ranges_valid`` (int8 0/1)."""
        max_range = self.config.max_range
        if self.model is None:
            ranges, hit = self.true_ranges(state.position, state.rotation)
        else:
            mean, signal = self.cone_ranges(state.position, state.rotation)
            snr = signal / np.sqrt(signal + self._ambient + 1e-300)
            hit = (signal > 0) & (snr >= self._snr_min)
            z = rng.standard_normal(4)
            lost = rng.random(4) < self._dropout
            ranges = np.where(hit, mean, max_range) + self.offset + z * self.model.sigma(signal)
            hit = hit & ~lost
        ranges, valid = self.noise.apply(ranges, hit, dt, rng)
        valid = valid & (ranges >= self._min) & (ranges <= max_range)
        ranges = np.where(valid, ranges, max_range)
        return {"ranges": ranges.astype(np.float32), "ranges_valid": valid.astype(np.int8)}
