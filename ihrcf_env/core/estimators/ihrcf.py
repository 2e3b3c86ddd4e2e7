"""IHRCF: Inverse Homography Range Camera Fusion (paper sections 2.4-2.8).

Both estimators report the pose of the **deck** frame in the drone **body** frame (see
:mod:`ihrcf_env.core.frames`): ``position`` (m), ``rotation`` ``R_body_deck`` and ``euler``
(roll, pitch, yaw) in radians, intrinsic Z-Y-X.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL, PoseEstimate, SensorFrame, _shape_checked
from ihrcf_env.core.frames import cam_pose_to_body
from ihrcf_env.core.geometry import (
    _apply_homography,
    _collinear,
    _fit_plane,
    _homography,
    _plane_z,
    _rigid_fit,
    quad_is_degenerate,
)
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

TouchPixels = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.bool_]]]


@dataclass(frozen=True, eq=False)
class IHRCFCorners:
    """The intermediate result of IHRCF (paper sections 2.4-2.6), before the rigid fit.

    Attributes:
        corners_cam: (4, 3) the tag corners on the fitted deck plane, camera frame (m), in the
            order of :func:`tag_corners_deck`. Each lies on the camera ray of its pixel (the ray is
            defined by the range-to-pixel table, never by K), so ``corners_cam[i] / corners_cam[i, 2]``
            is that ray; a filter may intersect the rays with another plane (see
            :mod:`~ihrcf_env.core.estimators.fused`).
        normal: (3,) unit normal of the deck plane through the touch points (camera frame, n_z > 0).
        offset: plane offset, ``normal . x = offset`` (m).
        ranges_used: (4,) bool, the ranges that defined the plane (the others were predicted).
    """

    corners_cam: NDArray[np.float64]
    normal: NDArray[np.float64]
    offset: float
    ranges_used: NDArray[np.bool_]


@functools.lru_cache(maxsize=8)
def _degenerate_layout(sensor_xy: bytes) -> bool:
    """:func:`quad_is_degenerate` of a rig's (4, 2) sensor XY (float64 bytes), once per rig."""
    return quad_is_degenerate(np.frombuffer(sensor_xy, dtype=np.float64).reshape(4, 2), DEGENERATE_REL_TOL)


@functools.lru_cache(maxsize=8)
def _tag_model(tag_size: float) -> NDArray[np.float64]:
    """:func:`tag_corners_deck` (validated), cached read-only."""
    model = tag_corners_deck(tag_size)
    model.setflags(write=False)
    return model


def ihrcf_corners(
    corners_px: ArrayLike,
    ranges: ArrayLike,
    ranges_valid: ArrayLike,
    touch_pixels: TouchPixels,
    rig: SensorRig,
) -> IHRCFCorners | str:
    """IHRCF up to the 3-D tag corners (paper sections 2.4-2.6): an :class:`IHRCFCorners`, or the
    reason (str) why there are none. Arguments as :func:`ihrcf_estimate`. (Every array is checked
    finite before it reaches a geometry kernel, so the kernels skip their own checks.)"""
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    r = _shape_checked(ranges, (4,), "ranges")
    rv = _shape_checked(ranges_valid, (4,), "ranges_valid", dtype=bool)
    if not np.isfinite(corners).all():
        return "non-finite tag corners"
    sensor_xy = rig.sensor_xy_cam  # (4, 2) ps1..ps4, camera frame, m

    # Section 2.6: the deck plane (camera frame) through the valid touch points (x_i, y_i, d_i).
    valid = rv & np.isfinite(r) & (r > 0)  # (comparisons with NaN do not warn)
    if int(valid.sum()) < 3:
        return "fewer than 3 valid ranges"
    touch = np.column_stack([sensor_xy[valid], r[valid]])
    try:
        normal, offset = _fit_plane(touch)  # least squares on 4 points, eq. (20) on 3
        predicted = _plane_z(normal, offset, sensor_xy)
    except ValueError as e:
        return f"deck plane undefined: {e}"
    full_ranges = np.where(valid, r, predicted)  # missing ranges predicted from the plane
    if not (np.isfinite(full_ranges).all() and np.all(full_ranges > 0)):
        return "predicted range not positive"

    # Touch pixels from the calibration table (paper section 2.2).
    tp, inside = touch_pixels(full_ranges.copy())
    tp = _shape_checked(tp, (4, 2), "touch_pixels()[0]")
    inside = _shape_checked(inside, (4,), "touch_pixels()[1]", dtype=bool)
    if not np.all(inside):
        return "range outside calibration table"
    if not np.isfinite(tp).all():
        return "non-finite touch pixels"
    if _degenerate_layout(sensor_xy.tobytes()):
        return "degenerate sensor layout"
    if _collinear(tp.tolist(), DEGENERATE_REL_TOL):  # quad_is_degenerate
        return "degenerate touch pixels"

    # Section 2.4: homography sensor XY (camera frame, m) <-> touch pixel. Row i of both arrays is
    # sensor ps_i (eq. 17-18 reorder both sides to ps1, ps2, ps4, ps3; only the row correspondence
    # matters, which is kept explicit here). Four exact correspondences: the inverse homography
    # (touch pixel -> sensor XY) is fitted directly, the same map as inverting eq. 13-16's.
    try:
        H_inv = _homography(tp, sensor_xy)
    except (ValueError, np.linalg.LinAlgError) as e:
        return f"homography failed: {e}"
    # Section 2.5: inverse homography of the tag corners -> camera-frame XY on the deck plane.
    xy = _apply_homography(H_inv, corners)
    if not np.isfinite(xy).all():
        return "tag corner maps to infinity"
    # Section 2.6, eq. (22): Z from the plane.
    z = _plane_z(normal, offset, xy)
    if not np.all(z > 0):
        return "tag corner behind the camera"
    corners_cam = np.column_stack([xy, z])
    for a in (corners_cam, normal, valid):  # shared between estimators (SensorFrame.memo)
        a.setflags(write=False)
    return IHRCFCorners(corners_cam, normal, float(offset), valid)


def ihrcf_estimate(
    corners_px: ArrayLike,
    ranges: ArrayLike,
    ranges_valid: ArrayLike,
    touch_pixels: TouchPixels,
    rig: SensorRig,
    tag_size: float,
    max_residual: float = 0.01,
) -> PoseEstimate:
    """IHRCF deck pose from the four tag corners and the four ToF ranges (paper sections 2.4-2.8).

    Args:
        corners_px: (4, 2) tag corners in OpenCV pixels (pixel centres at integers), in OpenCV's
            aruco order (the order of :func:`tag_corners_deck`).
        ranges: (4,) ranges of ps1..ps4 along the optical axis, m (NaN allowed for missing ones).
        ranges_valid: (4,) bool, which ranges are usable.
        touch_pixels: the range-to-pixel calibration: maps (4,) ranges (m) of ps1..ps4 to their
            (4, 2) touch pixels and a (4,) bool "inside the calibrated range" mask.
        rig: sensor geometry (sensor XY in the camera frame, camera position in the body frame).
        tag_size: outer black-border side of the tag, m.
        max_residual: largest acceptable RMS rigid-fit residual, m.

    Returns:
        A :class:`PoseEstimate`; invalid with a reason for any bad measurement (never raises for
        those). Raises ValueError only for wrongly shaped inputs.
    """
    return _corners_and_fit(corners_px, ranges, ranges_valid, touch_pixels, rig, tag_size, max_residual)[1]


def _corners_and_fit(
    corners_px: ArrayLike,
    ranges: ArrayLike,
    ranges_valid: ArrayLike,
    touch_pixels: TouchPixels,
    rig: SensorRig,
    tag_size: float,
    max_residual: float,
) -> tuple[IHRCFCorners | str, PoseEstimate]:
    """(:func:`ihrcf_corners`, the estimate of its rigid fit or invalid with its reason)."""
    measured = ihrcf_corners(corners_px, ranges, ranges_valid, touch_pixels, rig)
    if isinstance(measured, str):
        return measured, PoseEstimate.invalid(measured)
    return measured, ihrcf_fit(measured.corners_cam, rig, tag_size, max_residual)


def ihrcf_fit(
    corners_cam: ArrayLike, rig: SensorRig, tag_size: float, max_residual: float = 0.01
) -> PoseEstimate:
    """Section 2.7-2.8: the rigid fit (det = +1) of the tag model to (4, 3) measured corners in the
    camera frame (m), converted to the body frame; invalid when the RMS residual exceeds
    ``max_residual`` (m) or the fit fails."""
    measured = _shape_checked(corners_cam, (4, 3), "corners_cam")
    if not np.isfinite(measured).all():
        return PoseEstimate.invalid("rigid fit failed: non-finite corners")
    # Section 2.7: rigid transform deck model -> measured corners (camera frame).
    try:
        R_cd, t_cd, rms = _rigid_fit(_tag_model(tag_size), measured)
    except ValueError as e:
        return PoseEstimate.invalid(f"rigid fit failed: {e}")
    if not rms <= max_residual:
        return PoseEstimate.invalid(f"fit residual {rms:.4g} m > {max_residual:.4g} m")
    # Section 2.8 (eq. 26-27) is replaced by the explicit camera -> body conversion.
    R_bd, p_bd = cam_pose_to_body(R_cd, t_cd, rig.camera_position_array, check=False)  # checked below
    return PoseEstimate.from_body_pose(R_bd, p_bd, rms)


def ihrcf_measure(
    frame: SensorFrame,
    ranges: ArrayLike,
    touch_pixels: TouchPixels,
    rig: SensorRig,
    tag_size: float,
    max_residual: float = 0.01,
) -> tuple[IHRCFCorners | str, PoseEstimate]:
    """IHRCF on ``frame``'s corners and validity flags with ``ranges`` (m; the frame's or corrected
    ones): (the 3-D corners or why there are none, the estimate). Computed once per frame and set of
    inputs (:meth:`SensorFrame.memo`): the IHRCF estimator and the fused filter share it. The frame
    must have corners."""
    corners = frame.corners
    if corners is None:
        raise ValueError("ihrcf_measure needs a frame with tag corners")
    r = _shape_checked(ranges, (4,), "ranges")

    def compute() -> tuple[IHRCFCorners | str, PoseEstimate]:
        return _corners_and_fit(corners, r, frame.ranges_valid, touch_pixels, rig, tag_size, max_residual)

    key = ("ihrcf", id(touch_pixels), id(rig), float(tag_size), float(max_residual), r.tobytes())
    return frame.memo(key, compute)


class IHRCFEstimator:
    """IHRCF as a :class:`~ihrcf_env.core.estimators.base.DeckPoseSource`: stateless, one
    :func:`ihrcf_estimate` per frame on the frame's corners and ranges.

    Args: as :func:`ihrcf_estimate` (``touch_pixels`` table, ``rig``, ``tag_size`` m,
    ``max_residual`` m); ``name`` is the observation key.
    """

    def __init__(
        self,
        touch_pixels: TouchPixels,
        rig: SensorRig,
        tag_size: float,
        max_residual: float = 0.01,
        name: str = "ihrcf",
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        if not (math.isfinite(max_residual) and max_residual > 0):
            raise ValueError(f"max_residual must be positive (m), got {max_residual!r}")
        self._name = str(name)
        self.touch_pixels = touch_pixels
        self.rig = rig
        self.tag_size = float(tag_size)
        self.max_residual = float(max_residual)

    @property
    def name(self) -> str:
        """Observation key."""
        return self._name

    def reset(self) -> None:
        """Nothing to forget (stateless)."""

    def update(self, frame: SensorFrame) -> PoseEstimate:
        """IHRCF estimate of ``frame``; invalid with the frame's reason when it has no corners."""
        if frame.corners is None:
            return PoseEstimate.invalid(frame.corners_reason)
        return ihrcf_measure(
            frame, frame.ranges, self.touch_pixels, self.rig, self.tag_size, self.max_residual
        )[1]


__all__ = [
    "IHRCFCorners",
    "IHRCFEstimator",
    "TouchPixels",
    "ihrcf_corners",
    "ihrcf_estimate",
    "ihrcf_fit",
    "ihrcf_measure",
]
