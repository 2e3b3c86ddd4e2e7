"""The range -> touch-pixel table (:class:`~ihrcf_env.core.calibration.tables.RangePixelTable`) as
arrays, and its lookup for one frame: the same cubic pieces, clamping and flags as
:meth:`RangePixelTable.__call__ <ihrcf_env.core.calibration.tables.RangePixelTable.__call__>`
(m in, px out)."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.calibration.tables import RangePixelTable

__all__ = ["TouchTableArrays", "lookup", "touch_table"]


class TouchTableArrays(NamedTuple):
    """Per sensor (ps1..ps4): ``breaks`` (4, M) increasing ranges (m; padded with the last one),
    ``coef`` (4, M - 1, 2, 4) cubic coefficients of (u, v) in powers 3..0 of ``d - break`` (padded
    with zeros), ``pieces`` (4,) the number of real pieces, ``lo`` / ``hi`` (4,) the table's span."""

    breaks: Array
    coef: Array
    pieces: Array
    lo: Array
    hi: Array


def touch_table(table: RangePixelTable) -> TouchTableArrays:
    """The arrays of a :class:`RangePixelTable` (host-side, once per calibration)."""
    if not isinstance(table, RangePixelTable):
        raise TypeError(f"table must be a RangePixelTable, got {type(table).__name__}")
    breaks = [np.array(t._breaks, dtype=np.float64) for t in table.tables]
    coefs = [np.array(t._pieces, dtype=np.float64) for t in table.tables]  # (M - 1, 2, 4)
    m = max(len(b) for b in breaks)
    B = np.stack([np.concatenate([b, np.full(m - len(b), b[-1])]) for b in breaks])
    C = np.stack([np.concatenate([c, np.zeros((m - 1 - len(c), 2, 4))]) for c in coefs])
    pieces = np.array([len(c) for c in coefs])
    return TouchTableArrays(
        jnp.asarray(B),
        jnp.asarray(C),
        jnp.asarray(pieces),
        jnp.asarray(B[:, 0]),
        jnp.asarray([b[-1] for b in breaks]),
    )


def lookup(table: TouchTableArrays, ranges: Array) -> tuple[Array, Array]:
    """Touch pixels (4, 2) and in-span flags (4,) of ``ranges`` (4,) (m) of ps1..ps4: readings out of
    the span are clamped to its nearer end and flagged, NaN reads as the far end."""
    lo, hi = table.lo, table.hi
    inside = (lo <= ranges) & (ranges <= hi)
    d = jnp.minimum(jnp.maximum(jnp.where(jnp.isnan(ranges), hi, ranges), lo), hi)

    def one(b: Array, dj: Array, pieces: Array, coef: Array) -> Array:
        i = jnp.clip(jnp.searchsorted(b, dj, side="right") - 1, 0, pieces - 1)
        x = dj - b[i]
        c = coef[i]  # (2, 4)
        return ((c[:, 0] * x + c[:, 1]) * x + c[:, 2]) * x + c[:, 3]

    # the four sensors' tables in one call
    return jax.vmap(one)(table.breaks, d, table.pieces, table.coef), inside
