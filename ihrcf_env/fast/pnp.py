"""ATDA's square-tag PnP for one frame: both closed-form IPPE poses polished by the
fixed-iteration LM (:mod:`.lm`), then ATDA's choice (the lower RMS reprojection error, or of the
two the one nearer a prior rotation when their errors are within ``AMBIGUITY_RATIO``): the port
of :func:`ihrcf_env.core.estimators.atda.atda_candidates` and ``atda_choose``. Poses: the deck in the
body frame (m, rad); errors: RMS px."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import Array

from ihrcf_env.core.estimators import reasons as rs
from ihrcf_env.core.estimators.atda import AMBIGUITY_RATIO, R_MARKER_DECK
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL
from ihrcf_env.core.estimators.cv_lm import MAX_ITER as MAX_LM_ITER
from ihrcf_env.core.estimators.cv_lm import UNDISTORT_ITERATIONS
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.fast.homography import collinear
from ihrcf_env.fast.ihrcf import Pose, assemble
from ihrcf_env.fast.ippe import ippe_square, marker_points, undistort
from ihrcf_env.fast.linalg3 import matmul, matvec
from ihrcf_env.fast.lm import refine_lm, rodrigues, rodrigues_vector

__all__ = ["Candidates", "pnp_candidates", "pnp_choose"]


class Candidates(NamedTuple):
    """Both polished IPPE solutions, lower error first: ``rotation`` (2, 3, 3) ``R_body_deck``,
    ``position`` (2, 3) m, ``error`` (2,) RMS px, ``usable`` (2,) (finite, in front of the camera),
    ``code`` the reason code when none is usable (0 otherwise)."""

    rotation: Array
    position: Array
    error: Array
    usable: Array
    code: Array


def pnp_candidates(
    corners_px: Array,
    detected: Array,
    K: Array,
    dist: Array,
    tag_size: float,
    camera_position: Array,
    max_iter: int = MAX_LM_ITER,
) -> Candidates:
    """The candidates of one frame: tag ``corners_px`` (4, 2; aruco order), ``detected``, camera
    ``K`` (3, 3) and ``dist`` (k1, k2, p1, p2, k3), the tag's side ``tag_size`` (m), the camera's
    ``camera_position`` (3,; body, m) and at most ``max_iter`` LM steps per solution (0: IPPE only)."""
    code = jnp.where(detected, rs.OK, rs.NOT_DETECTED)
    code = jnp.where((code == rs.OK) & ~jnp.all(jnp.isfinite(corners_px)), rs.NONFINITE_CORNERS, code)
    obj = marker_points(tag_size).astype(K.dtype)
    px = jnp.where(code == rs.OK, corners_px, obj[:, :2] * 1000.0 + 100.0)
    code = jnp.where((code == rs.OK) & collinear(px, DEGENERATE_REL_TOL), rs.DEGENERATE_TAG, code)
    R0, t0, ok = ippe_square(undistort(K, dist, px, UNDISTORT_ITERATIONS), tag_size)
    code = jnp.where((code == rs.OK) & ~ok, rs.PNP_NO_SOLUTION, code)

    def polish(R: Array, t: Array) -> tuple[Array, Array, Array]:
        out = refine_lm(K, dist, rodrigues_vector(R), t, obj, px, max_iter)
        return rodrigues(out.rvec)[0].reshape(3, 3), out.tvec, jnp.sqrt(out.energy / 4.0)

    R2, t2, err2 = jax.vmap(polish)(R0, t0)  # both solutions, one compiled LM
    usable = jnp.isfinite(err2) & jnp.all(jnp.isfinite(t2), axis=1) & jnp.all(jnp.isfinite(R2), axis=(1, 2))
    usable &= (t2[:, 2] > 0) & (code == rs.OK)
    code = jnp.where((code == rs.OK) & ~jnp.any(usable), rs.TAG_BEHIND, code)
    R_bc = jnp.asarray(R_BODY_CAM, dtype=K.dtype)
    R_md = jnp.asarray(R_MARKER_DECK, dtype=K.dtype)
    R_bd = jax.vmap(lambda R: matmul(matmul(R_bc, R), R_md))(R2)  # both solutions in one call
    p_bd = matvec(R_bc, t2) + camera_position
    key = jnp.where(usable, err2, jnp.inf)
    swap = key[1] < key[0]
    order = jnp.where(swap, jnp.array([1, 0]), jnp.array([0, 1]))
    return Candidates(R_bd[order], p_bd[order], err2[order], usable[order], code.astype(jnp.int8))


def pnp_choose(cands: Candidates, prior_rotation: Array, has_prior: Array) -> Pose:
    """ATDA's pose of the candidates: the lower error, or the candidate nearer ``prior_rotation``
    (3, 3) when ``has_prior`` and the errors are within ``AMBIGUITY_RATIO`` (residual: RMS px)."""
    e = cands.error
    near_tie = has_prior & cands.usable[1] & (e[1] <= AMBIGUITY_RATIO * jnp.maximum(e[0], 1e-9))
    tr = jnp.sum(prior_rotation[None] * cands.rotation, axis=(1, 2))
    angle = jnp.arccos(jnp.clip((tr - 1.0) / 2.0, -1.0, 1.0))
    pick = jnp.where(near_tie & (angle[1] < angle[0]), 1, 0)
    return assemble(cands.rotation[pick], cands.position[pick], e[pick], cands.code, jnp.zeros_like(e[0]))
