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

from typing import TYPE_CHECKING

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.sensors import ToFConfig
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.noise import NoiseModel, NoNoise
from ihrcf_env.sim.sensors.base import BodyState

if TYPE_CHECKING:
    from ihrcf_env.sim.deck import Deck
    from ihrcf_env.sim.sensors.ranging import ClosedFormToF


class ToFArray:
    """Range sensors ps1..ps4 (see :mod:`ihrcf_env.core.rig`): a :class:`Sensor` reading ``ranges``
    (4,) float32 m and ``ranges_valid`` (4,) int8.

    Ideal: one ray per sensor, then ``noise`` (default: none) corrupts the ranges. Realistic: the
    :class:`VL53L1X` cone model (its own noise and validity), then ``noise`` (default: none).
    Readings outside ``[min_range, max_range]`` are invalid; invalid readings read ``max_range``.

    The rays are cast with PyBullet's ``rayTestBatch`` against the client's bodies, or, given the
    world's ``deck`` (its plate and base are then the scene, with the ground and the drone's own
    collision boxes), in closed form (:mod:`ihrcf_env.sim.sensors.ranging`), the deck's pose read
    from its body at each reading.
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
        self.closed_form: ClosedFormToF | None = None
        if deck is not None:
            from ihrcf_env.sim.sensors.ranging import ClosedFormToF
            from ihrcf_env.sim.sensors.rays import RayScene

            g = deck.geometry
            scene = RayScene.of(deck.config.size, deck.config.thickness, g.base_radius, g.base_height)
            self.closed_form = ClosedFormToF(rig.sensor_positions_body, config.max_range, scene, config.model)
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
        origins = self._pos_body @ R_wb.T + pos  # (4, 3) world
        dirs_w = self._dirs_body @ R_wb.T  # (rays, 3) world, the same for every sensor
        ends = (origins[:, None, :] + (dirs_w * length)[None]).reshape(-1, 3)
        starts = [o for o in origins.tolist() for _ in range(n)]
        hits = p.rayTestBatch(starts, ends.tolist(), physicsClientId=self.client)
        ids, _, fractions, _, normals = zip(*hits, strict=True)  # id, link, fraction, point, normal
        hit = np.array(ids) >= 0
        r = np.where(hit, np.maximum(np.array(fractions) * length, 1e-4), 1.0)
        cos_i = np.abs(np.einsum("kij,ij->ki", np.array(normals).reshape(4, n, 3), dirs_w)).ravel()
        signal = np.where(hit, self.model.reflectance * cos_i / r**2, 0.0)
        return np.where(hit, r, np.nan).reshape(4, n), signal.reshape(4, n)

    def _closed(
        self, pos: NDArray[np.float64], R_wb: NDArray[np.float64], cone: bool
    ) -> tuple[NDArray, NDArray]:
        """The closed-form rays at this drone pose and the deck's pose now, of this world:
        :meth:`ClosedFormToF.cone_returns` (``cone``) or :meth:`ClosedFormToF.true_ranges`."""
        cf = self.closed_form
        assert cf is not None
        deck_pos, deck_R = self._deck_pose()
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


__all__ = [
    "ToFArray",
]
