"""ATDA (:mod:`ihrcf_env.core.estimators.atda`) on N frames at once: batched square-tag PnP.

Per frame: both closed-form IPPE poses (:func:`~ihrcf_env.core.batch.ippe.ippe_square`), each
polished by Levenberg-Marquardt on the four corners' reprojection error (the distorted camera
model), then ATDA's choice: the lower RMS reprojection error, or of the two the one nearer a prior
rotation when their errors are within :data:`~ihrcf_env.core.estimators.atda.AMBIGUITY_RATIO`.
The LM is :func:`~ihrcf_env.core.batch.cvlm.refine_cv_lm`, ``cv2.solvePnPRefineLM``'s algorithm
(same parametrisation, damping, geodesic step and stopping rules) on both solutions, started from
the rotation vectors ``cv2.Rodrigues`` gives for IPPE's rotations, so the poses are the cv2 path's
up to rounding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch import result as rs
from ihrcf_env.core.batch.cvlm import refine_cv_lm, rodrigues, rodrigues_vector
from ihrcf_env.core.batch.geometry import collinear_batch
from ihrcf_env.core.batch.ippe import distortion5, ippe_square, marker_points, undistort
from ihrcf_env.core.batch.result import BatchPoses, assemble, first_failure
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL
from ihrcf_env.core.frames import R_BODY_CAM, as_array
from ihrcf_env.core.rig import SensorRig

F64 = NDArray[np.float64]

#: :data:`ihrcf_env.core.estimators.atda.AMBIGUITY_RATIO` (repeated here so that the estimators can
#: import this package; a test checks they are equal).
AMBIGUITY_RATIO: float = 2.0
#: Marker-frame -> deck-frame axes of :mod:`ihrcf_env.core.estimators.atda`, transposed.
R_MARKER_DECK: F64 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
#: Fixed-point undistortion iterations of the IPPE starting points (OpenCV's undistortPoints uses 5).
UNDISTORT_ITERATIONS = 5
#: LM iterations (``cv2.solvePnPRefineLM``'s default criteria).
MAX_LM_ITER = 20


@dataclass(frozen=True, eq=False)
class PnPCandidates:
    """Both polished IPPE solutions of N frames, in the body frame, lower error first.

    Attributes:
        rotation: (N, 2, 3, 3) ``R_body_deck``; position: (N, 2, 3) m; error: (N, 2) RMS px.
        usable: (N, 2) bool, finite and in front of the camera.
        code: (N,) reason codes of frames without any usable solution (0 otherwise).
    """

    rotation: F64
    position: F64
    error: F64
    usable: NDArray[np.bool_]
    code: NDArray[np.int8]


def pnp_candidates(
    corners_px: ArrayLike,
    detected: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    refine: bool = True,
) -> PnPCandidates:
    """:func:`~ihrcf_env.core.estimators.atda.atda_candidates` of N frames (arguments as
    :func:`atda_batch`)."""
    corners = np.asarray(corners_px, dtype=np.float64)
    if corners.ndim != 3 or corners.shape[1:] != (4, 2):
        raise ValueError(f"corners_px must have shape (N, 4, 2), got {corners.shape}")
    n_env = len(corners)
    det = np.asarray(detected, dtype=bool)
    if det.shape != (n_env,):
        raise ValueError(f"detected must have shape ({n_env},), got {det.shape}")
    Km = as_array(K, (3, 3), "K")
    d = distortion5(dist)
    code = np.zeros(n_env, dtype=np.int8)
    first_failure(code, ~det, rs.NOT_DETECTED)
    first_failure(code, ~np.isfinite(corners).all(axis=(1, 2)), rs.NONFINITE_CORNERS)
    obj = marker_points(tag_size)
    px = np.where((code == rs.OK)[:, None, None], corners, obj[:, :2] * 1000.0 + 100.0)
    first_failure(code, collinear_batch(px, DEGENERATE_REL_TOL), rs.DEGENERATE_TAG)
    R0, t0, ok = ippe_square(undistort(Km, d, px, UNDISTORT_ITERATIONS), tag_size)
    first_failure(code, ~ok, rs.PNP_NO_SOLUTION)
    R_all, t_all = R0.reshape(-1, 3, 3), t0.reshape(-1, 3)
    px2 = np.repeat(px, 2, axis=0)
    rvec, t_all, energy, _ = refine_cv_lm(
        Km, d, rodrigues_vector(R_all), t_all, obj, px2, max_iter=MAX_LM_ITER if refine else 0
    )
    R_all, err = rodrigues(rvec, False)[0].reshape(-1, 3, 3), np.sqrt(energy / 4.0)
    R2, t2, err2 = R_all.reshape(n_env, 2, 3, 3), t_all.reshape(n_env, 2, 3), err.reshape(n_env, 2)
    usable = (
        np.isfinite(err2) & np.isfinite(t2).all(axis=2) & np.isfinite(R2).all(axis=(2, 3)) & (t2[..., 2] > 0)
    )
    usable &= (code == rs.OK)[:, None]
    first_failure(code, ~usable.any(axis=1), rs.TAG_BEHIND)
    R_bd = np.einsum("ij,nsjk,kl->nsil", R_BODY_CAM, R2, R_MARKER_DECK)
    p_bd = t2 @ R_BODY_CAM.T + rig.camera_position_array
    # lower error first (a stable sort, unusable solutions last)
    key = np.where(usable, err2, np.inf)
    swap = key[:, 1] < key[:, 0]
    order = np.where(swap[:, None], [1, 0], [0, 1])
    take = np.take_along_axis
    return PnPCandidates(
        take(R_bd, order[:, :, None, None], axis=1),
        take(p_bd, order[:, :, None], axis=1),
        take(err2, order, axis=1),
        take(usable, order, axis=1),
        code,
    )


def pnp_choose(
    cands: PnPCandidates, prior_rotation: ArrayLike | None = None, has_prior: ArrayLike | None = None
) -> BatchPoses:
    """:func:`~ihrcf_env.core.estimators.atda.atda_choose` per frame: the lower error, or the
    candidate nearer ``prior_rotation`` (N, 3, 3) where ``has_prior`` (N,) and the two errors are
    within :data:`AMBIGUITY_RATIO`."""
    n_env = len(cands.code)
    pick = np.zeros(n_env, dtype=np.intp)
    if prior_rotation is not None:
        prior = np.asarray(prior_rotation, dtype=np.float64).reshape(n_env, 3, 3)
        hp = np.ones(n_env, dtype=bool) if has_prior is None else np.asarray(has_prior, dtype=bool)
        e = cands.error
        near_tie = hp & cands.usable[:, 1] & (e[:, 1] <= AMBIGUITY_RATIO * np.maximum(e[:, 0], 1e-9))
        tr = np.einsum("nij,nsij->ns", prior, cands.rotation)
        angle = np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))
        pick = np.where(near_tie & (angle[:, 1] < angle[:, 0]), 1, 0)
    rows = np.arange(n_env)
    R, p, err = cands.rotation[rows, pick], cands.position[rows, pick], cands.error[rows, pick]
    return assemble(R, p, err, cands.code.copy())


def atda_batch(
    corners_px: ArrayLike,
    detected: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    prior_rotation: ArrayLike | None = None,
    has_prior: ArrayLike | None = None,
    refine: bool = True,
) -> BatchPoses:
    """ATDA deck poses of N frames (body frame), row i as ``atda_estimate`` of frame i.

    Args:
        corners_px: (N, 4, 2) tag corners, OpenCV pixels, aruco order (ignored where not detected).
        detected: (N,) bool, the tag was found.
        K: (3, 3) camera matrix; dist: OpenCV (k1, k2, p1, p2[, k3]) or None.
        tag_size: tag side, m. rig: for the camera position in the body frame.
        prior_rotation: optional (N, 3, 3) ``R_body_deck`` priors, used where ``has_prior`` (N,)
            (default: every row) to break near-ties.
        refine: polish both IPPE solutions by LM before choosing.

    Returns:
        A :class:`BatchPoses` whose residual is the RMS reprojection error (px).
    """
    return pnp_choose(
        pnp_candidates(corners_px, detected, K, dist, tag_size, rig, refine), prior_rotation, has_prior
    )


class ATDABatch:
    """N ATDA estimators (:class:`~ihrcf_env.core.estimators.atda.ATDAEstimator`) side by side:
    each keeps its last valid rotation as its prior. Arguments as :func:`atda_batch`."""

    def __init__(
        self,
        n: int,
        K: ArrayLike,
        dist: ArrayLike | None,
        tag_size: float,
        rig: SensorRig,
        refine: bool = True,
    ) -> None:
        self.K = as_array(K, (3, 3), "K").copy()
        self.dist = distortion5(dist)
        self.tag_size = float(tag_size)
        self.rig = rig
        self.refine = bool(refine)
        self.prior = np.tile(np.eye(3), (int(n), 1, 1))
        self.has_prior = np.zeros(int(n), dtype=bool)

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget the priors of the rows in ``mask`` (N,) bool (default all)."""
        m = np.ones(len(self.has_prior), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        self.has_prior[m] = False
        self.prior[m] = np.eye(3)

    def update(self, corners_px: ArrayLike, detected: ArrayLike) -> BatchPoses:
        """Estimates of the N frames; valid rows become the new priors."""
        out = atda_batch(
            corners_px,
            detected,
            self.K,
            self.dist,
            self.tag_size,
            self.rig,
            self.prior,
            self.has_prior,
            self.refine,
        )
        self.prior[out.valid] = out.rotation[out.valid]
        self.has_prior |= out.valid
        return out


__all__ = [
    "AMBIGUITY_RATIO",
    "MAX_LM_ITER",
    "R_MARKER_DECK",
    "UNDISTORT_ITERATIONS",
    "ATDABatch",
    "PnPCandidates",
    "atda_batch",
    "pnp_candidates",
    "pnp_choose",
]
