"""IHRCF (:mod:`ihrcf_env.core.estimators.ihrcf`) on N frames at once.

Row i of :func:`ihrcf_batch` equals ``IHRCFEstimator.update`` of frame i (tag corners, ranges and
their validity, tag detected or not): the same checks in the same order (the first failure gives
the reason), the same arithmetic, vectorised over the frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch import result as rs
from ihrcf_env.core.batch.geometry import (
    apply_homography_batch,
    collinear_batch,
    fit_plane_batch,
    homography4_batch,
    plane_z_batch,
    rigid_fit_batch,
)
from ihrcf_env.core.batch.result import BatchPoses, assemble, first_failure
from ihrcf_env.core.batch.tables import BatchTable, batch_table
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL
from ihrcf_env.core.estimators.ihrcf import TouchPixels
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.geometry import quad_is_degenerate
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

F64 = NDArray[np.float64]

#: Codes of rows that failed after the 3-D corners were measured (they still carry corners).
_FIT_CODES = (rs.FIT_NONFINITE, rs.FIT_COLLINEAR, rs.FIT_RESIDUAL)


@dataclass(frozen=True, eq=False)
class IHRCFBatch:
    """IHRCF of N frames: the estimates and, per row, the intermediate of
    :class:`~ihrcf_env.core.estimators.ihrcf.IHRCFCorners` (meaningful where ``measured``).

    Attributes:
        poses: the N estimates.
        measured: (N,) bool, the 3-D corners exist (the estimate is valid or failed in the fit).
        corners_cam: (N, 4, 3) tag corners on the fitted deck plane, camera frame, m.
        normal: (N, 3) unit deck-plane normal (camera frame, n_z > 0); offset: (N,) m.
        ranges_used: (N, 4) bool, the ranges that defined the plane.
    """

    poses: BatchPoses
    measured: NDArray[np.bool_]
    corners_cam: F64
    normal: F64
    offset: F64
    ranges_used: NDArray[np.bool_]


def _rows(x: ArrayLike, shape: tuple[int, ...], name: str, dtype: type = np.float64) -> NDArray:
    a: NDArray = np.asarray(x, dtype=dtype)
    if a.shape[1:] != shape or a.ndim != len(shape) + 1:
        raise ValueError(f"{name} must have shape (N, {', '.join(map(str, shape))}), got {a.shape}")
    return a


def ihrcf_measure_batch(
    corners_px: ArrayLike,
    ranges: ArrayLike,
    ranges_valid: ArrayLike,
    detected: ArrayLike,
    touch_pixels: RangePixelTable | BatchTable | TouchPixels,
    rig: SensorRig,
    tag_size: float,
    max_residual: float = 0.01,
) -> IHRCFBatch:
    """IHRCF of N frames with their intermediate corners; arguments as :func:`ihrcf_batch`."""
    corners = _rows(corners_px, (4, 2), "corners_px")
    n_env = len(corners)
    r = _rows(ranges, (4,), "ranges")
    rv = _rows(ranges_valid, (4,), "ranges_valid", dtype=bool)
    det = np.asarray(detected, dtype=bool)
    if r.shape[0] != n_env or rv.shape[0] != n_env or det.shape != (n_env,):
        raise ValueError(f"all inputs must have {n_env} rows, got {r.shape}, {rv.shape}, {det.shape}")
    model = tag_corners_deck(tag_size)
    table = batch_table(touch_pixels)
    sensor_xy = rig.sensor_xy_cam
    code = np.zeros(n_env, dtype=np.int8)

    first_failure(code, ~det, rs.NOT_DETECTED)
    first_failure(code, ~np.isfinite(corners).all(axis=(1, 2)), rs.NONFINITE_CORNERS)
    # Section 2.6: the deck plane through the valid touch points (x_i, y_i, d_i).
    with np.errstate(invalid="ignore"):
        valid = rv & np.isfinite(r) & (r > 0)
    first_failure(code, valid.sum(axis=1) < 3, rs.FEW_RANGES)
    touch = np.concatenate(
        [np.broadcast_to(sensor_xy, (n_env, 4, 2)), np.where(valid, r, 0.0)[:, :, None]], 2
    )
    normal, offset, pcode = fit_plane_batch(touch, valid)
    first_failure(code, pcode == 1, rs.PLANE_COINCIDENT)
    first_failure(code, pcode == 2, rs.PLANE_COLLINEAR)
    predicted, z_ok = plane_z_batch(normal, offset, sensor_xy)
    first_failure(code, ~z_ok, rs.PLANE_PARALLEL)
    full = np.where(valid, r, predicted)
    with np.errstate(invalid="ignore"):
        first_failure(code, ~(np.isfinite(full) & (full > 0)).all(axis=1), rs.PREDICTED_RANGE)

    # Touch pixels from the calibration table (section 2.2), for the rows still going.
    tp, inside = table(np.where((code == rs.OK)[:, None], full, 1.0))
    first_failure(code, ~inside.all(axis=1), rs.OUTSIDE_TABLE)
    first_failure(code, ~np.isfinite(tp).all(axis=(1, 2)), rs.NONFINITE_TOUCH)
    if quad_is_degenerate(sensor_xy, DEGENERATE_REL_TOL):
        first_failure(code, np.ones(n_env, dtype=bool), rs.DEGENERATE_LAYOUT)
    going = code == rs.OK
    tp = np.where(going[:, None, None], tp, sensor_xy * 1000.0)  # a harmless quad in failed rows
    first_failure(code, collinear_batch(tp, DEGENERATE_REL_TOL), rs.DEGENERATE_TOUCH)

    # Section 2.4-2.5: inverse homography (touch pixel -> sensor XY) of the tag corners.
    H_inv, hcode = homography4_batch(tp, sensor_xy)
    first_failure(code, hcode == 1, rs.HOMOGRAPHY_NOT_UNIQUE)
    first_failure(code, hcode == 2, rs.HOMOGRAPHY_H22)
    xy = apply_homography_batch(H_inv, np.where(np.isfinite(corners), corners, 0.0))
    first_failure(code, ~np.isfinite(xy).all(axis=(1, 2)), rs.CORNER_AT_INFINITY)
    going = code == rs.OK
    xy = np.where(going[:, None, None], xy, model[None, :, :2])
    z, _ = plane_z_batch(normal, offset, xy)  # z_ok already required
    first_failure(code, ~(z > 0).all(axis=1), rs.CORNER_BEHIND)
    measured = code == rs.OK
    corners_cam = np.concatenate([xy, z[:, :, None]], axis=2)

    # Section 2.7-2.8: rigid fit of the tag model, then camera -> body.
    first_failure(code, ~np.isfinite(corners_cam).all(axis=(1, 2)), rs.FIT_NONFINITE)
    Q = np.where((code == rs.OK)[:, None, None], corners_cam, model)
    R_cd, t_cd, rms, fit_ok = rigid_fit_batch(model, Q)
    first_failure(code, ~fit_ok, rs.FIT_COLLINEAR)
    first_failure(code, ~(rms <= max_residual), rs.FIT_RESIDUAL)
    R_bd = np.einsum("ij,njk->nik", R_BODY_CAM, R_cd)
    p_bd = t_cd @ R_BODY_CAM.T + rig.camera_position_array
    poses = assemble(R_bd, p_bd, rms, code, rms, float(max_residual))
    return IHRCFBatch(poses, measured, corners_cam, normal, offset, valid)


def ihrcf_batch(
    corners_px: ArrayLike,
    ranges: ArrayLike,
    ranges_valid: ArrayLike,
    detected: ArrayLike,
    touch_pixels: RangePixelTable | BatchTable | TouchPixels,
    rig: SensorRig,
    tag_size: float,
    max_residual: float = 0.01,
) -> BatchPoses:
    """IHRCF deck poses of N frames (body frame), row i as ``IHRCFEstimator.update`` of frame i.

    Args:
        corners_px: (N, 4, 2) tag corners, OpenCV pixels, aruco order (ignored where not detected).
        ranges: (N, 4) ranges of ps1..ps4, m (NaN allowed). ranges_valid: (N, 4) bool.
        detected: (N,) bool, the tag was found (else the row is invalid, code ``NOT_DETECTED``).
        touch_pixels: the range -> pixel table: a :class:`RangePixelTable` (vectorised), a
            :class:`BatchTable`, or a single-frame table (called once per row).
        rig, tag_size (m), max_residual (m): as :func:`~ihrcf_env.core.estimators.ihrcf.ihrcf_estimate`.

    Returns:
        A :class:`BatchPoses`; its reason codes index :data:`~ihrcf_env.core.batch.result.REASONS`.
    """
    return ihrcf_measure_batch(
        corners_px, ranges, ranges_valid, detected, touch_pixels, rig, tag_size, max_residual
    ).poses


__all__ = [
    "IHRCFBatch",
    "ihrcf_batch",
    "ihrcf_measure_batch",
]
