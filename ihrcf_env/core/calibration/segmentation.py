"""Colour-pad segmentation (paper section 2.2): RGB -> YCbCr by eq. (2), the Table 1
thresholds, the largest blob's convex hull (eqs. 3-6) and its centroid (eq. 7).

Pixel convention everywhere: OpenCV pixel centres, ``u`` = column, ``v`` = row, pixel ``(r, c)``
has its centre at ``(u, v) = (c, r)``.
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.rig import PAD_COLOURS

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
        if not np.isfinite(rgb).all() or rgb.min(initial=0.0) < 0.0 or rgb.max(initial=0.0) > 1.0:
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


__all__ = [
    "YCBCR_MATRIX",
    "YCBCR_OFFSET",
    "YCBCR_THRESHOLDS",
    "PadDetection",
    "colour_mask",
    "rgb_to_ycbcr",
    "segment_mask",
    "segment_pad",
    "segment_pads",
    "ycbcr_mask",
]
