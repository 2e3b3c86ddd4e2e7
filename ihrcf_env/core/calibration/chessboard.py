"""Chessboard intrinsics (paper section 2.1), used by the AprilTag baseline (ATDA).

Pixel convention everywhere: OpenCV pixel centres, ``u`` = column, ``v`` = row, pixel ``(r, c)``
has its centre at ``(u, v) = (c, r)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray


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


__all__ = [
    "IntrinsicsResult",
    "calibrate_intrinsics",
    "chessboard_object_points",
    "find_chessboard",
]
