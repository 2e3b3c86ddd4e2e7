"""The range -> touch-pixel table (:class:`~ihrcf_env.core.calibration.tables.RangePixelTable`)
evaluated on N readings per sensor at once."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.calibration.tables import RangePixelTable

F64 = NDArray[np.float64]

#: A batched touch-pixel table: ranges (N, 4) (m) -> touch pixels (N, 4, 2) and (N, 4) "inside".
BatchTouchPixels = Callable[[F64], tuple[F64, NDArray[np.bool_]]]


class _Single(Protocol):
    def __call__(self, ranges: F64) -> tuple[F64, NDArray[np.bool_]]: ...


class BatchTable:
    """A :class:`RangePixelTable` evaluated on (N, 4) readings: the same cubic pieces, breaks and
    clamping as :meth:`SensorTable.pixel` (out-of-span readings clamped to the nearer end and
    flagged; NaN read as the far end), so each row equals the single lookup."""

    def __init__(self, table: RangePixelTable) -> None:
        self.table = table
        self._breaks = [np.array(t._breaks) for t in table.tables]
        # (M - 1, 2, 4): per piece, u / v coefficients of powers 3..0 of (d - break)
        self._coef = [np.array(t._pieces) for t in table.tables]

    def __call__(self, ranges: F64) -> tuple[F64, NDArray[np.bool_]]:
        """Touch pixels (N, 4, 2) and in-span flags (N, 4) of ranges (N, 4) (m) of ps1..ps4."""
        d_all = np.asarray(ranges, dtype=np.float64)
        if d_all.ndim != 2 or d_all.shape[1] != 4:
            raise ValueError(f"ranges must have shape (N, 4) (ps1..ps4), got {d_all.shape}")
        uv = np.empty(d_all.shape + (2,))
        inside = np.empty(d_all.shape, dtype=bool)
        for j, (breaks, coef) in enumerate(zip(self._breaks, self._coef, strict=True)):
            lo, hi = breaks[0], breaks[-1]
            d = d_all[:, j]
            with np.errstate(invalid="ignore"):
                inside[:, j] = (lo <= d) & (d <= hi)
            d = np.minimum(np.maximum(np.where(np.isnan(d), hi, d), lo), hi)
            i = np.clip(np.searchsorted(breaks, d, side="right") - 1, 0, len(coef) - 1)
            x = d - breaks[i]
            c = coef[i]  # (N, 2, 4)
            uv[:, j, :] = ((c[:, :, 0] * x[:, None] + c[:, :, 1]) * x[:, None] + c[:, :, 2]) * x[:, None] + c[
                :, :, 3
            ]
        return uv, inside


def batch_table(touch_pixels: RangePixelTable | BatchTable | _Single | BatchTouchPixels) -> BatchTouchPixels:
    """A batched touch-pixel table: :class:`BatchTable` of a :class:`RangePixelTable`, a
    :class:`BatchTable` as is, or any single-frame table (ranges (4,) -> ((4, 2), (4,))) called once
    per row (a fallback for tests and custom tables, not vectorised)."""
    if isinstance(touch_pixels, BatchTable):
        return touch_pixels
    if isinstance(touch_pixels, RangePixelTable):
        return BatchTable(touch_pixels)
    single = touch_pixels

    def per_row(ranges: F64) -> tuple[F64, NDArray[np.bool_]]:
        out = [single(np.array(r)) for r in np.asarray(ranges, dtype=np.float64)]
        uv = np.array([np.asarray(o[0], dtype=np.float64) for o in out]).reshape(-1, 4, 2)
        return uv, np.array([np.asarray(o[1], dtype=bool) for o in out]).reshape(-1, 4)

    return per_row


__all__ = [
    "BatchTable",
    "BatchTouchPixels",
    "batch_table",
]
