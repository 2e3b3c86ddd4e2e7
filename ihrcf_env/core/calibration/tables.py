"""The range -> pixel lookup table (paper section 2.2): one PCHIP interpolant per ToF sensor
(ps1..ps4) mapping a range reading ``d`` (m) to the pixel ``(u, v)`` where that sensor's beam
touches the surface.

Pixel convention everywhere: OpenCV pixel centres, ``u`` = column, ``v`` = row, pixel ``(r, c)``
has its centre at ``(u, v) = (c, r)``.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import PchipInterpolator

from ihrcf_env.core.calibration._checks import check_keys, check_real_array
from ihrcf_env.core.checks import describe

#: Longest range of a table sample in a calibration file (m): far beyond any ToF sensor's reach.
MAX_TABLE_RANGE = 100.0
#: Largest magnitude of a table pixel coordinate in a calibration file (px); the file also bounds
#: them by its image size (:class:`~ihrcf_env.core.calibration.file.Calibration`).
MAX_PIXEL = 1e6
#: Range-sensor names in rig order; sensor i is centred on pad ``PAD_COLOURS[i]``.
SENSOR_NAMES: tuple[str, str, str, str] = ("ps1", "ps2", "ps3", "ps4")


class SensorTable:
    """Range -> pixel table of one ToF sensor: PCHIP interpolation of ``u(d)`` and ``v(d)``.

    Built from samples ``ranges`` (N,) in metres and ``pixels`` (N, 2) ``(u, v)``: rows with a
    non-finite value are dropped, samples are sorted by range, samples with exactly equal ranges are
    merged (their pixels averaged), and at least 4 distinct ranges are required. The interpolant is
    :class:`scipy.interpolate.PchipInterpolator` (the paper's PCHIP) with ``extrapolate=False``.
    """

    def __init__(self, ranges: ArrayLike, pixels: ArrayLike, name: str = "sensor") -> None:
        self.name = str(name)
        r = np.asarray(ranges, dtype=np.float64)
        p = np.asarray(pixels, dtype=np.float64)
        if r.ndim != 1 or p.shape != (r.size, 2):
            raise ValueError(
                f"{self.name}: ranges must be (N,) and pixels (N, 2), got {r.shape} and {p.shape}"
            )
        ok = np.isfinite(r) & np.all(np.isfinite(p), axis=1)
        r, p = r[ok], p[ok]
        uniq, inverse, counts = np.unique(r, return_inverse=True, return_counts=True)
        if uniq.size < 4:
            raise ValueError(
                f"{self.name}: need at least 4 distinct finite range samples for PCHIP, got {uniq.size}"
            )
        merged = np.zeros((uniq.size, 2))
        np.add.at(merged, inverse, p)
        merged /= counts[:, None]
        self._ranges = uniq
        self._pixels = merged
        self._ranges.setflags(write=False)
        self._pixels.setflags(write=False)
        self._interp = PchipInterpolator(uniq, merged, axis=0, extrapolate=False)
        # the same cubic pieces as plain floats, for :meth:`pixel` (one reading, no numpy call)
        self._breaks: list[float] = uniq.tolist()
        coef = np.asarray(self._interp.c)  # (4, M - 1, 2): powers 3..0 of (d - break)
        self._pieces: list[tuple[tuple[float, ...], tuple[float, ...]]] = [
            (tuple(coef[:, i, 0].tolist()), tuple(coef[:, i, 1].tolist())) for i in range(uniq.size - 1)
        ]

    @property
    def ranges(self) -> NDArray[np.float64]:
        """(M,) strictly increasing table ranges (m)."""
        return self._ranges

    @property
    def pixels(self) -> NDArray[np.float64]:
        """(M, 2) table pixels ``(u, v)`` at :attr:`ranges`."""
        return self._pixels

    @property
    def span(self) -> tuple[float, float]:
        """``(d_min, d_max)`` (m): the ranges the table covers."""
        return float(self._ranges[0]), float(self._ranges[-1])

    def __call__(self, ranges: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Pixels of range readings: ``(uv (N, 2), in_range (N,))`` for ``ranges`` (N,) (m).

        Readings outside ``[d_min, d_max]`` are clamped to the nearer table end (NaN, e.g. a
        "no target" reading, to ``d_max``) and flagged ``in_range = False``: the output is never NaN.
        """
        d = np.atleast_1d(np.asarray(ranges, dtype=np.float64))
        if d.ndim != 1:
            raise ValueError(f"{self.name}: ranges must be (N,), got {d.shape}")
        lo, hi = self.span
        in_range = np.isfinite(d) & (d >= lo) & (d <= hi)
        dc = np.clip(np.where(np.isnan(d), hi, d), lo, hi)
        return np.asarray(self._interp(dc), dtype=np.float64), in_range

    def pixel(self, d: float) -> tuple[float, float, bool]:
        """``(u, v, in_range)`` of one reading ``d`` (m): :meth:`__call__` for a single value, in
        plain floats (the per-frame path of :class:`RangePixelTable`)."""
        breaks = self._breaks
        lo, hi = breaks[0], breaks[-1]
        in_range = lo <= d <= hi  # False for NaN
        d = hi if math.isnan(d) else min(max(d, lo), hi)
        i = min(max(bisect.bisect_right(breaks, d) - 1, 0), len(self._pieces) - 1)
        x = d - breaks[i]
        (a, b, c, e), (f, g, h, k) = self._pieces[i]
        return ((a * x + b) * x + c) * x + e, ((f * x + g) * x + h) * x + k, in_range

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "ranges": self._ranges.tolist(), "pixels": self._pixels.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], field: str = "table", name: str | None = None) -> SensorTable:
        """From :meth:`to_dict`'s JSON object, type-checked: ``ranges`` (N,) numbers in
        (0, :data:`MAX_TABLE_RANGE`] m and ``pixels`` (N, 2) numbers within +-:data:`MAX_PIXEL` px
        (no null: a missing sample is simply left out), optional ``name`` string (``name``
        overrides it). TypeError / ValueError naming ``field`` and the key otherwise."""
        check_keys(field, d, ("ranges", "pixels"), ("name",))
        stored = d.get("name", "sensor")
        if not isinstance(stored, str):
            raise TypeError(f"{field}.name must be a string, got {describe(stored)}")
        ranges = check_real_array(f"{field}.ranges", d["ranges"], (None,), "m", high=MAX_TABLE_RANGE)
        pixels = check_real_array(
            f"{field}.pixels", d["pixels"], (None, 2), "px", low=-MAX_PIXEL, high=MAX_PIXEL
        )
        if np.any(ranges <= 0):
            raise ValueError(f"{field}.ranges must be positive distances (m), got min {ranges.min()!r}")
        return cls(ranges, pixels, name=stored if name is None else name)

    def __repr__(self) -> str:
        lo, hi = self.span
        return f"SensorTable({self.name!r}, {self._ranges.size} samples, {lo:.4g}..{hi:.4g} m)"


class RangePixelTable:
    """The four sensor tables ps1..ps4 (rig order): range readings (4,) -> touch pixels (4, 2)."""

    def __init__(self, tables: Sequence[SensorTable]) -> None:
        t = tuple(tables)
        if len(t) != 4 or not all(isinstance(x, SensorTable) for x in t):
            raise ValueError(f"RangePixelTable needs 4 SensorTable (ps1..ps4), got {len(t)} items")
        self.tables: tuple[SensorTable, SensorTable, SensorTable, SensorTable] = (t[0], t[1], t[2], t[3])

    @classmethod
    def from_samples(cls, ranges: ArrayLike, pixels: ArrayLike) -> RangePixelTable:
        """Build from calibration stages: ``ranges`` (N, 4) (m) and ``pixels`` (N, 4, 2) ``(u, v)``.

        A stage where a pad was not found can carry NaN pixels; it is dropped for that sensor only.
        """
        r = np.asarray(ranges, dtype=np.float64)
        p = np.asarray(pixels, dtype=np.float64)
        if r.ndim != 2 or r.shape[1] != 4 or p.shape != (r.shape[0], 4, 2):
            raise ValueError(f"ranges must be (N, 4) and pixels (N, 4, 2), got {r.shape} and {p.shape}")
        return cls([SensorTable(r[:, i], p[:, i], name=SENSOR_NAMES[i]) for i in range(4)])

    @property
    def spans(self) -> NDArray[np.float64]:
        """(4, 2) ``(d_min, d_max)`` (m) per sensor."""
        return np.array([t.span for t in self.tables])

    def __call__(self, ranges: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """``(uv (4, 2), in_range (4,))`` for one reading per sensor ``ranges`` (4,) (m).

        Out-of-span or non-finite readings are clamped to the table end and flagged False
        (see :meth:`SensorTable.__call__`); the output is never NaN.
        """
        d = np.asarray(ranges, dtype=np.float64)
        if d.shape != (4,):
            raise ValueError(f"ranges must have shape (4,) (ps1..ps4), got {d.shape}")
        out = [t.pixel(x) for t, x in zip(self.tables, d.tolist(), strict=True)]
        return np.array([o[:2] for o in out]), np.array([o[2] for o in out])

    def to_dict(self) -> dict[str, Any]:
        return {name: t.to_dict() for name, t in zip(SENSOR_NAMES, self.tables, strict=True)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RangePixelTable:
        """From :meth:`to_dict`'s JSON object (keys ps1..ps4, see :meth:`SensorTable.from_dict`),
        type-checked; TypeError / ValueError naming the field (e.g. ``tables.ps2.pixels``)."""
        if not isinstance(d, Mapping):
            raise TypeError(f"tables must be an object, got {describe(d)}")
        missing = [name for name in SENSOR_NAMES if name not in d]
        if missing:
            raise ValueError(f"tables: missing sensor(s) {missing}")
        check_keys("tables", d, SENSOR_NAMES)
        return cls(
            [SensorTable.from_dict(d[name], field=f"tables.{name}", name=name) for name in SENSOR_NAMES]
        )

    def __repr__(self) -> str:
        return "RangePixelTable(" + ", ".join(repr(t) for t in self.tables) + ")"


__all__ = [
    "MAX_PIXEL",
    "MAX_TABLE_RANGE",
    "SENSOR_NAMES",
    "RangePixelTable",
    "SensorTable",
]
