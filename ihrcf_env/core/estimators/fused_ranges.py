"""The fused estimator's range-only measurements: the deck plane from the ToF ranges alone.

In a frame without a tag measurement (tag out of view close to the deck, or lost), the ranges
still see the deck plane: its tilt (roll, pitch in the filter's world axes, with the filter's own
yaw) and its distance along its normal. :func:`ranges_plane` fits IHRCF's plane to the valid touch
points, :func:`ranges_tilt` turns its normal into a roll / pitch measurement and
:func:`ranges_distance` the plane of the filter's (updated) normal through the touch points into
one linear measurement of the relative position, ``h @ r = z``, that leaves the position along the
plane free (it coasts on the IMU). The filter (:mod:`~ihrcf_env.core.estimators.fused`) calls
these functions.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.geometry import _fit_plane

F64 = NDArray[np.float64]
_R_CAM_BODY = np.ascontiguousarray(R_BODY_CAM.T)


def ranges_plane(
    ranges: F64, valid: NDArray[np.bool_], sensor_xy: F64
) -> tuple[F64, NDArray[np.bool_]] | None:
    """IHRCF's deck plane through the valid touch points ``(x_i, y_i, range_i)`` (camera frame, m):
    (unit normal (3,) into the deck, n_z > 0; the ranges used (4,) bool), or None with fewer than
    three valid, finite, positive ranges or a degenerate plane."""
    with np.errstate(invalid="ignore"):
        used = valid & np.isfinite(ranges) & (ranges > 0)
    if int(used.sum()) < 3:
        return None
    try:
        normal, _ = _fit_plane(np.column_stack([sensor_xy[used], ranges[used]]))
    except ValueError:
        return None
    if not normal[2] > 1e-6:
        return None
    return normal, used


def ranges_tilt(normal: F64, R_wb: F64, yaw: float) -> F64:
    """Roll and pitch (2,) rad (Z-Y-X Euler of the deck in the filter's world axes) of a deck
    plane of camera-frame ``normal`` (into the deck) seen with IMU attitude ``R_wb``, the deck's
    yaw being ``yaw`` (rad)."""
    z = R_wb @ (R_BODY_CAM @ -normal)  # the deck's z axis in the world
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = c * z[0] + s * z[1], -s * z[0] + c * z[1]  # R_z(-yaw) z = R_y(pitch) R_x(roll) e_z
    return np.array([math.atan2(-y, math.hypot(x, z[2])), math.atan2(x, z[2])])


def ranges_distance(
    ranges: F64,
    used: NDArray[np.bool_],
    sensor_xy: F64,
    camera_position: F64,
    R_bd: F64,
    R_wb: F64,
    r: F64,
    sigma_r: float,
    tilt_var: float,
    floor_var: float,
) -> tuple[float, F64, float]:
    """The deck plane of orientation ``R_bd`` (the filter's deck rotation in the body frame) placed
    at the mean offset of the used touch points along its normal, as a measurement ``h @ r = z`` of
    the relative position ``r`` (world axes, m; the deck origin lies on the plane): returns
    (z m, h (3,), variance m^2). Variance: ``sigma_r^2 / m`` (m used ranges) plus the filter's tilt
    variance ``tilt_var`` times the squared distance from the touch points' centroid to the
    predicted deck origin ``r``, plus ``floor_var``."""
    n = -(_R_CAM_BODY @ R_bd[:, 2])  # deck normal in the camera frame, into the deck
    xy = sensor_xy[used]
    m = int(used.sum())
    c = float((xy @ n[:2] + ranges[used] * n[2]).sum()) / m
    n_body = R_BODY_CAM @ n
    X = _R_CAM_BODY @ (R_wb.T @ r - camera_position)  # predicted deck origin, camera frame
    dxy = X[:2] - xy.sum(axis=0) / m
    var = sigma_r * sigma_r / m + float(dxy @ dxy) * tilt_var + floor_var
    return c + float(n_body @ camera_position), R_wb @ n_body, var


__all__ = [
    "ranges_distance",
    "ranges_plane",
    "ranges_tilt",
]
