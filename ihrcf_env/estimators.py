"""Deck pose estimators: IHRCF (paper sections 2.4-2.8) and the AprilTag baseline (ATDA).

Pure numpy / scipy / OpenCV; importing this module does not import pybullet.

Both estimators report the pose of the **deck** frame in the drone **body** frame (see
:mod:`ihrcf_env.frames`): ``position`` (m), ``rotation`` ``R_body_deck`` and ``euler``
(roll, pitch, yaw) in radians, intrinsic Z-Y-X.

Corner detection (:class:`TagDetector`), measured on synthetic 512x512 images (f = 443 px, 0.4 m tag
at 1-4 m, i.e. 184-43 px across, tilts up to 0.3 rad, random yaw; tag rendered with
``cv2.aruco.generateImageMarker`` + a one-cell white quiet zone, ``cv2.warpPerspective`` at 4x
supersampling and ``INTER_AREA`` down-sampling, compared with the analytic pinhole projection of
:func:`ihrcf_env.rig.tag_corners_deck`; OpenCV 5.0.0, 15-20 poses per row):

=========================  ============================  ==================  ================
refinement                 mean corner error, clean      same, noise s.d. 3  time per frame
=========================  ============================  ==================  ================
CORNER_REFINE_NONE         0.62-0.70 px                  0.67-0.70 px        1.4-3 ms
CORNER_REFINE_CONTOUR      0.67-0.72 px                  0.68 px             1.4-3 ms
CORNER_REFINE_SUBPIX       0.17-0.22 px (bias < 0.01)    0.19-0.23 px        1.3-3 ms
CORNER_REFINE_APRILTAG     0.59-0.62 px raw              0.60-0.62 px        1.2-3.6 ms clean,
                                                                             64-86 ms noisy
=========================  ============================  ==================  ================

The APRILTAG mode has a systematic offset of (+0.42, +0.42) px (measured: 0.41-0.44 in every
configuration, independent of the supersampling factor 1-8, while SUBPIX/NONE/CONTOUR show < 0.05 px
mean offset on the same images, so the renderer is consistent with OpenCV's pixel-centre convention).
FIELD-NOTES says +0.5 px; subtracting 0.5 leaves 0.10-0.16 px, subtracting the measured 0.42 leaves
0.04-0.10 px. Because APRILTAG costs 30x more on noisy images, the default is SUBPIX with
``cornerRefinementMinAccuracy = 0.01`` and 100 iterations (0.17 vs 0.174 px with the defaults);
``refine="apriltag"`` is available and subtracts :data:`APRILTAG_CORNER_OFFSET_PX`.

ATDA (:func:`atda_estimate`), measured on exact projected corners plus Gaussian pixel noise (300 poses,
0.4 m tag, f = 443 px, random yaw, mean rotation error / mean position error):

===============================  =======================  ======================  ====================
case                             IPPE_SQUARE, lowest err  + solvePnPRefineLM      IHRCF (exact ranges)
===============================  =======================  ======================  ====================
1 m, tilt < 0.05, noise 0.2 px   1.40 deg / 1.5 mm        0.36 deg / 0.8 mm       --
1 m, tilt < 0.05, noise 0.5 px   2.97 deg / 3.4 mm        0.90 deg / 2.0 mm       --
2 m, tilt < 0.05, noise 0.5 px   6.51 deg / 11.1 mm       3.82 deg / 7.9 mm       --
1 m, tilt < 0.2,  noise 0.5 px   --                       0.83 deg / 2.0 mm       0.10 deg / 0.7 mm
2 m, tilt < 0.2,  noise 0.5 px   --                       2.82 deg / 8.0 mm       0.19 deg / 1.4 mm
===============================  =======================  ======================  ====================

IPPE's closed-form solution leaves an RMS reprojection error 1.4-2.4x the corner noise; LM polishing of
*both* IPPE solutions removes most of it (after polishing, the two usually coincide), so
``refine=True`` is the default. A prior (e.g. the previous rotation perturbed by 1.5 deg) chosen
when the two polished errors are within :data:`AMBIGUITY_RATIO` changed the mean error by < 0.5 deg
(3 m, 0.5 px noise: 7.95 -> 7.57 deg) and by nothing at 1-2 m. End to end on rendered images
(tilt < 0.2 rad, SUBPIX corners, exact ranges; 20 poses): ATDA 0.8 / 4.1 / 12.8 mm and 0.11 / 0.31 /
0.73 deg mean at 1 / 2 / 3 m (almost all of it depth: at 3 m the mean error is (0.2, 0.0, -12.8) mm,
i.e. the tag is seen ~0.4 % too small, SUBPIX corners sitting slightly inside the tag); IHRCF
0.05 / 0.12 / 0.23 mm and 0.06 / 0.11 / 0.17 deg. Detection + both estimators take ~3 ms per
512x512 frame.

The corner order returned by OpenCV on a ``generateImageMarker`` texture laid on the deck with its
top edge towards deck +x and its left edge towards deck +y matches :func:`tag_corners_deck`
(checked in ``tests/test_estimators.py``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.frames import as_array, cam_pose_to_body, euler_from_matrix, rotation_angle
from ihrcf_env.geometry import (
    apply_homography,
    fit_plane,
    homography_from_points,
    plane_z,
    quad_is_degenerate,
    rigid_fit,
)
from ihrcf_env.rig import SensorRig, tag_corners_deck

#: Measured offset (px, both axes) of CORNER_REFINE_APRILTAG corners w.r.t. OpenCV's pixel-centre convention.
APRILTAG_CORNER_OFFSET_PX: float = 0.42

#: Collinearity tolerance (see geometry.collinear) for the touch-pixel, sensor and corner quadrilaterals.
DEGENERATE_REL_TOL: float = 1e-2

#: ATDA: if the two IPPE solutions' reprojection errors are within this ratio, a prior decides.
AMBIGUITY_RATIO: float = 2.0

#: Rotation taking marker-frame vectors (OpenCV IPPE_SQUARE: x right, y up in the tag image, z out of
#: the tag) to deck-frame vectors (x = tag up, y = tag left, z out): deck = (m_y, -m_x, m_z).
R_DECK_MARKER: NDArray[np.float64] = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])

TouchPixels = Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.bool_]]]


def _frozen(a: ArrayLike, shape: tuple[int, ...], name: str) -> NDArray[np.float64]:
    a = np.array(as_array(a, shape, name), dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """Deck pose in the drone body frame.

    Attributes:
        position: (3,) deck origin (tag centre) in the body frame, m.
        euler: (3,) (roll, pitch, yaw) of ``rotation``, rad (intrinsic Z-Y-X, see frames).
        rotation: (3, 3) ``R_body_deck`` (deck axes expressed in the body frame).
        valid: False when the estimator could not produce a pose; then all numbers are zeros /
            identity (never NaN), see :meth:`invalid`.
        residual: fit quality. IHRCF: RMS of the rigid-fit residuals of the four 3-D corners, m.
            ATDA: RMS reprojection error of the four corners, px. 0 when invalid.
        reason: why the estimate is invalid; '' when valid.
    """

    position: NDArray[np.float64]
    euler: NDArray[np.float64]
    rotation: NDArray[np.float64]
    valid: bool
    residual: float
    reason: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _frozen(self.position, (3,), "position"))
        object.__setattr__(self, "euler", _frozen(self.euler, (3,), "euler"))
        object.__setattr__(self, "rotation", _frozen(self.rotation, (3, 3), "rotation"))
        object.__setattr__(self, "valid", bool(self.valid))
        object.__setattr__(self, "residual", float(self.residual))

    @classmethod
    def invalid(cls, reason: str) -> PoseEstimate:
        """An invalid estimate: zero position and euler, identity rotation, residual 0, ``reason`` set."""
        return cls(np.zeros(3), np.zeros(3), np.eye(3), False, 0.0, reason)

    @classmethod
    def from_body_pose(cls, R_body_deck: ArrayLike, p_body_deck: ArrayLike, residual: float) -> PoseEstimate:
        """A valid estimate from a body-frame rotation (3, 3) and position (3,) (m)."""
        R = as_array(R_body_deck, (3, 3), "R_body_deck")
        return cls(p_body_deck, euler_from_matrix(R), R, True, residual, "")


def _shape_checked(x: ArrayLike, shape: tuple[int, ...], name: str, dtype: type = np.float64) -> NDArray:
    """Shape check only (NaN allowed: a bad measurement, not a programmer error)."""
    a = np.asarray(x, dtype=dtype)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return a


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
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    r = _shape_checked(ranges, (4,), "ranges")
    rv = _shape_checked(ranges_valid, (4,), "ranges_valid", dtype=bool)
    if not np.all(np.isfinite(corners)):
        return PoseEstimate.invalid("non-finite tag corners")
    sensor_xy = rig.sensor_xy_cam  # (4, 2) ps1..ps4, camera frame, m

    # Section 2.6: the deck plane (camera frame) through the valid touch points (x_i, y_i, d_i).
    with np.errstate(invalid="ignore"):
        valid = rv & np.isfinite(r) & (r > 0)
    if int(valid.sum()) < 3:
        return PoseEstimate.invalid("fewer than 3 valid ranges")
    touch = np.column_stack([sensor_xy[valid], r[valid]])
    try:
        normal, offset = fit_plane(touch)  # least squares on 4 points, eq. (20) on 3
        predicted = plane_z(normal, offset, sensor_xy)
    except ValueError as e:
        return PoseEstimate.invalid(f"deck plane undefined: {e}")
    full_ranges = np.where(valid, r, predicted)  # missing ranges predicted from the plane
    if not (np.all(np.isfinite(full_ranges)) and np.all(full_ranges > 0)):
        return PoseEstimate.invalid("predicted range not positive")

    # Touch pixels from the calibration table (paper section 2.2).
    tp, inside = touch_pixels(full_ranges.copy())
    tp = _shape_checked(tp, (4, 2), "touch_pixels()[0]")
    inside = _shape_checked(inside, (4,), "touch_pixels()[1]", dtype=bool)
    if not np.all(inside):
        return PoseEstimate.invalid("range outside calibration table")
    if not np.all(np.isfinite(tp)):
        return PoseEstimate.invalid("non-finite touch pixels")
    if quad_is_degenerate(sensor_xy, DEGENERATE_REL_TOL):
        return PoseEstimate.invalid("degenerate sensor layout")
    if quad_is_degenerate(tp, DEGENERATE_REL_TOL):
        return PoseEstimate.invalid("degenerate touch pixels")

    # Section 2.4: homography sensor XY (camera frame, m) -> touch pixel. Row i of both arrays is
    # sensor ps_i (eq. 17-18 reorder both sides to ps1, ps2, ps4, ps3; only the row correspondence
    # matters, which is kept explicit here).
    try:
        H = homography_from_points(sensor_xy, tp)
        H_inv = np.linalg.inv(H)
    except (ValueError, np.linalg.LinAlgError) as e:
        return PoseEstimate.invalid(f"homography failed: {e}")
    # Section 2.5: inverse homography of the tag corners -> camera-frame XY on the deck plane.
    xy = apply_homography(H_inv, corners)
    if not np.all(np.isfinite(xy)):
        return PoseEstimate.invalid("tag corner maps to infinity")
    # Section 2.6, eq. (22): Z from the plane.
    z = plane_z(normal, offset, xy)
    if not np.all(z > 0):
        return PoseEstimate.invalid("tag corner behind the camera")
    measured = np.column_stack([xy, z])

    # Section 2.7: rigid transform deck model -> measured corners (camera frame).
    try:
        R_cd, t_cd, rms = rigid_fit(tag_corners_deck(tag_size), measured)
    except ValueError as e:
        return PoseEstimate.invalid(f"rigid fit failed: {e}")
    if not rms <= max_residual:
        return PoseEstimate.invalid(f"fit residual {rms:.4g} m > {max_residual:.4g} m")
    # Section 2.8 (eq. 26-27) is replaced by the explicit camera -> body conversion.
    R_bd, p_bd = cam_pose_to_body(R_cd, t_cd, rig.camera_position)
    return PoseEstimate.from_body_pose(R_bd, p_bd, rms)


def _marker_object_points(tag_size: float) -> NDArray[np.float64]:
    """(4, 3) corners in the marker frame, in the order SOLVEPNP_IPPE_SQUARE requires."""
    h = tag_size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def atda_estimate(
    corners_px: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    prior_rotation: ArrayLike | None = None,
    refine: bool = True,
) -> PoseEstimate:
    """AprilTag-only deck pose (ATDA baseline) by IPPE on the four corners.

    Args:
        corners_px: (4, 2) corners in OpenCV pixels, OpenCV's aruco order.
        K: (3, 3) camera matrix; dist: OpenCV distortion coefficients or None (no distortion).
        tag_size: tag side, m. rig: for the camera position in the body frame.
        prior_rotation: optional (3, 3) ``R_body_deck`` (e.g. the previous estimate) used to
            resolve the planar flip ambiguity when the two IPPE solutions' reprojection errors are
            within :data:`AMBIGUITY_RATIO` of each other. Otherwise the lower error wins.
        refine: polish both IPPE solutions with ``cv2.solvePnPRefineLM`` before choosing.

    Returns:
        A :class:`PoseEstimate` whose residual is the RMS reprojection error (px); invalid with a
        reason for degenerate corners or a failed solve.
    """
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    Km = as_array(K, (3, 3), "K")
    d = np.zeros(5) if dist is None else np.asarray(dist, dtype=np.float64).ravel()
    prior = None if prior_rotation is None else as_array(prior_rotation, (3, 3), "prior_rotation")
    if not np.all(np.isfinite(corners)):
        return PoseEstimate.invalid("non-finite tag corners")
    if quad_is_degenerate(corners, DEGENERATE_REL_TOL):
        return PoseEstimate.invalid("degenerate tag corners")
    obj = _marker_object_points(tag_size)
    img = corners.reshape(4, 1, 2)
    try:
        n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, Km, d, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    except cv2.error as e:
        return PoseEstimate.invalid(f"solvePnP failed: {e.err}")
    if n == 0:
        return PoseEstimate.invalid("solvePnP found no solution")

    def reproj_rms(rvec: NDArray, tvec: NDArray) -> float:
        proj, _ = cv2.projectPoints(obj, rvec, tvec, Km, d)
        return float(np.sqrt(np.mean(np.sum((proj.reshape(4, 2) - corners) ** 2, axis=1))))

    cands = []
    for rvec0, tvec0 in zip(rvecs, tvecs, strict=True):
        rvec = np.array(rvec0, dtype=np.float64).reshape(3, 1)
        tvec = np.array(tvec0, dtype=np.float64).reshape(3, 1)
        if refine:  # both IPPE solutions are polished before choosing (see module docstring)
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, Km, d, rvec, tvec)
        t = tvec.ravel()
        if not (np.all(np.isfinite(t)) and t[2] > 0):
            continue
        R_cm, _ = cv2.Rodrigues(rvec)
        R_bd, p_bd = cam_pose_to_body(R_cm @ R_DECK_MARKER.T, t, rig.camera_position)
        cands.append((reproj_rms(rvec, tvec), R_bd, p_bd))
    if not cands:
        return PoseEstimate.invalid("tag behind the camera")
    cands.sort(key=lambda c: c[0])
    best = cands[0]
    if prior is not None and len(cands) > 1 and cands[1][0] <= AMBIGUITY_RATIO * max(cands[0][0], 1e-9):
        best = min(cands[:2], key=lambda c: rotation_angle(prior, c[1]))
    err, R_bd, p_bd = best
    return PoseEstimate.from_body_pose(R_bd, p_bd, err)


_REFINE_METHODS: dict[str, int] = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
}


class TagDetector:
    """AprilTag 36h11 detector (``cv2.aruco.ArucoDetector``) returning one tag's corners.

    ``refine`` is one of 'none', 'subpix' (default, see the module docstring for the measurements),
    'contour', 'apriltag'. With 'apriltag' the corners are shifted by ``-apriltag_offset`` px on
    both axes to OpenCV's pixel-centre convention.
    """

    def __init__(
        self, tag_id: int = 0, refine: str = "subpix", apriltag_offset: float = APRILTAG_CORNER_OFFSET_PX
    ) -> None:
        if refine not in _REFINE_METHODS:
            raise ValueError(f"refine must be one of {sorted(_REFINE_METHODS)}, got {refine!r}")
        self.tag_id = int(tag_id)
        self.refine = refine
        self._offset = float(apriltag_offset) if refine == "apriltag" else 0.0
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = _REFINE_METHODS[refine]
        params.cornerRefinementMinAccuracy = 0.01
        params.cornerRefinementMaxIterations = 100
        # The tag's black square, its white quiet zone and the square deck around it are nested,
        # nearly concentric quads. With OpenCV 5's defaults (minMarkerDistanceRate 0.125,
        # minDistanceToBorder 3) the black square was dropped in favour of its neighbours on some
        # frames: measured on 300 random rendered poses (0.45-2.5 m, tilts to 0.2 rad), 255 of the
        # 259 with the tag fully in view were detected; with 0.05 (OpenCV 4's default) and 1 px,
        # 259 of 259, and no false ids in either case.
        params.minMarkerDistanceRate = 0.05
        params.minDistanceToBorder = 1
        dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
        self._detector = cv2.aruco.ArucoDetector(dictionary, params)

    def detect(self, image: ArrayLike) -> NDArray[np.float64] | None:
        """(4, 2) float64 corners (OpenCV pixel centres, OpenCV order) of tag ``tag_id``, or None.

        ``image``: uint8 grayscale (H, W), RGB (H, W, 3) or RGBA (H, W, 4).
        """
        img = np.asarray(image)
        if img.dtype != np.uint8:
            raise ValueError(f"image must be uint8, got {img.dtype}")
        if img.ndim == 3 and img.shape[2] == 3:
            img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
        elif img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(img, cv2.COLOR_RGBA2GRAY)
        elif img.ndim != 2:
            raise ValueError(f"image must have shape (H, W), (H, W, 3) or (H, W, 4), got {img.shape}")
        corners, ids, _ = self._detector.detectMarkers(np.ascontiguousarray(img))
        if ids is None:
            return None
        for c, i in zip(corners, ids.ravel(), strict=True):
            if int(i) == self.tag_id:
                return c.reshape(4, 2).astype(np.float64) - self._offset
        return None


class DeckPoseEstimator:
    """Tag detection + IHRCF + ATDA for one camera frame and one set of ToF ranges.

    Keeps the last valid ATDA rotation (body frame) as the prior for the flip ambiguity
    (:meth:`reset` forgets it).
    """

    def __init__(
        self,
        rig: SensorRig,
        tag_size: float,
        tag_id: int,
        K: ArrayLike,
        dist: ArrayLike | None,
        touch_pixels: TouchPixels,
        refine: str = "subpix",
        max_residual: float = 0.01,
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        self.rig = rig
        self.tag_size = float(tag_size)
        self.K = as_array(K, (3, 3), "K").copy()
        self.dist = None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy()
        self.touch_pixels = touch_pixels
        self.max_residual = float(max_residual)
        self.detector = TagDetector(tag_id, refine)
        self._prior: NDArray[np.float64] | None = None

    @property
    def prior_rotation(self) -> NDArray[np.float64] | None:
        """The ATDA prior: last valid ATDA ``R_body_deck`` (3, 3), or None."""
        return None if self._prior is None else self._prior.copy()

    def reset(self) -> None:
        """Forget the ATDA rotation prior."""
        self._prior = None

    def estimate(
        self, image: ArrayLike, ranges: ArrayLike, ranges_valid: ArrayLike
    ) -> tuple[PoseEstimate, PoseEstimate]:
        """(IHRCF, ATDA) estimates from one image and the four ranges (m) of ps1..ps4."""
        corners = self.detector.detect(image)
        if corners is None:
            lost = PoseEstimate.invalid("tag not found")
            return lost, lost
        ihrcf = ihrcf_estimate(
            corners, ranges, ranges_valid, self.touch_pixels, self.rig, self.tag_size, self.max_residual
        )
        atda = atda_estimate(corners, self.K, self.dist, self.tag_size, self.rig, self._prior)
        if atda.valid:
            self._prior = np.array(atda.rotation)
        return ihrcf, atda


__all__ = [
    "APRILTAG_CORNER_OFFSET_PX",
    "DeckPoseEstimator",
    "PoseEstimate",
    "TagDetector",
    "atda_estimate",
    "ihrcf_estimate",
]
