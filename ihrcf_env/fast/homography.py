"""The homography of four exact correspondences (Heckbert's square-to-quad closed form, as
:func:`ihrcf_env.core.geometry.homography_from_points` of four points), its application to points, and the
scale-invariant collinearity test of :func:`ihrcf_env.core.geometry.collinear`, for one frame."""

from __future__ import annotations

import itertools

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.geometry import _RANK_TOL
from ihrcf_env.fast.linalg3 import matmul

__all__ = ["apply_homography", "collinear", "homography4"]


def _det_terms(m: Array) -> tuple[Array, Array, Array]:
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    return a * (e * i - f * h), b * (d * i - f * g), c * (d * h - e * g)


def _adjugate(m: Array) -> Array:
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    return jnp.array(
        [
            [e * i - f * h, c * h - b * i, b * f - c * e],
            [f * g - d * i, a * i - c * g, c * d - a * f],
            [d * h - e * g, b * g - a * h, a * e - b * d],
        ]
    )


def _square_to_quad(q: Array) -> tuple[Array, Array]:
    """The unit square -> quad ``q`` (4, 2) homography (3, 3) and whether it is unique."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = ((q[i, 0], q[i, 1]) for i in range(4))
    sx, sy = x0 - x1 + x2 - x3, y0 - y1 + y2 - y3
    dx1, dx2, dy1, dy2 = x1 - x2, x3 - x2, y1 - y2, y3 - y2
    den = dx1 * dy2 - dx2 * dy1
    ok = (den != 0.0) & jnp.isfinite(den)
    den = jnp.where(ok, den, 1.0)
    g = (sx * dy2 - dx2 * sy) / den
    h = (dx1 * sy - sx * dy1) / den
    m = jnp.array(
        [
            [x1 - x0 + g * x1, x3 - x0 + h * x3, x0],
            [y1 - y0 + g * y1, y3 - y0 + h * y3, y0],
            [g, h, jnp.ones_like(g)],
        ]
    )
    t0, t1, t2 = _det_terms(m)
    ok &= jnp.abs(t0 - t1 + t2) > _RANK_TOL * (jnp.abs(t0) + jnp.abs(t1) + jnp.abs(t2))
    return m, ok


def _shift(c: Array, sign: float) -> Array:
    one, zero = jnp.ones_like(c[0]), jnp.zeros_like(c[0])
    return jnp.array([[one, zero, sign * c[0]], [zero, one, sign * c[1]], [zero, zero, one]])


def _sum4(p: Array) -> Array:
    return ((p[0] + p[1]) + p[2]) + p[3]


def homography4(src: Array, dst: Array) -> tuple[Array, Array]:
    """``H`` (3, 3) with ``dst ~ H [src, 1]`` for four exact correspondences ``src``, ``dst`` (4, 2),
    normalised to ``H[2, 2] = 1`` (identity where it fails), and an error code: 0 success, 1 the
    homography is not unique (three points collinear), 2 ``H[2, 2] = 0``."""
    cs, cd = _sum4(src) / 4.0, _sum4(dst) / 4.0
    q, ok_q = jax.vmap(_square_to_quad)(jnp.stack([dst - cd, src - cs]))  # both quads in one call
    qd, qs, ok_d, ok_s = q[0], q[1], ok_q[0], ok_q[1]
    H = matmul(matmul(_shift(cd, 1.0), matmul(qd, _adjugate(qs))), _shift(cs, -1.0))
    ok = ok_d & ok_s & jnp.all(jnp.isfinite(H))
    h22 = H[2, 2]
    zero = jnp.abs(h22) <= _RANK_TOL * jnp.max(jnp.abs(H))
    code = jnp.where(ok, jnp.where(zero, 2, 0), 1).astype(jnp.int8)
    good = code == 0
    H = jnp.where(good, H / jnp.where(good, h22, 1.0), jnp.eye(3, dtype=H.dtype))
    return H, code


def apply_homography(H: Array, pts: Array) -> Array:
    """Points (M, 2) through ``H`` (3, 3); points mapped to infinity come out inf / NaN."""
    x, y = pts[:, 0], pts[:, 1]
    h = [x * H[r, 0] + y * H[r, 1] + H[r, 2] for r in range(3)]
    return jnp.stack([h[0] / h[2], h[1] / h[2]], axis=-1)


def collinear(pts: Array, tol: float) -> Array:
    """True where any three of ``pts`` (M, 2) are collinear within ``tol``: ``2 area <= tol *
    longest_side^2`` (coincident points count); the triples in one broadcast expression."""
    i, j, k = (np.asarray(t) for t in zip(*itertools.combinations(range(pts.shape[0]), 3), strict=True))
    a, pj, pk = pts[i], pts[j], pts[k]  # (T, 2) each
    ux, uy = pj[:, 0] - a[:, 0], pj[:, 1] - a[:, 1]
    vx, vy = pk[:, 0] - a[:, 0], pk[:, 1] - a[:, 1]
    wx, wy = pk[:, 0] - pj[:, 0], pk[:, 1] - pj[:, 1]
    area2 = jnp.abs(ux * vy - uy * vx)
    longest2 = jnp.maximum(jnp.maximum(ux * ux + uy * uy, vx * vx + vy * vy), wx * wx + wy * wy)
    return jnp.any((longest2 == 0.0) | (area2 <= tol * longest2))
