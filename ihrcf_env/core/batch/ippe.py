"""Batched camera model and closed-form IPPE for a square tag (Collins & Bartoli 2014).

The camera is OpenCV's pinhole with the (k1, k2, p1, p2, k3) distortion model. :func:`ippe_square`
gives both IPPE poses of the tag, ``X_cam = R X_marker + t``, with the marker points in the order
of ``SOLVEPNP_IPPE_SQUARE`` (see :func:`marker_points`): the starting points of the refinement in
:mod:`ihrcf_env.core.batch.pnp`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch.geometry import homography4_batch

F64 = NDArray[np.float64]


def marker_points(tag_size: float) -> F64:
    """(4, 3) tag corners in the marker frame, in the order ``SOLVEPNP_IPPE_SQUARE`` requires."""
    h = tag_size / 2
    return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


def distortion5(dist: ArrayLike | None) -> F64:
    """OpenCV distortion coefficients (None, 4, 5 or more numbers) as (k1, k2, p1, p2, k3); models
    beyond five coefficients are refused (ValueError) unless the extra ones are all zero."""
    d = np.zeros(5) if dist is None else np.asarray(dist, dtype=np.float64).ravel()
    if d.size < 4 or (d.size > 5 and np.any(d[5:] != 0.0)) or not np.isfinite(d).all():
        raise ValueError(f"dist must be finite (k1, k2, p1, p2[, k3]) coefficients, got {d!r}")
    out = np.zeros(5)
    out[: min(d.size, 5)] = d[:5]
    return out


def project(K: F64, dist: F64, X: F64) -> tuple[F64, F64]:
    """Pixels (..., 2) of camera-frame points X (..., 3) and the Jacobians (..., 2, 3) d(pixel)/dX."""
    k1, k2, p1, p2, k3 = dist
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    iz = 1.0 / X[..., 2]
    x, y = X[..., 0] * iz, X[..., 1] * iz
    r2 = x * x + y * y
    rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    drad = 2.0 * (k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3))  # d rad / d r2, times 2
    xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    px = np.stack([fx * xd + s * yd + cx, fy * yd + cy], axis=-1)
    # d(pixel)/dX = [[fx, s], [0, fy]] @ d(xd, yd)/d(x, y) @ d(x, y)/dX,
    # with d(x, y)/dX = [[1, 0, -x], [0, 1, -y]] / z
    a = rad + x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x
    b = x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
    d_ = rad + y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x
    m00, m01, m10, m11 = (fx * a + s * b) * iz, (fx * b + s * d_) * iz, fy * b * iz, fy * d_ * iz
    J = np.stack(
        [np.stack([m00, m01, -(m00 * x + m01 * y)], -1), np.stack([m10, m11, -(m10 * x + m11 * y)], -1)], -2
    )
    return px, J


def undistort(K: F64, dist: F64, px: F64, iterations: int = 20) -> F64:
    """Normalised image points (..., 2) of pixels (..., 2): OpenCV's fixed-point undistortion."""
    fx, s, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
    y0 = (px[..., 1] - cy) / fy
    x0 = (px[..., 0] - cx - s * y0) / fx
    k1, k2, p1, p2, k3 = dist
    x, y = x0, y0
    if np.any(dist != 0.0):
        for _ in range(iterations):
            r2 = x * x + y * y
            icdist = 1.0 / (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
            dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
            dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
            x, y = (x0 - dx) * icdist, (y0 - dy) * icdist
    return np.stack([x, y], axis=-1)


def _rotate_to_z(v: F64) -> F64:
    """Rotations (N, 3, 3) taking the unit directions of v (N, 3) to +z (IPPE's R_v transposed)."""
    a = v / np.linalg.norm(v, axis=1, keepdims=True)
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
    d = 1.0 / (1.0 + az)  # az > 0: the tag centre is in front of the camera
    return np.stack(
        [
            np.stack([1.0 - ax * ax * d, -ax * ay * d, -ax], -1),
            np.stack([-ax * ay * d, 1.0 - ay * ay * d, -ay], -1),
            np.stack([ax, ay, 1.0 - (ax * ax + ay * ay) * d], -1),
        ],
        axis=1,
    )


def _translation(R: F64, obj: F64, xn: F64) -> F64:
    """Least-squares t (N, 3) of the projection equations ``x_n (r3.X + tz) = r1.X + tx`` (and y)."""
    RX = np.einsum("nij,kj->nki", R, obj)  # (N, 4, 3)
    u, v = xn[..., 0], xn[..., 1]
    ones, zeros = np.ones_like(u), np.zeros_like(u)
    A = np.concatenate([np.stack([ones, zeros, -u], -1), np.stack([zeros, ones, -v], -1)], 1)
    b = np.concatenate([u * RX[..., 2] - RX[..., 0], v * RX[..., 2] - RX[..., 1]], 1)
    AtA = np.einsum("nki,nkj->nij", A, A)
    Atb = np.einsum("nki,nk->ni", A, b)
    return np.linalg.solve(AtA, Atb[..., None])[..., 0]


def ippe_square(xn: F64, tag_size: float) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Both IPPE poses of a square tag from its normalised (undistorted) corners ``xn`` (N, 4, 2):
    rotations (N, 2, 3, 3), translations (N, 2, 3) (marker -> camera) and (N,) success (finite
    homography and poses; failed rows hold placeholders)."""
    obj = marker_points(tag_size)
    H, code = homography4_batch(obj[:, :2], xn)  # model plane -> normalised image
    ok = code == 0
    # Jacobian of the homography at the model origin and the image of the origin
    h = H
    j00, j01 = h[:, 0, 0] - h[:, 2, 0] * h[:, 0, 2], h[:, 0, 1] - h[:, 2, 1] * h[:, 0, 2]
    j10, j11 = h[:, 1, 0] - h[:, 2, 0] * h[:, 1, 2], h[:, 1, 1] - h[:, 2, 1] * h[:, 1, 2]
    p, q = h[:, 0, 2], h[:, 1, 2]
    Rv = np.swapaxes(_rotate_to_z(np.stack([p, q, np.ones_like(p)], -1)), 1, 2)
    b00, b01 = Rv[:, 0, 0] - p * Rv[:, 2, 0], Rv[:, 0, 1] - p * Rv[:, 2, 1]
    b10, b11 = Rv[:, 1, 0] - q * Rv[:, 2, 0], Rv[:, 1, 1] - q * Rv[:, 2, 1]
    with np.errstate(all="ignore"):
        dtinv = 1.0 / (b00 * b11 - b01 * b10)
        a00 = dtinv * (b11 * j00 - b01 * j10)
        a01 = dtinv * (b11 * j01 - b01 * j11)
        a10 = dtinv * (b00 * j10 - b10 * j00)
        a11 = dtinv * (b00 * j11 - b10 * j01)
        ata00, ata01, ata11 = a00 * a00 + a01 * a01, a00 * a10 + a01 * a11, a10 * a10 + a11 * a11
        gamma = np.sqrt(0.5 * (ata00 + ata11 + np.sqrt((ata00 - ata11) ** 2 + 4.0 * ata01 * ata01)))
        r00, r01, r10, r11 = a00 / gamma, a01 / gamma, a10 / gamma, a11 / gamma
        b0 = np.sqrt(np.maximum(1.0 - r00 * r00 - r10 * r10, 0.0))
        b1 = np.sqrt(np.maximum(1.0 - r01 * r01 - r11 * r11, 0.0))
        b1 = np.where(-r00 * r01 - r10 * r11 < 0, -b1, b1)
        Rs = []
        for sgn in (1.0, -1.0):
            c0 = np.stack([r00, r10, sgn * b0], -1)
            c1 = np.stack([r01, r11, sgn * b1], -1)
            M = np.stack([c0, c1, np.cross(c0, c1)], -1)
            Rs.append(Rv @ M)
        R = np.stack(Rs, axis=1)
        ok &= np.isfinite(R).all(axis=(1, 2, 3))
        R = np.where(ok[:, None, None, None], R, np.eye(3))
        t = np.stack(
            [_translation(R[:, i], obj, np.where(ok[:, None, None], xn, obj[:, :2])) for i in (0, 1)], 1
        )
    ok &= np.isfinite(t).all(axis=(1, 2))
    return R, t, ok


def reprojection(K: F64, dist: F64, R: F64, t: F64, obj: F64, corners: F64) -> F64:
    """Reprojection residuals (..., 4, 2), px, of poses R (..., 3, 3), t (..., 3) of ``obj`` (4, 3)."""
    X = np.einsum("...ij,kj->...ki", R, obj) + t[..., None, :]
    return project(K, dist, X)[0] - corners


__all__ = [
    "distortion5",
    "ippe_square",
    "marker_points",
    "project",
    "reprojection",
    "undistort",
]
