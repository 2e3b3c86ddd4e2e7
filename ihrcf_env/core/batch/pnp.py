"""ATDA (:mod:`ihrcf_env.core.estimators.atda`) on N frames at once: batched square-tag PnP.

Per frame: both closed-form IPPE poses (:func:`~ihrcf_env.core.batch.ippe.ippe_square`), each
polished by Levenberg-Marquardt on the four corners' reprojection error (the distorted camera
model), then ATDA's choice: the lower RMS reprojection error, or of the two the one nearer a prior
rotation when their errors are within :data:`~ihrcf_env.core.estimators.atda.AMBIGUITY_RATIO`.
The LM runs to convergence (steps below ~1e-10 of the pose), so its result is the local minimum
itself; ``cv2.solvePnPRefineLM`` stops on its own criteria, near it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch import result as rs
from ihrcf_env.core.batch.geometry import collinear_batch
from ihrcf_env.core.batch.ippe import distortion5, ippe_square, marker_points, project, undistort
from ihrcf_env.core.batch.result import BatchPoses, assemble, first_failure
from ihrcf_env.core.estimators.atda import _R_MARKER_DECK, AMBIGUITY_RATIO
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL
from ihrcf_env.core.frames import R_BODY_CAM, as_array
from ihrcf_env.core.rig import SensorRig

F64 = NDArray[np.float64]


def _exp(w: F64) -> F64:
    """Rotation matrices (M, 3, 3) of rotation vectors w (M, 3) (Rodrigues)."""
    th = np.sqrt(np.einsum("mi,mi->m", w, w))
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th * th / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th * th / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    W = np.zeros((len(w), 3, 3))
    W[:, 0, 1], W[:, 0, 2], W[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    W[:, 1, 0], W[:, 2, 0], W[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return np.eye(3) + a[:, None, None] * W + b[:, None, None] * (W @ W)


def _residual(K: F64, dist: F64, R: F64, t: F64, obj: F64, px: F64) -> tuple[F64, F64, F64]:
    """Residuals (M, 8) px, Jacobians (M, 8, 6) w.r.t. (left rotation increment, t), and costs (M,)."""
    RX = np.einsum("mij,kj->mki", R, obj)
    X = RX + t[:, None, :]
    with np.errstate(all="ignore"):
        proj, J3 = project(K, dist, X)  # (M, 4, 2), (M, 4, 2, 3)
    r = (proj - px).reshape(len(R), 8)
    # a left rotation increment w moves RX by w x RX: d(pixel)/dw = rows g of J3 crossed as RX x g
    J = np.concatenate([np.cross(RX[:, :, None, :], J3), J3], axis=-1).reshape(len(R), 8, 6)
    return r, J, np.einsum("mi,mi->m", r, r)


def refine_lm(
    K: F64, dist: F64, R: F64, t: F64, obj: F64, px: F64, max_iter: int = 50
) -> tuple[F64, F64, F64]:
    """Levenberg-Marquardt (Marquardt scaling) of poses R (M, 3, 3), t (M, 3) minimising the squared
    reprojection error of ``obj`` (4, 3) on pixels ``px`` (M, 4, 2), until every step is below 1e-10
    of the pose (or ``max_iter``). Returns the polished R, t and RMS reprojection errors (M,), px."""
    R, t = R.copy(), t.copy()
    r, J, cost = _residual(K, dist, R, t, obj, px)
    lam = np.full(len(R), 1e-6)
    active = np.isfinite(cost)
    for _ in range(max_iter):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        Ji, ri = J[idx], r[idx]
        A = np.einsum("mki,mkj->mij", Ji, Ji)
        g = np.einsum("mki,mk->mi", Ji, ri)
        Ad = A + lam[idx, None, None] * (np.eye(6) * np.diagonal(A, axis1=1, axis2=2)[:, None, :])
        with np.errstate(all="ignore"):
            step = -np.linalg.solve(Ad + 1e-300 * np.eye(6), g[..., None])[..., 0]
        R_new = _exp(step[:, :3]) @ R[idx]
        t_new = t[idx] + step[:, 3:]
        r_new, J_new, cost_new = _residual(K, dist, R_new, t_new, obj, px[idx])
        better = cost_new <= cost[idx]
        acc = idx[better]
        R[acc], t[acc], r[acc], J[acc], cost[acc] = (
            R_new[better],
            t_new[better],
            r_new[better],
            J_new[better],
            cost_new[better],
        )
        lam[idx] = np.where(better, np.maximum(lam[idx] / 10.0, 1e-12), lam[idx] * 10.0)
        size = np.abs(step).max(axis=1)
        scale = 1.0 + np.abs(t[idx]).max(axis=1)
        done = (size <= 1e-10 * scale) | (lam[idx] > 1e8) | ~np.isfinite(size)
        active[idx[done]] = False
    return R, t, np.sqrt(cost / 4.0)


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
    R0, t0, ok = ippe_square(undistort(Km, d, px), tag_size)
    first_failure(code, ~ok, rs.PNP_NO_SOLUTION)
    R_all, t_all = R0.reshape(-1, 3, 3), t0.reshape(-1, 3)
    px2 = np.repeat(px, 2, axis=0)
    if refine:
        R_all, t_all, err = refine_lm(Km, d, R_all, t_all, obj, px2)
    else:
        err = refine_lm(Km, d, R_all, t_all, obj, px2, max_iter=0)[2]
    R2, t2, err2 = R_all.reshape(n_env, 2, 3, 3), t_all.reshape(n_env, 2, 3), err.reshape(n_env, 2)
    usable = (
        np.isfinite(err2) & np.isfinite(t2).all(axis=2) & np.isfinite(R2).all(axis=(2, 3)) & (t2[..., 2] > 0)
    )
    usable &= (code == rs.OK)[:, None]
    first_failure(code, ~usable.any(axis=1), rs.TAG_BEHIND)
    R_bd = np.einsum("ij,nsjk,kl->nsil", R_BODY_CAM, R2, _R_MARKER_DECK)
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
