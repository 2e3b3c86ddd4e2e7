"""The ToF sensors' readings for one drone: the ideal model (one noise-free ray per sensor) and the
VL53L1X cone model (the signal-weighted mean of the cone's rays, the SNR limit, the repeatability,
the per-episode offset, the dropout): the port of :meth:`ihrcf_env.sim.sensors.tof.ToFArray.read`
with the closed-form rays of :meth:`ihrcf_env.sim.sensors.ranging.ClosedFormToF.cone_returns`.

The draws (the offsets' and the noise's standard normals, the dropout's uniforms) are inputs.
Ranges in m (float64: the observation rounds them to float32), ``valid`` flags; an invalid reading
reads ``max_range``.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.fast.rays import Scene, body_hits

__all__ = ["ConeModel", "ConeRays", "cone_model", "cone_ranges", "cone_rays_of", "read_cone", "read_ideal"]


class ConeRays(NamedTuple):
    """The cones' rays fixed in the body frame, sensor by sensor: ``starts`` and ``directions``
    (4 rays, 3), their own-box hit ``self_fraction`` (4 rays,; ``inf`` none) and ``self_normal``."""

    starts: Array
    directions: Array
    self_fraction: Array
    self_normal: Array


class ConeModel(NamedTuple):
    """The VL53L1X constants (host-side, :func:`cone_model`)."""

    rays: int
    reflectance: float
    gain: float
    snr_min: float
    ambient: float
    sigma_floor: float
    sigma_at_limit: float
    offset_sigma: float
    dropout: float
    min_range: float


def cone_model(model: Any) -> ConeModel:
    """The :class:`ConeModel` of a ``VL53L1X``-like object."""
    return ConeModel(
        int(model.rays),
        float(model.reflectance),
        float(model.flat_gain),
        float(model.snr_min),
        float(model.ambient * model.strong_ambient),
        float(model.sigma_floor),
        float(model.sigma_at_limit),
        float(model.offset_sigma),
        float(model.dropout),
        float(model.min_range),
    )


def cone_ranges(
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    rays: ConeRays,
    max_range: float,
    scene: Scene,
    model: ConeModel,
) -> tuple[Array, Array]:
    """Noise-free readings (4,) m (NaN where nothing is hit) and total signals (4,) of the cones."""
    h, dirs = body_hits(
        position,
        rotation,
        deck_position,
        deck_rotation,
        rays.starts,
        rays.directions,
        max_range,
        scene,
        rays.self_fraction,
        rays.self_normal,
    )
    r = jnp.where(h.hit, jnp.maximum(h.fraction * max_range, 1e-4), 1.0)
    cos_i = jnp.abs(h.normal[:, 0] * dirs[:, 0] + h.normal[:, 1] * dirs[:, 1] + h.normal[:, 2] * dirs[:, 2])
    signal = jnp.where(h.hit, model.reflectance * cos_i / r**2, 0.0).reshape(4, model.rays)
    lengths = jnp.where(h.hit, r, jnp.nan).reshape(4, model.rays)
    total = jnp.sum(signal, axis=1)
    weighted = jnp.sum(jnp.where(jnp.isnan(lengths), 0.0, signal * lengths), axis=1)
    mean = weighted / jnp.where(total > 0, total, 1.0) / model.gain
    return jnp.where(total > 0, mean, jnp.nan), total / model.rays


def read_cone(
    mean: Array, signal: Array, offset: Array, z: Array, u: Array, model: ConeModel, max_range: float
) -> tuple[Array, Array]:
    """The VL53L1X reading of the noise-free ``mean`` and ``signal`` (4,): ``offset`` (4,) m the
    sensors' constant offsets, ``z`` (4,) standard normals, ``u`` (4,) uniforms on [0, 1) (the
    dropout). Returns (ranges (4,), valid (4,))."""
    snr = signal / jnp.sqrt(signal + model.ambient + 1e-300)
    hit = (signal > 0) & (snr >= model.snr_min)
    lost = u < model.dropout
    s = jnp.maximum(signal, 1e-12)
    snr_s = s / jnp.sqrt(s + model.ambient)
    sigma = jnp.sqrt(model.sigma_floor**2 + (model.sigma_at_limit * model.snr_min / snr_s) ** 2)
    ranges = jnp.where(hit, mean, max_range) + offset + z * sigma
    valid = hit & ~lost & (ranges >= model.min_range) & (ranges <= max_range)
    return jnp.where(valid, ranges, max_range), valid


def read_ideal(ranges: Array, hit: Array, max_range: float) -> tuple[Array, Array]:
    """The ideal model's reading of the true ranges and hit flags (4,)."""
    valid = hit & (ranges >= 0.0) & (ranges <= max_range)
    return jnp.where(valid, ranges, max_range), valid


def cone_rays_of(
    starts: np.ndarray, directions: np.ndarray, self_fraction: np.ndarray, self_normal: np.ndarray
) -> ConeRays:
    """:class:`ConeRays` of host arrays (e.g. ``ClosedFormToF._cone``)."""
    return ConeRays(
        jnp.asarray(starts), jnp.asarray(directions), jnp.asarray(self_fraction), jnp.asarray(self_normal)
    )
