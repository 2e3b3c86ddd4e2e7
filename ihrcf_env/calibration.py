"""Camera-range calibration maths of IHRCF (Sefidgar & Landry 2022, sections 2.1 and 2.2).

Pure numpy/scipy/cv2 (no simulator). Contents:

* Colour-pad segmentation: RGB -> YCbCr by eq. (2), the Table 1 thresholds, the largest blob's
  convex hull (eqs. 3-6) and its centroid (eq. 7).
* The range -> pixel lookup table: one PCHIP interpolant per ToF sensor (ps1..ps4) mapping a range
  reading ``d`` (m) to the pixel ``(u, v)`` where that sensor's beam touches the surface.
* Chessboard intrinsics (section 2.1), used by the AprilTag baseline (ATDA).
* :class:`Calibration`: the versioned calibration file (deterministic JSON).

Pixel convention everywhere: OpenCV pixel centres, ``u`` = column, ``v`` = row, pixel ``(r, c)``
has its centre at ``(u, v) = (c, r)``.
"""

from __future__ import annotations

import json
import math
import os
import types
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import PchipInterpolator

from ihrcf_env import __version__
from ihrcf_env.paths import assets_dir
from ihrcf_env.rig import PAD_COLOURS, SensorRig

#: Range-sensor names in rig order; sensor i is centred on pad ``PAD_COLOURS[i]``.
SENSOR_NAMES: tuple[str, str, str, str] = ("ps1", "ps2", "ps3", "ps4")

#: Version of the calibration file format written by :meth:`Calibration.save`.
FORMAT_VERSION: int = 1

# --------------------------------------------------------------------------------------------
# Colour segmentation
# --------------------------------------------------------------------------------------------

#: Eq. (2): ``[Y, Cb, Cr] = YCBCR_OFFSET + YCBCR_MATRIX @ [R, G, B]`` with R, G, B in [0, 1].
YCBCR_MATRIX: NDArray[np.float64] = np.array(
    [[65.481, 128.553, 24.966], [-37.797, -74.203, 112.0], [112.0, -93.786, -18.214]]
)
YCBCR_OFFSET: NDArray[np.float64] = np.array([16.0, 128.0, 128.0])

#: Table 1 of the paper: colour -> ((Y_lo, Y_hi), (Cb_lo, Cb_hi), (Cr_lo, Cr_hi)), inclusive bounds.
YCBCR_THRESHOLDS: Mapping[str, tuple[tuple[float, float], tuple[float, float], tuple[float, float]]] = (
    types.MappingProxyType(
        {
            "blue": ((0.0, 165.0), (139.0, 255.0), (0.0, 255.0)),
            "green": ((0.0, 255.0), (0.0, 155.0), (0.0, 90.0)),
            "yellow": ((103.0, 255.0), (0.0, 95.0), (0.0, 255.0)),
            "red": ((0.0, 160.0), (0.0, 255.0), (167.0, 255.0)),
        }
    )
)


def rgb_to_ycbcr(image: ArrayLike) -> NDArray[np.float64]:
    """Convert an RGB image to YCbCr by eq. (2) (ITU-R BT.601, studio swing).

    Args:
        image: (H, W, 3) RGB, either ``uint8`` (0..255) or float in [0, 1].

    Returns:
        (H, W, 3) float64 ``(Y, Cb, Cr)``; Y in [16, 235], Cb and Cr in [16, 240].
    """
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 3:
        hint = " (drop the alpha channel of an RGBA image with image[..., :3])" if a.ndim == 3 else ""
        raise ValueError(f"image must be an (H, W, 3) RGB array, got shape {a.shape}{hint}")
    if a.dtype == np.uint8:
        rgb = a.astype(np.float64) / 255.0
    elif np.issubdtype(a.dtype, np.floating):
        rgb = a.astype(np.float64)
        if not np.all(np.isfinite(rgb)) or rgb.min(initial=0.0) < 0.0 or rgb.max(initial=0.0) > 1.0:
            raise ValueError("a float image must hold finite values in [0, 1] (uint8 images use 0..255)")
    else:
        raise ValueError(f"image must be uint8 or float in [0, 1], got dtype {a.dtype}")
    return rgb @ YCBCR_MATRIX.T + YCBCR_OFFSET


def _thresholds(colour: str) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
    try:
        return YCBCR_THRESHOLDS[colour]
    except KeyError:
        known = tuple(YCBCR_THRESHOLDS)
        raise ValueError(f"unknown pad colour {colour!r}; expected one of {known}") from None


def ycbcr_mask(ycbcr: ArrayLike, colour: str) -> NDArray[np.bool_]:
    """(H, W) bool mask of the pixels of a YCbCr image inside ``colour``'s Table 1 box."""
    y = np.asarray(ycbcr, dtype=np.float64)
    if y.ndim != 3 or y.shape[2] != 3:
        raise ValueError(f"ycbcr must have shape (H, W, 3), got {y.shape}")
    mask = np.ones(y.shape[:2], dtype=bool)
    for ch, (lo, hi) in enumerate(_thresholds(colour)):
        mask &= (y[..., ch] >= lo) & (y[..., ch] <= hi)
    return mask


def colour_mask(image: ArrayLike, colour: str) -> NDArray[np.bool_]:
    """(H, W) bool mask of the RGB ``image`` pixels that pass ``colour``'s Table 1 thresholds."""
    return ycbcr_mask(rgb_to_ycbcr(image), colour)


@dataclass(frozen=True, eq=False)
class PadDetection:
    """A segmented calibration pad.

    Attributes:
        centroid: (2,) ``(u, v)`` pixel centroid (OpenCV pixel centres) of the filled convex hull, eq. (7).
        area_px: number of pixels of the filled convex hull.
        mask: (H, W) bool filled convex hull.
    """

    centroid: NDArray[np.float64]
    area_px: int
    mask: NDArray[np.bool_]


def _fill_convex(hull: NDArray[np.float64], h: int, w: int) -> NDArray[np.bool_]:
    """(h, w) mask of the pixel centres inside or on a convex polygon ``hull`` (K, 2) of (x, y) pixels.

    The exact digital convex hull: unlike ``cv2.fillConvexPoly``, whose edge rasterisation adds
    pixels on one side and biases the centroid by ~0.1 px, it is symmetric, so eq. (7) stays unbiased.
    A degenerate (collinear) hull gives an empty mask; the caller adds the blob's own pixels.
    """
    x, y = hull[:, 0], hull[:, 1]
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if hull.shape[0] < 3 or abs(area2) < 1e-9:
        return np.zeros((h, w), dtype=bool)
    if area2 < 0:  # make the interior lie where cross(edge, p - start) >= 0
        hull = hull[::-1]
    start = hull
    edge = np.roll(hull, -1, axis=0) - hull
    rows = np.arange(h, dtype=np.float64)
    lo = np.full(h, -np.inf)
    hi = np.full(h, np.inf)
    row_ok = np.ones(h, dtype=bool)
    eps = 1e-9
    for (x0, y0), (ex, ey) in zip(start, edge, strict=True):
        if ey == 0.0:  # horizontal edge: a constraint on the row only
            row_ok &= ex * (rows - y0) >= -eps
            continue
        bound = x0 + ex * (rows - y0) / ey
        if ey > 0:
            hi = np.minimum(hi, bound + eps)
        else:
            lo = np.maximum(lo, bound - eps)
    cols = np.arange(w, dtype=np.float64)[None, :]
    return row_ok[:, None] & (cols >= lo[:, None]) & (cols <= hi[:, None])


def segment_mask(mask: ArrayLike, min_area_px: int = 20) -> PadDetection | None:
    """Largest connected blob of a binary mask -> filled convex hull -> centroid (eqs. 3-7).

    Returns None when there is no blob, when the filled hull has fewer than ``min_area_px`` pixels,
    or when the largest blob touches the image border: a pad cut by the image edge has a centroid
    biased towards the image centre, which would poison the range -> pixel table. (Smaller blobs
    are never promoted in that case: the largest blob is taken to be the pad.)
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must have shape (H, W), got {m.shape}")
    m8 = (m != 0).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(m8, connectivity=8)
    if n <= 1:
        return None
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x0, y0, w, h = (
        int(stats[k, i]) for i in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT)
    )
    H, W = m8.shape
    if x0 == 0 or y0 == 0 or x0 + w == W or y0 + h == H:
        return None
    blob = (labels[y0 : y0 + h, x0 : x0 + w] == k).astype(np.uint8)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    hull = cv2.convexHull(np.concatenate(contours, axis=0)).reshape(-1, 2).astype(np.float64)
    filled = _fill_convex(hull, h, w) | (blob != 0)
    rows, cols = np.nonzero(filled)
    area = int(rows.size)
    if area < min_area_px:
        return None
    full = np.zeros((H, W), dtype=bool)
    full[y0 : y0 + h, x0 : x0 + w] = filled.astype(bool)
    centroid = np.array([cols.mean() + x0, rows.mean() + y0], dtype=np.float64)
    return PadDetection(centroid=centroid, area_px=area, mask=full)


def segment_pad(image: ArrayLike, colour: str, min_area_px: int = 20) -> PadDetection | None:
    """Find the ``colour`` pad in an RGB image: Table 1 threshold, then :func:`segment_mask`."""
    return segment_mask(colour_mask(image, colour), min_area_px=min_area_px)


def segment_pads(image: ArrayLike, min_area_px: int = 20) -> dict[str, PadDetection | None]:
    """All four pads (``PAD_COLOURS`` order) of an RGB image, converting to YCbCr only once.

    Table 1's boxes overlap: a bright green such as rendered (0, 1, 0) also passes the yellow box,
    so the yellow "pad" can come out as the green one. Use a green pad of about (0, 0.8, 0) (see
    the tests and FIELD-NOTES) so each rendered pad falls in its own box only.
    """
    ycc = rgb_to_ycbcr(image)
    return {c: segment_mask(ycbcr_mask(ycc, c), min_area_px=min_area_px) for c in PAD_COLOURS}


# --------------------------------------------------------------------------------------------
# Range -> pixel lookup tables
# --------------------------------------------------------------------------------------------


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

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "ranges": self._ranges.tolist(), "pixels": self._pixels.tolist()}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SensorTable:
        return cls(d["ranges"], d["pixels"], name=d.get("name", "sensor"))

    def __repr__(self) -> str:
        lo, hi = self.span
        return f"SensorTable({self.name!r}, {self._ranges.size} samples, {lo:.4g}..{hi:.4g} m)"


class RangePixelTable:
    """The four sensor tables ps1..ps4 (rig order): range readings (4,) -> touch pixels (4, 2)."""

    def __init__(self, tables: Sequence[SensorTable]) -> None:
        tables = tuple(tables)
        if len(tables) != 4 or not all(isinstance(t, SensorTable) for t in tables):
            raise ValueError(f"RangePixelTable needs 4 SensorTable (ps1..ps4), got {len(tables)} items")
        self.tables: tuple[SensorTable, SensorTable, SensorTable, SensorTable] = tables  # type: ignore[assignment]

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
        uv = np.empty((4, 2))
        ok = np.empty(4, dtype=bool)
        for i, t in enumerate(self.tables):
            p, f = t(d[i : i + 1])
            uv[i], ok[i] = p[0], f[0]
        return uv, ok

    def to_dict(self) -> dict[str, Any]:
        return {name: t.to_dict() for name, t in zip(SENSOR_NAMES, self.tables, strict=True)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RangePixelTable:
        tables = []
        for name in SENSOR_NAMES:
            if name not in d:
                raise ValueError(f"tables: missing sensor {name!r}")
            sd = d[name]
            tables.append(SensorTable(sd["ranges"], sd["pixels"], name=name))
        return cls(tables)

    def __repr__(self) -> str:
        return "RangePixelTable(" + ", ".join(repr(t) for t in self.tables) + ")"


# --------------------------------------------------------------------------------------------
# Chessboard intrinsics (section 2.1)
# --------------------------------------------------------------------------------------------


def find_chessboard(gray: ArrayLike, pattern: tuple[int, int] = (7, 9)) -> NDArray[np.float64] | None:
    """Inner chessboard corners of an image, refined to sub-pixel, or None.

    Args:
        gray: (H, W) uint8 grey image ((H, W, 3) RGB is converted).
        pattern: inner corners per row and per column (paper: 7 x 9).

    Returns:
        (pattern[0] * pattern[1], 2) float64 ``(u, v)`` in OpenCV's order (row by row, matching
        :func:`chessboard_object_points`), or None when the board is not found.
    """
    g = np.asarray(gray)
    if g.ndim == 3 and g.shape[2] == 3:
        g = cv2.cvtColor(np.ascontiguousarray(g), cv2.COLOR_RGB2GRAY)
    if g.ndim != 2 or g.dtype != np.uint8:
        raise ValueError(f"gray must be an (H, W) uint8 image, got shape {g.shape} dtype {g.dtype}")
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(g, tuple(pattern), flags=flags)
    if not found:
        return None
    pts = corners.reshape(-1, 2)
    grid = pts.reshape(pattern[1], pattern[0], 2)
    spacing = min(
        float(np.min(np.linalg.norm(np.diff(grid, axis=1), axis=2))),
        float(np.min(np.linalg.norm(np.diff(grid, axis=0), axis=2))),
    )
    win = int(max(2, min(11, math.floor(spacing / 2 - 1))))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-4)
    refined = cv2.cornerSubPix(g, corners.astype(np.float32), (win, win), (-1, -1), criteria)
    return refined.reshape(-1, 2).astype(np.float64)


def chessboard_object_points(pattern: tuple[int, int], square: float) -> NDArray[np.float64]:
    """(N, 3) inner-corner coordinates in the board frame (m), z = 0, x along ``pattern[0]``."""
    nx, ny = int(pattern[0]), int(pattern[1])
    if nx < 2 or ny < 2:
        raise ValueError(f"pattern must have at least 2 x 2 inner corners, got {pattern}")
    if not (math.isfinite(square) and square > 0):
        raise ValueError(f"square must be a positive length in metres, got {square!r}")
    xx, yy = np.meshgrid(np.arange(nx), np.arange(ny))
    return np.column_stack([xx.ravel(), yy.ravel(), np.zeros(nx * ny)]) * np.array([square, square, 1.0])


@dataclass(frozen=True, eq=False)
class IntrinsicsResult:
    """Result of :func:`calibrate_intrinsics`: ``K`` (3, 3), ``dist`` (5,) (k1, k2, p1, p2, k3),
    ``rms`` reprojection error (px) and the number of views used."""

    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    rms: float
    n_views: int


def calibrate_intrinsics(
    image_points: Sequence[ArrayLike],
    pattern: tuple[int, int],
    square: float,
    image_size: tuple[int, int],
    flags: int = 0,
) -> IntrinsicsResult:
    """Zhang calibration (``cv2.calibrateCamera``) from chessboard corners of several views.

    Args:
        image_points: per view, (N, 2) corners as returned by :func:`find_chessboard`.
        pattern: inner corners per row and column.
        square: square side (m).
        image_size: ``(width, height)`` in pixels.
        flags: ``cv2.CALIB_*`` flags passed through.
    """
    if len(image_points) < 3:
        raise ValueError(f"calibrate_intrinsics needs at least 3 chessboard views, got {len(image_points)}")
    obj = chessboard_object_points(pattern, square).astype(np.float32)
    n = obj.shape[0]
    imgs = []
    for i, p in enumerate(image_points):
        a = np.asarray(p, dtype=np.float32)
        if a.shape != (n, 2):
            raise ValueError(f"image_points[{i}] must have shape ({n}, 2), got {a.shape}")
        imgs.append(a.reshape(-1, 1, 2))
    rms, K, dist, _, _ = cv2.calibrateCamera(
        [obj] * len(imgs), imgs, (int(image_size[0]), int(image_size[1])), None, None, flags=flags
    )
    d = np.zeros(5)
    dr = np.asarray(dist, dtype=np.float64).ravel()[:5]
    d[: dr.size] = dr
    return IntrinsicsResult(K=np.asarray(K, dtype=np.float64), dist=d, rms=float(rms), n_views=len(imgs))


# --------------------------------------------------------------------------------------------
# Calibration file
# --------------------------------------------------------------------------------------------


class CalibrationError(ValueError):
    """A calibration file is missing, unreadable, malformed, or made for another camera/rig."""


def default_calibration_path() -> Path:
    """The calibration file shipped with the package (``assets/calibration_default.json``)."""
    return assets_dir() / "calibration_default.json"


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} in JSON")


_REQUIRED_KEYS = (
    "image_width",
    "image_height",
    "fov",
    "rig",
    "tables",
    "K",
    "dist",
    "chessboard_rms",
    "seed",
    "created_with",
    "report",
)


@dataclass(eq=False)
class Calibration:
    """Versioned calibration file of one camera configuration and rig.

    Attributes:
        image_width, image_height: image size (px) the file was made for.
        fov: vertical field of view (rad) the file was made for.
        rig: :meth:`ihrcf_env.rig.SensorRig.to_dict` of the rig.
        tables: the range -> pixel tables ps1..ps4.
        K: (3, 3) intrinsics from the chessboard stage (section 2.1; used by ATDA).
        dist: (5,) distortion (k1, k2, p1, p2, k3).
        chessboard_rms: reprojection RMS (px) of the chessboard calibration, None if skipped.
        seed: RNG seed of the calibration run (None if unseeded).
        created_with: producer string, e.g. ``"ihrcf_env 0.1.0"``.
        report: free JSON-serialisable dict (stages used/skipped, measurements).
        lens_distortion: (k1, k2) radial distortion of the simulated camera the file was made for
            (the camera's property, like ``fov``; ``dist`` is what the chessboard estimated).
        format_version: file format version (:data:`FORMAT_VERSION`).
        source: file this was loaded from (not serialised).
    """

    image_width: int
    image_height: int
    fov: float
    rig: dict[str, Any]
    tables: RangePixelTable
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    chessboard_rms: float | None = None
    seed: int | None = None
    created_with: str = f"ihrcf_env {__version__}"
    report: dict[str, Any] = field(default_factory=dict)
    lens_distortion: tuple[float, float] = (0.0, 0.0)
    format_version: int = FORMAT_VERSION
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        self.image_width, self.image_height = int(self.image_width), int(self.image_height)
        if self.image_width <= 0 or self.image_height <= 0:
            raise ValueError(f"image size must be positive, got {self.image_width}x{self.image_height}")
        self.fov = float(self.fov)
        k = np.asarray(self.lens_distortion, dtype=np.float64)
        if k.shape != (2,) or not np.all(np.isfinite(k)):
            raise ValueError(
                f"lens_distortion must be two finite numbers (k1, k2), got {self.lens_distortion!r}"
            )
        self.lens_distortion = (float(k[0]), float(k[1]))
        if not (0.0 < self.fov < math.pi):
            raise ValueError(f"fov must be in (0, pi) rad, got {self.fov!r}")
        if not isinstance(self.tables, RangePixelTable):
            raise ValueError(f"tables must be a RangePixelTable, got {type(self.tables).__name__}")
        self.K = np.asarray(self.K, dtype=np.float64)
        self.dist = np.asarray(self.dist, dtype=np.float64)
        if self.K.shape != (3, 3) or not np.all(np.isfinite(self.K)):
            raise ValueError(f"K must be a finite (3, 3) matrix, got shape {self.K.shape}")
        if self.dist.shape != (5,) or not np.all(np.isfinite(self.dist)):
            raise ValueError(f"dist must be finite with shape (5,), got shape {self.dist.shape}")
        if self.chessboard_rms is not None:
            self.chessboard_rms = float(self.chessboard_rms)
            if not math.isfinite(self.chessboard_rms):
                raise ValueError("chessboard_rms must be finite or None")
        missing = [k for k in ("a", "theta", "camera_position") if k not in self.rig]
        if missing:
            raise ValueError(f"rig: missing key(s) {missing}")
        self.rig = {
            "a": float(self.rig["a"]),
            "theta": float(self.rig["theta"]),
            "camera_position": [float(x) for x in self.rig["camera_position"]],
        }
        SensorRig(self.rig["a"], self.rig["theta"], tuple(self.rig["camera_position"]))  # validates

    def to_dict(self) -> dict[str, Any]:
        return {
            "format_version": self.format_version,
            "image_width": self.image_width,
            "image_height": self.image_height,
            "fov": self.fov,
            "lens_distortion": list(self.lens_distortion),
            "rig": self.rig,
            "tables": self.tables.to_dict(),
            "K": self.K.tolist(),
            "dist": self.dist.tolist(),
            "chessboard_rms": self.chessboard_rms,
            "seed": self.seed,
            "created_with": self.created_with,
            "report": self.report,
        }

    def to_json(self) -> str:
        """Deterministic JSON: sorted keys, floats by ``repr`` (exact round trip), no NaN/inf."""
        try:
            return (
                json.dumps(self.to_dict(), sort_keys=True, indent=1, allow_nan=False, default=_json_default)
                + "\n"
            )
        except ValueError as e:
            raise ValueError(f"calibration contains a non-finite number (report?): {e}") from e

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the calibration file; the same contents always give byte-identical files."""
        p = Path(path)
        text = self.to_json()
        if p.parent != Path(""):
            p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(p.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, p)
        return p

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], source: str = "<dict>") -> Calibration:
        """Validate and build; raises :class:`CalibrationError` naming ``source`` and the problem."""
        if not isinstance(d, Mapping):
            raise CalibrationError(f"{source}: expected a JSON object, got {type(d).__name__}")
        if "format_version" not in d:
            raise CalibrationError(f"{source}: missing 'format_version' (not an ihrcf_env calibration file?)")
        if d["format_version"] != FORMAT_VERSION:
            raise CalibrationError(
                f"{source}: unsupported format_version {d['format_version']!r} (this ihrcf_env reads "
                f"{FORMAT_VERSION}); re-create it with python -m ihrcf_env.calibrate"
            )
        missing = [k for k in _REQUIRED_KEYS if k not in d]
        if missing:
            raise CalibrationError(f"{source}: missing key(s) {missing}")
        try:
            tables = RangePixelTable.from_dict(d["tables"])
        except (ValueError, KeyError, TypeError) as e:
            raise CalibrationError(f"{source}: bad 'tables': {e}") from e
        if not isinstance(d["report"], dict):
            raise CalibrationError(f"{source}: 'report' must be an object")
        try:
            return cls(
                image_width=d["image_width"],
                image_height=d["image_height"],
                fov=d["fov"],
                rig=d["rig"],
                tables=tables,
                K=d["K"],
                dist=d["dist"],
                chessboard_rms=d["chessboard_rms"],
                seed=d["seed"],
                created_with=str(d["created_with"]),
                report=dict(d["report"]),
                lens_distortion=tuple(d.get("lens_distortion", (0.0, 0.0))),
                format_version=d["format_version"],
                source=source,
            )
        except (ValueError, KeyError, TypeError) as e:
            raise CalibrationError(f"{source}: {e}") from e

    @classmethod
    def load(cls, path: str | os.PathLike[str] | Traversable) -> Calibration:
        """Read and validate a calibration file; :class:`CalibrationError` naming the file otherwise."""
        name = str(path)
        try:
            if isinstance(path, str | os.PathLike):
                text = Path(path).read_text(encoding="utf-8")
            else:
                text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise CalibrationError(
                f"{name}: calibration file not found; create one with python -m ihrcf_env.calibrate"
            ) from None
        except (OSError, UnicodeDecodeError) as e:
            raise CalibrationError(f"{name}: cannot read calibration file: {e}") from e
        try:
            data = json.loads(text, parse_constant=_reject_constant)
        except ValueError as e:
            raise CalibrationError(f"{name}: not a valid calibration JSON file: {e}") from e
        return cls.from_dict(data, source=name)

    def matches(
        self,
        width: int,
        height: int,
        fov: float,
        rig: SensorRig | Mapping[str, Any],
        distortion: tuple[float, float] = (0.0, 0.0),
    ) -> list[str]:
        """Human-readable differences between this file and a camera config / rig (empty if none)."""
        rd = dict(rig.to_dict() if isinstance(rig, SensorRig) else rig)
        diffs = []
        if not np.allclose(
            np.asarray(distortion, dtype=np.float64), self.lens_distortion, rtol=0.0, atol=1e-12
        ):
            theirs = tuple(float(x) for x in distortion)
            diffs.append(f"lens distortion (k1, k2) {self.lens_distortion} in the file vs {theirs}")
        if (int(width), int(height)) != (self.image_width, self.image_height):
            diffs.append(f"image size {self.image_width}x{self.image_height} in the file vs {width}x{height}")
        if not math.isclose(float(fov), self.fov, rel_tol=0.0, abs_tol=1e-8):
            diffs.append(f"fov {math.degrees(self.fov):.10g} deg in the file vs {math.degrees(fov):.10g} deg")
        for key in ("a", "theta"):
            if not math.isclose(float(rd[key]), self.rig[key], rel_tol=0.0, abs_tol=1e-9):
                diffs.append(f"rig {key} {self.rig[key]!r} in the file vs {float(rd[key])!r}")
        cp = np.asarray(rd["camera_position"], dtype=np.float64)
        if cp.shape != (3,) or not np.allclose(cp, self.rig["camera_position"], rtol=0.0, atol=1e-9):
            diffs.append(f"rig camera_position {self.rig['camera_position']} in the file vs {cp.tolist()}")
        return diffs

    def check_matches(
        self,
        width: int,
        height: int,
        fov: float,
        rig: SensorRig | Mapping[str, Any],
        output: str | os.PathLike[str] | None = None,
        distortion: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Raise :class:`CalibrationError` if the file was made for another camera config (px, rad) or rig.

        The message gives the command that produces a matching file; ``output`` is the path to
        suggest in it (default ``calibration_<W>x<H>_fov<F>.json``).
        """
        diffs = self.matches(width, height, fov, rig, distortion)
        if not diffs:
            return
        fov_deg = f"{math.degrees(fov):.10g}"
        out = str(output) if output is not None else f"calibration_{width}x{height}_fov{fov_deg}.json"
        k1, k2 = (float(x) for x in distortion)
        lens = f" --k1 {k1:.10g} --k2 {k2:.10g}" if (k1, k2) != (0.0, 0.0) else ""
        cmd = (
            f"python -m ihrcf_env.calibrate --width {width} --height {height} --fov-deg {fov_deg}{lens} "
            f"--output {out}"
        )
        rig_note = " (with the same rig settings)" if any(s.startswith("rig") for s in diffs) else ""
        raise CalibrationError(
            f"calibration file {self.source or '<in memory>'} does not match the requested configuration: "
            + "; ".join(diffs)
            + f". Produce a matching file with:\n    {cmd}{rig_note}"
        )
