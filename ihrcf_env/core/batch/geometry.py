"""Batched geometry kernels of :mod:`ihrcf_env.core.geometry` and :mod:`ihrcf_env.core.frames`.

Every function takes arrays with a leading axis N (one independent problem per row) and repeats
the single-frame kernel's arithmetic in the same order, so each row equals the single result to
floating-point rounding. Instead of raising, a kernel returns an error code per row (0: success,
otherwise an index into its ``*_ERRORS`` table, whose text is the single kernel's ValueError
message); the outputs of failed rows are finite placeholders (zeros / identity) unless stated.
Inputs are assumed finite in the rows that matter (as the single ``_``-kernels assume).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.geometry import _RANK_TOL

F64 = NDArray[np.float64]

#: fit_plane_batch error codes -> the single kernel's messages (code 0: success).
PLANE_ERRORS: tuple[str, ...] = (
    "",
    "points are all coincident: plane undefined",
    "points are collinear: plane undefined",
    "fewer than 3 points",
)
#: plane_z_batch failure message.
PLANE_Z_ERROR = "plane is parallel to the z axis: z is undefined"
#: homography4_batch error codes -> messages (code 0: success).
HOMOGRAPHY_ERRORS: tuple[str, ...] = (
    "",
    "degenerate point configuration: homography is not unique",
    "homography has H[2, 2] = 0 and cannot be normalised",
)
#: rigid_fit_batch failure message.
RIGID_ERROR = "P is collinear or coincident: rotation undefined"


def _seq_sum(a: F64, axis: int) -> F64:
    """Sum along a short ``axis`` in index order (the order of numpy's reduction of a few rows)."""
    parts = np.moveaxis(a, axis, 0)
    s = parts[0].copy()
    for p in parts[1:]:
        s = s + p
    return s


def fit_plane_batch(points: F64, use: NDArray[np.bool_] | None = None) -> tuple[F64, F64, NDArray[np.int8]]:
    """:func:`~ihrcf_env.core.geometry.fit_plane` of each row of ``points`` (N, k, 3), restricted to the
    points with ``use`` (N, k) True (default all): 3 used points give the cross product of eq. (20)
    (in index order), more give total least squares. Returns unit normals (N, 3) (n_z >= 0
    convention), offsets (N,) and error codes (N,) into :data:`PLANE_ERRORS`."""
    n_env, k, _ = points.shape
    u = np.ones((n_env, k), dtype=bool) if use is None else np.asarray(use, dtype=bool)
    count = u.sum(axis=1)
    pts = np.where(u[:, :, None], points, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        centroid = _seq_sum(pts, 1) / np.maximum(count, 1)[:, None]
    centred = np.where(u[:, :, None], points - centroid[:, None, :], 0.0)
    sq = np.einsum("nij,nij->ni", centred, centred)
    scale = np.sqrt(sq.max(axis=1))
    code = np.zeros(n_env, dtype=np.int8)
    code[count < 3] = 3
    code[(code == 0) & (scale == 0.0)] = 1
    safe = np.where(scale > 0.0, scale, 1.0)

    # three points: eq. (20), n = (p1 - p2) x (p2 - p3) over the used points in index order
    order = np.argsort(~u, axis=1, kind="stable")[:, :3]
    p1, p2, p3 = (np.take_along_axis(points, order[:, i, None, None], axis=1)[:, 0] for i in range(3))
    n3 = np.cross(p1 - p2, p2 - p3)
    norm3 = np.sqrt(np.einsum("ni,ni->n", n3, n3))
    # four or more: the right singular vector of least spread of the scaled centred points
    _, sv, vt = np.linalg.svd(centred / safe[:, None, None], full_matrices=False)
    n4 = vt[:, 2]
    three = count == 3
    collinear = np.where(three, norm3 <= 1e-9 * safe * safe, sv[:, 1] <= 1e-9 * sv[:, 0])
    code[(code == 0) & collinear] = 2
    n = np.where(three[:, None], n3, n4)
    norm = np.where(three, norm3, np.sqrt(np.einsum("ni,ni->n", n4, n4)))
    ok = code == 0
    n = np.where(ok[:, None], n / np.where(ok, norm, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    first = np.take_along_axis(n, np.argmax(n != 0.0, axis=1)[:, None], axis=1)[:, 0]
    flip = (n[:, 2] < 0) | ((n[:, 2] == 0) & (first < 0))
    n = np.where(flip[:, None], -n, n)
    offset = np.where(ok, np.einsum("ni,ni->n", n, np.where(ok[:, None], centroid, 0.0)), 0.0)
    return n, offset, code


def plane_z_batch(normal: F64, offset: F64, xy: F64) -> tuple[F64, NDArray[np.bool_]]:
    """:func:`~ihrcf_env.core.geometry.plane_z`: Z (N, m) of the planes ``normal (N, 3) . x = offset (N,)``
    above points ``xy`` (N, m, 2) or (m, 2), and (N,) False where the plane is parallel to z
    (:data:`PLANE_Z_ERROR`; Z is 0 there)."""
    nn = np.sqrt(np.einsum("ni,ni->n", normal, normal))
    ok = ~(np.abs(normal[:, 2]) < 1e-9 * nn) & np.any(normal != 0.0, axis=1)
    n2 = np.where(ok, normal[:, 2], 1.0)
    x, y = xy[..., 0], xy[..., 1]
    z = (offset[:, None] - normal[:, 0, None] * x - normal[:, 1, None] * y) / n2[:, None]
    return np.where(ok[:, None], z, 0.0), ok


def collinear_batch(pts: F64, tol: float) -> NDArray[np.bool_]:
    """:func:`~ihrcf_env.core.geometry.collinear` of each row of ``pts`` (N, m, 2): True where any three
    points are collinear within ``tol`` (NaN rows give False: check finiteness first)."""
    m = pts.shape[1]
    out = np.zeros(pts.shape[0], dtype=bool)
    for i in range(m):
        for j in range(i + 1, m):
            for k in range(j + 1, m):
                ax, ay = pts[:, i, 0], pts[:, i, 1]
                ux, uy = pts[:, j, 0] - ax, pts[:, j, 1] - ay
                vx, vy = pts[:, k, 0] - ax, pts[:, k, 1] - ay
                wx, wy = pts[:, k, 0] - pts[:, j, 0], pts[:, k, 1] - pts[:, j, 1]
                area2 = np.abs(ux * vy - uy * vx)
                longest2 = np.maximum(np.maximum(ux * ux + uy * uy, vx * vx + vy * vy), wx * wx + wy * wy)
                out |= (longest2 == 0.0) | (area2 <= tol * longest2)
    return out


def _product(m: F64, n: F64) -> F64:
    """3x3 products (N, 3, 3) summed in the single kernel's order."""
    return (
        m[:, :, 0, None] * n[:, None, 0, :]
        + m[:, :, 1, None] * n[:, None, 1, :]
        + m[:, :, 2, None] * n[:, None, 2, :]
    )


def _det_terms(m: F64) -> tuple[F64, F64, F64]:
    """The first-row expansion terms of each 3x3 determinant (det = t0 - t1 + t2)."""
    a, b, c = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    d, e, f = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    g, h, i = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    return a * (e * i - f * h), b * (d * i - f * g), c * (d * h - e * g)


def _adjugate(m: F64) -> F64:
    a, b, c = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    d, e, f = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    g, h, i = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    rows = (
        (e * i - f * h, c * h - b * i, b * f - c * e),
        (f * g - d * i, a * i - c * g, c * d - a * f),
        (d * h - e * g, b * g - a * h, a * e - b * d),
    )
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=1)


def _square_to_quad(q: F64) -> tuple[F64, NDArray[np.bool_]]:
    """Heckbert's unit-square -> quad homographies (N, 3, 3) of quads (N, 4, 2), and (N,) success."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = ((q[:, i, 0], q[:, i, 1]) for i in range(4))
    sx, sy = x0 - x1 + x2 - x3, y0 - y1 + y2 - y3
    dx1, dx2, dy1, dy2 = x1 - x2, x3 - x2, y1 - y2, y3 - y2
    den = dx1 * dy2 - dx2 * dy1
    ok = (den != 0.0) & np.isfinite(den)
    den = np.where(ok, den, 1.0)
    g = (sx * dy2 - dx2 * sy) / den
    h = (dx1 * sy - sx * dy1) / den
    one = np.ones_like(g)
    m = np.stack(
        [
            np.stack([x1 - x0 + g * x1, x3 - x0 + h * x3, x0], axis=-1),
            np.stack([y1 - y0 + g * y1, y3 - y0 + h * y3, y0], axis=-1),
            np.stack([g, h, one], axis=-1),
        ],
        axis=1,
    )
    t0, t1, t2 = _det_terms(m)
    ok &= np.abs(t0 - t1 + t2) > _RANK_TOL * (np.abs(t0) + np.abs(t1) + np.abs(t2))
    return m, ok


def _shift(c: F64, sign: float) -> F64:
    out = np.zeros((len(c), 3, 3))
    out[:, 0, 0] = out[:, 1, 1] = out[:, 2, 2] = 1.0
    out[:, :2, 2] = sign * c
    return out


def homography4_batch(src: F64, dst: F64) -> tuple[F64, NDArray[np.int8]]:
    """:func:`~ihrcf_env.core.geometry.homography_from_points` of four exact correspondences per row:
    ``dst ~ H [src, 1]`` for ``src``, ``dst`` (N, 4, 2) (either may be (4, 2), shared by all rows).
    Returns H (N, 3, 3) with ``H[2, 2] = 1`` (identity where failed) and error codes (N,) into
    :data:`HOMOGRAPHY_ERRORS`."""
    n_env = max(np.shape(src)[0] if np.ndim(src) == 3 else 1, np.shape(dst)[0] if np.ndim(dst) == 3 else 1)
    src = np.broadcast_to(src, (n_env, 4, 2))
    dst = np.broadcast_to(dst, (n_env, 4, 2))
    cs, cd = _seq_sum(src, 1) / 4.0, _seq_sum(dst, 1) / 4.0
    with np.errstate(all="ignore"):
        qd, ok_d = _square_to_quad(dst - cd[:, None, :])
        qs, ok_s = _square_to_quad(src - cs[:, None, :])
        H = _product(_product(_shift(cd, 1.0), _product(qd, _adjugate(qs))), _shift(cs, -1.0))
        ok = ok_d & ok_s & np.isfinite(H).all(axis=(1, 2))
        code = np.where(ok, 0, 1).astype(np.int8)
        h22 = H[:, 2, 2]
        zero = np.abs(h22) <= _RANK_TOL * np.abs(H).max(axis=(1, 2))
        code[ok & zero] = 2
        good = code == 0
        H = np.where(good[:, None, None], H / np.where(good, h22, 1.0)[:, None, None], np.eye(3))
    return H, code


def apply_homography_batch(H: F64, pts: F64) -> F64:
    """:func:`~ihrcf_env.core.geometry.apply_homography` per row: points (N, m, 2) through H (N, 3, 3);
    points mapped to infinity come out inf / NaN (no warning)."""
    x, y = pts[..., 0], pts[..., 1]
    h = [x * H[:, r, 0, None] + y * H[:, r, 1, None] + H[:, r, 2, None] for r in range(3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.stack([h[0] / h[2], h[1] / h[2]], axis=-1)


def rigid_fit_batch(P: F64, Q: F64) -> tuple[F64, F64, F64, NDArray[np.bool_]]:
    """:func:`~ihrcf_env.core.geometry.rigid_fit` (Kabsch without scale, det +1) per row: ``Q ~ R P + t``
    for ``P`` (N, k, 3) or (k, 3) (shared) and ``Q`` (N, k, 3). Returns R (N, 3, 3), t (N, 3), RMS
    residual (N,) and (N,) success (False where P is collinear: :data:`RIGID_ERROR`)."""
    k = Q.shape[1]
    P = np.broadcast_to(P, Q.shape)
    cp, cq = _seq_sum(P, 1) / k, _seq_sum(Q, 1) / k
    Pc, Qc = P - cp[:, None, :], Q - cq[:, None, :]
    sp = np.linalg.svd(Pc, compute_uv=False)
    ok = ~(sp[:, 1] <= 1e-9 * np.maximum(sp[:, 0], 1e-300))
    U, _, Vt = np.linalg.svd(np.einsum("nki,nkj->nij", Qc, Pc))
    R = U @ Vt
    t0, t1, t2 = _det_terms(R)
    refl = t0 - t1 + t2 < 0
    U[refl, :, 2] *= -1.0
    R = np.where(refl[:, None, None], U @ Vt, R)
    R = np.where(ok[:, None, None], R, np.eye(3))
    t = np.where(ok[:, None], cq - np.einsum("nij,nj->ni", R, cp), 0.0)
    res = np.einsum("nkj,nij->nki", P, R) + t[:, None, :] - Q
    rms = np.where(ok, np.sqrt(np.einsum("nki,nki->n", res, res) / k), 0.0)
    return R, t, rms, ok


def euler_batch(R: F64) -> F64:
    """:func:`~ihrcf_env.core.frames.euler_from_matrix` per row: (roll, pitch, yaw) (N, 3), rad, of
    rotations (N, 3, 3) (intrinsic Z-Y-X; gimbal lock puts everything in yaw)."""
    r20 = R[:, 2, 0]
    pitch = np.arcsin(np.clip(-r20, -1.0, 1.0))
    lock = ~(np.abs(r20) < 1.0 - 1e-12)
    roll = np.where(lock, 0.0, np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    yaw = np.where(lock, np.arctan2(-R[:, 0, 1], R[:, 1, 1]), np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    return np.stack([roll, pitch, yaw], axis=-1)


def matrix_from_euler_batch(euler: F64) -> F64:
    """:func:`~ihrcf_env.core.frames.matrix_from_euler` per row: ``Rz(yaw) Ry(pitch) Rx(roll)`` (N, 3, 3)
    of (roll, pitch, yaw) (N, 3), rad."""
    cr, sr = np.cos(euler[:, 0]), np.sin(euler[:, 0])
    cp, sp = np.cos(euler[:, 1]), np.sin(euler[:, 1])
    cy, sy = np.cos(euler[:, 2]), np.sin(euler[:, 2])
    rows = (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=1)


__all__ = [
    "HOMOGRAPHY_ERRORS",
    "PLANE_ERRORS",
    "PLANE_Z_ERROR",
    "RIGID_ERROR",
    "apply_homography_batch",
    "collinear_batch",
    "euler_batch",
    "fit_plane_batch",
    "homography4_batch",
    "matrix_from_euler_batch",
    "plane_z_batch",
    "rigid_fit_batch",
]
