"""The ``forecast.*`` observation block for one environment: the port of
:class:`ihrcf_env.wrappers.forecast_feed.ForecastFeed` over :mod:`ihrcf_env.fast.forecast`.

Once per control step, :func:`feed_step` integrates the navigation altitude (trapezoids of the
navigation vertical velocity), feeds the forecaster one sample when the fused filter took a new
camera frame and its estimate is valid (the deck's heave relative to the drone's altitude at reset,
and the deck normal's roll and pitch, in the level frame of fixed heading: the IMU's world axes),
and returns the block (``forecast_fields(H)``'s layout: per horizon the heave about the window
mean, heave rate, roll and pitch in the drone's heading frame, then their standard deviations, all
scaled; then ``quiet`` and ``valid``), clipped into its bounds. Every field is 0 until the
forecaster's first fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.forecast import ForecastOptions, forecast_options
from ihrcf_env.core.landing_layout import FORECAST_BOUNDS, FORECAST_SCALES
from ihrcf_env.core.quiescence import QuiescenceThresholds
from ihrcf_env.fast.forecast import (
    ForecastParams,
    ForecastState,
    forecast_init,
    forecast_out,
    forecast_params,
    forecast_update,
)
from ihrcf_env.fast.linalg3 import matrix_from_euler

__all__ = [
    "FeedOutput",
    "FeedParams",
    "FeedState",
    "feed_init",
    "feed_params",
    "feed_step",
]

# the block's scales and bounds per output column (the layout's, as the reference's)
_SCALES = FORECAST_SCALES
_BOUNDS = FORECAST_BOUNDS


@dataclass(frozen=True)
class FeedParams:
    """Host-side constants of the block: the forecaster's :class:`ForecastParams`, the fields'
    scales (4,) and the block's bounds ``low``, ``high`` (8 H + 2,)."""

    forecast: ForecastParams
    scales: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @property
    def size(self) -> int:
        """Length of the block (8 H + 2)."""
        return int(self.low.size)


class FeedState(NamedTuple):
    """The forecaster's state, the navigation ``altitude`` (m, relative to the drone's at reset),
    the previous step's ``time`` (s) and navigation vertical velocity ``vz`` (m/s) (``has_last``
    False before the first step) and the number of ``samples`` fed since reset."""

    forecaster: ForecastState
    altitude: Array
    time: Array
    vz: Array
    has_last: Array
    samples: Array


class FeedOutput(NamedTuple):
    """One step's block (8 H + 2,) and the unscaled forecast of ``info["forecast"]``: ``mean`` and
    ``std`` (H, 4) in the block's frames (zeros until valid), ``quiet`` and ``valid``."""

    block: Array
    mean: Array
    std: Array
    quiet: Array
    valid: Array


def feed_params(
    options: ForecastOptions | dict[str, Any] | None = None, length_scale: float = 30.0
) -> FeedParams:
    """The block's constants for ``options`` and the deck's Froude ``length_scale`` (the
    quiescence thresholds are ``QuiescenceThresholds().scaled(length_scale)``)."""
    o = forecast_options(options)
    prm = forecast_params(o, QuiescenceThresholds().scaled(length_scale))
    h = prm.horizons.size
    bounds = np.repeat(np.asarray(_BOUNDS), h)
    low = np.concatenate([-bounds, np.zeros(4 * h), [0.0, 0.0]])
    high = np.concatenate([bounds, bounds, [1.0, 1.0]])
    return FeedParams(prm, np.asarray(_SCALES), low, high)


def feed_init(fp: FeedParams, dtype: Any = None) -> FeedState:
    """The state at reset (no sample, navigation altitude 0)."""
    st = forecast_init(fp.forecast, dtype)
    f = st.acc.dtype
    return FeedState(
        forecaster=st,
        altitude=jnp.zeros((), f),
        time=jnp.zeros((), f),
        vz=jnp.zeros((), f),
        has_last=jnp.asarray(False),
        samples=jnp.zeros((), jnp.int_),
    )


def _sample(altitude: Array, fused: Any, R_lb: Array, R_lw: Array) -> Array:
    """(heave m, roll rad, pitch rad) of the fused deck pose in the level frame of fixed heading."""
    R_wb = R_lw.T @ R_lb
    p = R_wb @ fused.position
    n = R_wb @ matrix_from_euler(fused.euler)[:, 2]
    return jnp.stack([altitude + p[2], jnp.arctan2(-n[1], n[2]), jnp.arctan2(n[0], n[2])])


def feed_step(
    fp: FeedParams,
    st: FeedState,
    time: Array,
    nav_velocity_z: Array,
    fresh: Array,
    fused: Any,
    R_lb: Array,
    R_lw: Array,
) -> tuple[FeedState, FeedOutput]:
    """One control step at ``time`` (s): the navigation vertical velocity (m/s, world z),
    ``fresh`` True when the fused filter took a new camera frame this step, the fused estimate
    shown ``fused`` (anything with the deck's ``position`` (3,) m and ``euler`` (3,) rad in the body
    frame and ``valid``: a :class:`~ihrcf_env.fast.fused.FusedOutput` or the observation's
    estimate), the IMU's level-from-body ``R_lb`` and heading-from-world
    ``R_lw`` rotations (the observation's ``heading_rotation``)."""
    f = st.altitude.dtype
    time = jnp.asarray(time, f)
    vz_in = jnp.asarray(nav_velocity_z, f)
    vz = jnp.where(jnp.isfinite(vz_in), vz_in, 0.0)
    step = st.has_last & (time > st.time)
    altitude = jnp.where(step, st.altitude + 0.5 * (st.vz + vz) * (time - st.time), st.altitude)
    R_lb = jnp.asarray(R_lb, f)
    R_lw = jnp.asarray(R_lw, f)
    sample = _sample(altitude, fused, R_lb, R_lw)
    go = jnp.asarray(fresh, bool) & jnp.asarray(fused.valid, bool) & jnp.all(jnp.isfinite(sample))
    fed = forecast_update(fp.forecast, st.forecaster, time, jnp.where(go, sample, 0.0), jnp.asarray(True))
    fc = jax.tree.map(lambda a, b: jnp.where(go, a, b), fed, st.forecaster)
    st = FeedState(fc, altitude, time, vz, jnp.asarray(True), st.samples + go.astype(st.samples.dtype))
    out = forecast_out(fp.forecast, fc)
    mean = out.mean.at[:, 0].add(-fc.mu[0])
    R2 = R_lw[:2, :2]
    mean = mean.at[:, 2:4].set(mean[:, 2:4] @ R2.T)
    std = out.std.at[:, 2:4].set(jnp.sqrt(out.std[:, 2:4] ** 2 @ (R2**2).T))
    valid = out.valid & jnp.all(jnp.isfinite(mean)) & jnp.all(jnp.isfinite(std)) & jnp.isfinite(out.quiet)
    mean = jnp.where(valid, mean, 0.0)
    std = jnp.where(valid, std, 0.0)
    quiet = jnp.where(valid, out.quiet, 0.0)
    scales = jnp.asarray(fp.scales, f)
    block = jnp.concatenate(
        [(mean / scales).T.reshape(-1), (std / scales).T.reshape(-1), jnp.stack([quiet, valid.astype(f)])]
    )
    block = jnp.clip(block, jnp.asarray(fp.low, f), jnp.asarray(fp.high, f))
    return st, FeedOutput(block, mean, std, quiet, valid)
