"""Closed-form IPPE for a square tag (Collins & Bartoli 2014) for one frame: OpenCV's
``SOLVEPNP_IPPE_SQUARE`` as ATDA calls it (:mod:`ihrcf_env.core.estimators.atda`): the pinhole
camera with the (k1, k2, p1, p2, k3) model, the fixed-point undistortion, both IPPE poses
``X_cam = R X_marker + t``."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import Array, lax

from ihrcf_env.fast.homography import homography4
from ihrcf_env.fast.linalg3 import cross, matmul

__all__ = ["ippe_square", "marker_points", "solve3", "undistort"]


def marker_points(tag_size: float) -> Array:
    """(4, 3) tag corners in the marker frame, in ``SOLVEPNP_IPPE_SQUARE``'s order (m)."""
    h = tag_size / 2
    return jnp.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def undistort(K: Array, dist: Array, px: Array, iterations: int = 5) -> Array:
    """Normalised image points (M, 2) of pixels (M, 2): OpenCV's fixed-point undistortion with
    ``iterations`` steps (a fixed count)."""
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    y0 = (px[:, 1] - cy) / fy
    x0 = (px[:, 0] - cx - s * y0) / fx
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]

    def step(xy: tuple[Array, Array], _: None) -> tuple[tuple[Array, Array], None]:
        x, y = xy
        r2 = x * x + y * y
        icdist = 1.0 / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
        dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        return ((x0 - dx) * icdist, (y0 - dy) * icdist), None

    (x, y), _ = lax.scan(step, (x0, y0), None, length=iterations)
    return jnp.stack([x, y], axis=-1)


def solve3(A: Array, b: Array) -> Array:
    """``A^-1 b`` of a 3x3 system by cofactors (inf / NaN when ``A`` is singular)."""
    a, bb, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, h, i = A[2, 0], A[2, 1], A[2, 2]
    adj = jnp.array(
        [
            [e * i - f * h, c * h - bb * i, bb * f - c * e],
            [f * g - d * i, a * i - c * g, c * d - a * f],
            [d * h - e * g, bb * g - a * h, a * e - bb * d],
        ]
    )
    det = a * adj[0, 0] + bb * adj[1, 0] + c * adj[2, 0]
    return (adj @ b) / det


def _rotate_to_z(v: Array) -> Array:
    """The rotation taking the unit direction of ``v`` (3,) to +z (IPPE's R_v transposed)."""
    a = v / jnp.sqrt(jnp.sum(v * v))
    ax, ay, az = a[0], a[1], a[2]
    d = 1.0 / (1.0 + az)
    return jnp.array(
        [
            [1.0 - ax * ax * d, -ax * ay * d, -ax],
            [-ax * ay * d, 1.0 - ay * ay * d, -ay],
            [ax, ay, 1.0 - (ax * ax + ay * ay) * d],
        ]
    )


def _translation(R: Array, obj: Array, xn: Array) -> Array:
    """Least-squares t (3,) of ``x_n (r3.X + tz) = r1.X + tx`` (and y) over the four points."""
    RX = obj @ R.T  # (4, 3)
    u, v = xn[:, 0], xn[:, 1]
    ones, zeros = jnp.ones_like(u), jnp.zeros_like(u)
    A = jnp.concatenate([jnp.stack([ones, zeros, -u], -1), jnp.stack([zeros, ones, -v], -1)], 0)
    b = jnp.concatenate([u * RX[:, 2] - RX[:, 0], v * RX[:, 2] - RX[:, 1]], 0)
    return solve3(A.T @ A, A.T @ b)


def ippe_square(xn: Array, tag_size: float) -> tuple[Array, Array, Array]:
    """Both IPPE poses of a square tag of ``tag_size`` (m) from its normalised (undistorted) corners
    ``xn`` (4, 2): rotations (2, 3, 3), translations (2, 3) (marker -> camera, m) and success (a
    finite homography and poses; placeholders otherwise)."""
    obj = marker_points(tag_size).astype(xn.dtype)
    H, code = homography4(obj[:, :2], xn)
    ok = code == 0
    h = H
    j00, j01 = h[0, 0] - h[2, 0] * h[0, 2], h[0, 1] - h[2, 1] * h[0, 2]
    j10, j11 = h[1, 0] - h[2, 0] * h[1, 2], h[1, 1] - h[2, 1] * h[1, 2]
    p, q = h[0, 2], h[1, 2]
    Rv = _rotate_to_z(jnp.stack([p, q, jnp.ones_like(p)])).T
    b00, b01 = Rv[0, 0] - p * Rv[2, 0], Rv[0, 1] - p * Rv[2, 1]
    b10, b11 = Rv[1, 0] - q * Rv[2, 0], Rv[1, 1] - q * Rv[2, 1]
    dtinv = 1.0 / (b00 * b11 - b01 * b10)
    a00 = dtinv * (b11 * j00 - b01 * j10)
    a01 = dtinv * (b11 * j01 - b01 * j11)
    a10 = dtinv * (b00 * j10 - b10 * j00)
    a11 = dtinv * (b00 * j11 - b10 * j01)
    ata00, ata01, ata11 = a00 * a00 + a01 * a01, a00 * a10 + a01 * a11, a10 * a10 + a11 * a11
    gamma = jnp.sqrt(0.5 * (ata00 + ata11 + jnp.sqrt((ata00 - ata11) ** 2 + 4.0 * ata01 * ata01)))
    r00, r01, r10, r11 = a00 / gamma, a01 / gamma, a10 / gamma, a11 / gamma
    b0 = jnp.sqrt(jnp.maximum(1.0 - r00 * r00 - r10 * r10, 0.0))
    b1 = jnp.sqrt(jnp.maximum(1.0 - r01 * r01 - r11 * r11, 0.0))
    b1 = jnp.where(-r00 * r01 - r10 * r11 < 0, -b1, b1)

    def pose(sgn: Array) -> Array:
        c0 = jnp.stack([r00, r10, sgn * b0])
        c1 = jnp.stack([r01, r11, sgn * b1])
        M = jnp.stack([c0, c1, cross(c0, c1)], -1)
        return matmul(Rv, M)

    R = jax.vmap(pose)(jnp.asarray([1.0, -1.0], dtype=b0.dtype))  # both poses in one call
    ok &= jnp.all(jnp.isfinite(R))
    R = jnp.where(ok, R, jnp.eye(3, dtype=R.dtype))
    xs = jnp.where(ok, xn, obj[:, :2])
    t = jax.vmap(lambda Ri: _translation(Ri, obj, xs))(R)
    ok &= jnp.all(jnp.isfinite(t))
    return R, t, ok
