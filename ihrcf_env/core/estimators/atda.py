"""ATDA: the AprilTag + PnP deck-pose baseline.

ATDA (:func:`atda_estimate`) solves the square tag's four corners by IPPE (both planar solutions),
polishes both with Levenberg-Marquardt (``refine=True``: IPPE's closed form leaves a reprojection
error above the corner noise) and keeps the lower reprojection error; when the two are within
:data:`AMBIGUITY_RATIO` a prior rotation (the previous estimate) decides. Its measured accuracy
against IHRCF is in ``docs/estimators.md`` ("ATDA").

The corner order returned by OpenCV on a ``generateImageMarker`` texture laid on the deck with its
top edge towards deck +x and its left edge towards deck +y matches :func:`tag_corners_deck`
(checked in ``tests/test_estimators.py``).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL, PoseEstimate, SensorFrame, _shape_checked
from ihrcf_env.core.frames import as_array, cam_pose_to_body, rotation_angle
from ihrcf_env.core.geometry import (
    quad_is_degenerate,
)
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

#: ATDA: if the two IPPE solutions' reprojection errors are within this ratio, a prior decides.
AMBIGUITY_RATIO: float = 2.0

#: Rotation taking marker-frame vectors (OpenCV IPPE_SQUARE: x right, y up in the tag image, z out of
#: the tag) to deck-frame vectors (x = tag up, y = tag left, z out): deck = (m_y, -m_x, m_z).
R_DECK_MARKER: NDArray[np.float64] = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: Its transpose: marker-frame axes of deck-frame vectors (the camera-to-marker rotation times this
#: is the camera-to-deck rotation).
R_MARKER_DECK: NDArray[np.float64] = np.ascontiguousarray(R_DECK_MARKER.T)
_NO_DISTORTION = np.zeros(5)
_NO_DISTORTION.setflags(write=False)


def _marker_object_points(tag_size: float) -> NDArray[np.float64]:
    """(4, 3) corners in the marker frame, in the order SOLVEPNP_IPPE_SQUARE requires."""
    h = tag_size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


#: One IPPE solution: (RMS reprojection error px, ``R_body_deck`` (3, 3), ``p_body_deck`` (3,) m).
Candidate = tuple[float, NDArray[np.float64], NDArray[np.float64]]


def atda_candidates(
    corners_px: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    refine: bool = True,
) -> list[Candidate] | str:
    """The IPPE solutions of :func:`atda_estimate` in front of the camera, lowest reprojection
    error first (the part that does not depend on the prior), or the reason (str) there are none."""
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    Km = as_array(K, (3, 3), "K")
    d = _NO_DISTORTION if dist is None else np.asarray(dist, dtype=np.float64).ravel()
    if not np.isfinite(corners).all():
        return "non-finite tag corners"
    if quad_is_degenerate(corners, DEGENERATE_REL_TOL):
        return "degenerate tag corners"
    obj = _marker_object_points(tag_size)
    img = corners.reshape(4, 1, 2)
    try:
        n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, Km, d, flags=cv2.SOLVEPNP_IPPE_SQUARE)
    except cv2.error as e:
        return f"solvePnP failed: {e.err}"
    if n == 0:
        return "solvePnP found no solution"

    def reproj_rms(rvec: NDArray, tvec: NDArray) -> float:
        proj, _ = cv2.projectPoints(obj, rvec, tvec, Km, d)
        e = proj.reshape(4, 2) - corners
        return math.sqrt(float(np.einsum("ij,ij->", e, e)) / 4.0)

    cands: list[Candidate] = []
    for rvec0, tvec0 in zip(rvecs, tvecs, strict=True):
        rvec = np.array(rvec0, dtype=np.float64).reshape(3, 1)
        tvec = np.array(tvec0, dtype=np.float64).reshape(3, 1)
        if refine:  # both IPPE solutions are polished before choosing (see module docstring)
            r_lm, t_lm = cv2.solvePnPRefineLM(obj, img, Km, d, rvec, tvec)
            rvec = np.asarray(r_lm, dtype=np.float64).reshape(3, 1)
            tvec = np.asarray(t_lm, dtype=np.float64).reshape(3, 1)
        t = tvec.ravel()
        if not (math.isfinite(float(t @ t) + float(rvec.ravel() @ rvec.ravel())) and t[2] > 0):
            continue  # a non-finite solution, or the tag behind the camera
        R_cm, _ = cv2.Rodrigues(rvec)
        R_bd, p_bd = cam_pose_to_body(R_cm @ R_MARKER_DECK, t, rig.camera_position_array, check=False)
        cands.append((reproj_rms(rvec, tvec), R_bd, p_bd))
    if not cands:
        return "tag behind the camera"
    cands.sort(key=lambda c: c[0])
    return cands


def atda_choose(cands: list[Candidate] | str, prior_rotation: ArrayLike | None = None) -> PoseEstimate:
    """The estimate of :func:`atda_candidates`' solutions: the lowest error, or of the two best the
    one nearer ``prior_rotation`` when their errors are within :data:`AMBIGUITY_RATIO`."""
    prior = None if prior_rotation is None else as_array(prior_rotation, (3, 3), "prior_rotation")
    if isinstance(cands, str):
        return PoseEstimate.invalid(cands)
    best = cands[0]
    if prior is not None and len(cands) > 1 and cands[1][0] <= AMBIGUITY_RATIO * max(cands[0][0], 1e-9):
        best = min(cands[:2], key=lambda c: rotation_angle(prior, c[1], check=False))
    err, R_bd, p_bd = best
    return PoseEstimate.from_body_pose(R_bd, p_bd, err)


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
    return atda_choose(atda_candidates(corners_px, K, dist, tag_size, rig, refine), prior_rotation)


def atda_frame_candidates(
    frame: SensorFrame,
    K: NDArray[np.float64],
    dist: NDArray[np.float64] | None,
    tag_size: float,
    rig: SensorRig,
    refine: bool = True,
) -> list[Candidate] | str:
    """:func:`atda_candidates` of ``frame``'s corners, once per frame and set of inputs
    (:meth:`SensorFrame.memo`: the ATDA estimator and the fused filter share it)."""
    if frame.corners is None:
        raise ValueError("atda_frame_candidates needs a frame with tag corners")
    Kb = np.ascontiguousarray(K, dtype=np.float64).tobytes()
    db = None if dist is None else np.ascontiguousarray(dist, dtype=np.float64).tobytes()
    key = ("atda", Kb, db, float(tag_size), id(rig), bool(refine))
    corners = frame.corners
    return frame.memo(key, lambda: atda_candidates(corners, K, dist, tag_size, rig, refine))


class ATDAEstimator:
    """ATDA as a :class:`~ihrcf_env.core.estimators.base.DeckPoseSource`: :func:`atda_estimate` on
    the frame's corners, with the last valid rotation (body frame) as the prior for the planar flip
    ambiguity (:meth:`reset` forgets it; a frame without a valid estimate keeps it).

    Args: ``K`` (3, 3) camera matrix, ``dist`` OpenCV distortion coefficients or None, ``tag_size``
    m, ``rig``, ``refine`` (see :func:`atda_estimate`); ``name`` is the observation key.
    """

    def __init__(
        self,
        K: ArrayLike,
        dist: ArrayLike | None,
        tag_size: float,
        rig: SensorRig,
        refine: bool = True,
        name: str = "atda",
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        self._name = str(name)
        self.K = as_array(K, (3, 3), "K").copy()
        self.dist = None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy()
        self.tag_size = float(tag_size)
        self.rig = rig
        self.refine = bool(refine)
        self._prior: NDArray[np.float64] | None = None

    @property
    def name(self) -> str:
        """Observation key."""
        return self._name

    @property
    def prior_rotation(self) -> NDArray[np.float64] | None:
        """The prior: last valid ``R_body_deck`` (3, 3), or None."""
        return None if self._prior is None else self._prior.copy()

    def reset(self) -> None:
        """Forget the rotation prior."""
        self._prior = None

    def update(self, frame: SensorFrame) -> PoseEstimate:
        """ATDA estimate of ``frame``; invalid with the frame's reason when it has no corners."""
        if frame.corners is None:
            return PoseEstimate.invalid(frame.corners_reason)
        cands = atda_frame_candidates(frame, self.K, self.dist, self.tag_size, self.rig, self.refine)
        est = atda_choose(cands, self._prior)
        if est.valid:
            self._prior = np.array(est.rotation)
        return est


__all__ = [
    "AMBIGUITY_RATIO",
    "R_DECK_MARKER",
    "R_MARKER_DECK",
    "ATDAEstimator",
    "Candidate",
    "atda_candidates",
    "atda_choose",
    "atda_estimate",
    "atda_frame_candidates",
]
