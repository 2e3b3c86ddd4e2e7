"""``cv2.solvePnPRefineLM`` on N poses at once: OpenCV's Levenberg-Marquardt, row by row.

The same algorithm as OpenCV 5's ``solvePnPRefineLM`` (its default criteria: at most
:data:`MAX_ITER` iterations, tolerance ``FLT_EPSILON``), so that each row's result is cv2's for the
same inputs up to rounding:

- parameters: the rotation vector and the translation, ``p = (rvec, tvec)``, updated additively;
  residuals: projected minus observed pixels, interleaved ``(u0, v0, u1, v1, ...)``; Jacobian: the
  derivatives of ``projectPoints`` (Rodrigues' formula and the (k1, k2, p1, p2, k3) model);
- energy: the sum of squared residuals; damping: ``lambda`` times the diagonal of J^T J, each term
  clamped to [``MIN_DIAG``, ``MAX_DIAG``], starting at :data:`LAMBDA0`;
- geodesic acceleration: the second directional derivative along the step from a probe at
  ``p + H_GEO x``, added (times :data:`GEO_SCALE`) when its relative size is below 1;
- a step is rejected when the energy increases: lambda times the up factor, which doubles each
  time; accepted: lambda times max(1/3, 1 - (2 q - 1)^3), q the actual over the predicted decrease;
- a row stops after :data:`MAX_ITER` tried steps, when lambda exceeds ``MAX_LAMBDA``, or after an
  accepted step with max |J^T r| below :data:`MIN_GRADIENT` (before the step), a squared step norm
  below :data:`STEP_TOL`, a relative energy decrease below :data:`REL_ENERGY_TOL`, or the energy
  below :data:`SMALL_ENERGY`.

Row-independent arithmetic only (elementwise array operations; sums over the corners and the 6 x 6
solves written out in a fixed order), so a row's result does not depend on how many rows are
refined with it. The residuals and the Jacobian are ``projectPoints``' to the bit; the normal
equations are solved by Gauss-Jordan elimination where OpenCV uses an SVD (LAPACK), and the
geodesic correction divides a difference of J^T r terms by ``H_GEO^2``, which magnifies rounding:
cv2's own result moves by up to a few micro-units when its input moves by one rounding unit, and
this module agrees with it to that level, not to the bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch.lm import HAT, solve6

F64 = NDArray[np.float64]

_FLT_EPSILON = float(np.finfo(np.float32).eps)
#: Iteration cap (tried steps, accepted or not), as cv2's default criteria.
MAX_ITER = 20
#: Stop when the squared norm of an accepted step is below this (cv2: the criteria's epsilon).
STEP_TOL = _FLT_EPSILON
#: Stop when the energy (px^2) is below this (cv2: epsilon squared).
SMALL_ENERGY = _FLT_EPSILON * _FLT_EPSILON
#: Stop when an accepted step lowers the energy by less than this fraction of the new energy.
REL_ENERGY_TOL = 1e-6
#: Stop when max |J^T r| (px^2 per parameter unit) is below this.
MIN_GRADIENT = 1e-6
#: Damping: initial lambda, its up factor after a rejected step (doubled each time) and down
#: divisor bound after an accepted one.
LAMBDA0, UP0, DOWN = 1e-4, 2.0, 3.0
#: Damping terms are clamped to [MIN_DIAG, MAX_DIAG]; a row stops once lambda reaches MAX_LAMBDA.
MIN_DIAG, MAX_DIAG, MAX_LAMBDA = 1e-6, 1e32, 1e32
#: Geodesic acceleration: probe fraction of the step, and the weight of the correction.
H_GEO, GEO_SCALE = 1e-4, 0.5

_DBL_EPSILON = float(np.finfo(np.float64).eps)
_IDX6 = np.arange(6)


def rodrigues_vector(R: F64) -> F64:
    """Rotation vectors (M, 3) of rotation matrices (M, 3, 3), as ``cv2.Rodrigues`` (the branch
    rules near 0 and pi included; the matrices are taken as orthonormal)."""
    Rf = R.reshape(-1, 9)
    rx, ry, rz = Rf[:, 7] - Rf[:, 5], Rf[:, 2] - Rf[:, 6], Rf[:, 3] - Rf[:, 1]
    s = np.sqrt((rx * rx + ry * ry + rz * rz) * 0.25)
    c = np.clip((Rf[:, 0] + Rf[:, 4] + Rf[:, 8] - 1.0) * 0.5, -1.0, 1.0)
    theta = np.arccos(c)
    with np.errstate(all="ignore"):
        vth = (1.0 / (2.0 * s)) * theta
        out = np.stack([rx * vth, ry * vth, rz * vth], axis=1)
        # |sin theta| < 1e-5: identity, or a half-turn whose axis comes from the diagonal
        px = np.sqrt(np.maximum((Rf[:, 0] + 1.0) * 0.5, 0.0))
        py = np.sqrt(np.maximum((Rf[:, 4] + 1.0) * 0.5, 0.0)) * np.where(Rf[:, 1] < 0, -1.0, 1.0)
        pz = np.sqrt(np.maximum((Rf[:, 8] + 1.0) * 0.5, 0.0)) * np.where(Rf[:, 2] < 0, -1.0, 1.0)
        flip = (np.abs(px) < np.abs(py)) & (np.abs(px) < np.abs(pz)) & ((Rf[:, 5] > 0) != (py * pz > 0))
        pz = np.where(flip, -pz, pz)
        th = theta / np.sqrt(px * px + py * py + pz * pz)
        half = np.stack([px * th, py * th, pz * th], axis=1)
    small = s < 1e-5
    out = np.where((small & (c > 0))[:, None], 0.0, out)
    return np.where((small & ~(c > 0))[:, None], half, out)


_EYE9 = np.array([1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0])


def rodrigues(r: F64, jacobian: bool = True) -> tuple[F64, F64]:
    """Rotation matrices (M, 9) row-major of rotation vectors r (M, 3) and, with ``jacobian``,
    their derivatives (M, 3, 9), ``[:, i, k]`` = d R_k / d r_i (else an empty array)
    (``cv2.Rodrigues``' formulas)."""
    theta = np.sqrt(r[:, 0] * r[:, 0] + r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2])
    tiny = theta < _DBL_EPSILON
    th = np.where(tiny, 1.0, theta)
    c, s = np.cos(th), np.sin(th)
    c1 = 1.0 - c
    it = 1.0 / th
    u = r * it[:, None]
    ux, uy, uz = u[:, 0], u[:, 1], u[:, 2]
    m = len(r)
    rrt = np.empty((m, 9))
    rrt[:, 0], rrt[:, 1], rrt[:, 2] = ux * ux, ux * uy, ux * uz
    rrt[:, 3], rrt[:, 4], rrt[:, 5] = uy * ux, uy * uy, uy * uz
    rrt[:, 6], rrt[:, 7], rrt[:, 8] = uz * ux, uz * uy, uz * uz
    rx = np.zeros((m, 9))
    rx[:, 1], rx[:, 2], rx[:, 3] = -uz, uy, uz
    rx[:, 5], rx[:, 6], rx[:, 7] = -ux, -uy, ux
    R = c[:, None] * _EYE9 + c1[:, None] * rrt + s[:, None] * rx
    if tiny.any():
        R = np.where(tiny[:, None], _EYE9, R)
    if not jacobian:
        return R, np.empty(0)
    drrt = np.zeros((m, 3, 9))  # d (u u^T) / d u_j, row j
    drrt[:, 0, 0], drrt[:, 0, 1], drrt[:, 0, 2], drrt[:, 0, 3], drrt[:, 0, 6] = ux + ux, uy, uz, uy, uz
    drrt[:, 1, 1], drrt[:, 1, 3], drrt[:, 1, 4], drrt[:, 1, 5], drrt[:, 1, 7] = ux, ux, uy + uy, uz, uz
    drrt[:, 2, 2], drrt[:, 2, 5], drrt[:, 2, 6], drrt[:, 2, 7], drrt[:, 2, 8] = ux, uy, ux, uy, uz + uz
    a0 = -s[:, None] * u
    a1 = (s - 2.0 * c1 * it)[:, None] * u
    a2 = (c1 * it)[:, None, None]
    a3 = (c - s * it)[:, None] * u
    a4 = (s * it)[:, None, None]
    dR = (
        a0[:, :, None] * _EYE9
        + a1[:, :, None] * rrt[:, None, :]
        + a2 * drrt
        + a3[:, :, None] * rx[:, None, :]
        + a4 * HAT
    )
    if tiny.any():
        dR = np.where(tiny[:, None, None], HAT, dR)
    return R, dR


class _Camera:
    """fx, fy, cx, cy (``projectPoints`` ignores the skew) and (k1, k2, p1, p2, k3) as floats."""

    def __init__(self, K: F64, dist: F64) -> None:
        self.fx, self.fy, self.cx, self.cy = float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2])
        self.k = tuple(float(v) for v in dist)


def project(cam: _Camera, obj: F64, p: F64, px: F64, jacobian: bool) -> tuple[F64, F64]:
    """Residuals (M, 2 P) px, projected minus observed ``px`` (M, P, 2), interleaved (u, v) per
    point, of the marker points ``obj`` (P, 3) at poses ``p`` (M, 6) = (rvec, tvec); with
    ``jacobian``, d residual / d p (M, 2 P, 6) (else an empty array). ``projectPoints``' formulas."""
    k0, k1, k2, k3, k4 = cam.k
    R, dR = rodrigues(p[:, :3], jacobian)
    t = p[:, 3:]
    X, Y, Z = obj[:, 0], obj[:, 1], obj[:, 2]
    R3 = R.reshape(-1, 3, 3, 1)
    cam_pts = R3[:, :, 0] * X + R3[:, :, 1] * Y + R3[:, :, 2] * Z + t[:, :, None]  # (M, 3, P)
    x, y, z = cam_pts[:, 0], cam_pts[:, 1], cam_pts[:, 2]
    z = np.where(z != 0.0, 1.0 / np.where(z != 0.0, z, 1.0), 1.0)
    x, y = x * z, y * z
    r2 = x * x + y * y
    r4 = r2 * r2
    r6 = r4 * r2
    a1 = 2.0 * x * y
    a2 = r2 + 2.0 * x * x
    a3 = r2 + 2.0 * y * y
    cdist = 1.0 + k0 * r2 + k1 * r4 + k4 * r6
    xd = x * cdist + k2 * a1 + k3 * a2
    yd = y * cdist + k2 * a3 + k3 * a1
    res = np.empty((len(p), 2 * len(X)))
    res[:, 0::2] = xd * cam.fx + cam.cx - px[:, :, 0]
    res[:, 1::2] = yd * cam.fy + cam.cy - px[:, :, 1]
    if not jacobian:
        return res, np.empty(0)
    J = np.empty((len(p), 2 * len(X), 6))

    dc = (k0 + 2.0 * k1 * r2 + 3.0 * k4 * r4)[:, None]
    xb, yb, r2b, r4b, cb = x[:, None], y[:, None], r2[:, None], r4[:, None], cdist[:, None]

    def chain(dxd: F64, dyd: F64, rotation: bool) -> tuple[F64, F64]:
        """d (u, v) of the derivatives (M, C, P) of the normalised point (columns side by side)."""
        dr2 = 2.0 * xb * dxd + 2.0 * yb * dyd
        # (cv2 writes the translation columns' dcdist expanded, the rotation columns' factored)
        dcdist = dc * dr2 if rotation else k0 * dr2 + 2.0 * k1 * r2b * dr2 + 3.0 * k4 * r4b * dr2
        da1 = 2.0 * (xb * dyd + yb * dxd)
        dmx = dxd * cb + xb * dcdist + k2 * da1 + k3 * (dr2 + 4.0 * xb * dxd)
        dmy = dyd * cb + yb * dcdist + k2 * (dr2 + 4.0 * yb * dyd) + k3 * da1
        return cam.fx * dmx, cam.fy * dmy

    m, n_pt = x.shape
    dxt, dyt = np.zeros((m, 3, n_pt)), np.zeros((m, 3, n_pt))
    dxt[:, 0], dyt[:, 1] = z, z
    dxt[:, 2], dyt[:, 2] = -x * z, -y * z
    ju, jv = chain(dxt, dyt, False)
    J[:, 0::2, 3:] = ju.transpose(0, 2, 1)
    J[:, 1::2, 3:] = jv.transpose(0, 2, 1)
    dR3 = dR.reshape(-1, 3, 3, 3, 1)
    d_pts = dR3[:, :, :, 0] * X + dR3[:, :, :, 1] * Y + dR3[:, :, :, 2] * Z  # (M, 3 params, 3, P)
    dx0, dy0, dz0 = d_pts[:, :, 0], d_pts[:, :, 1], d_pts[:, :, 2]
    zb = z[:, None]
    ju, jv = chain(zb * (dx0 - xb * dz0), zb * (dy0 - yb * dz0), True)
    J[:, 0::2, :3] = ju.transpose(0, 2, 1)
    J[:, 1::2, :3] = jv.transpose(0, 2, 1)
    return res, J


def _sum(a: F64) -> F64:
    """Sum over the last axis in index order (the same additions whatever the leading shape)."""
    s = a[..., 0]
    for k in range(1, a.shape[-1]):
        s = s + a[..., k]
    return s


def _normal(J: F64, r: F64) -> tuple[F64, F64]:
    """J^T J (M, 6, 6) and J^T r (M, 6) of J (M, E, 6), r (M, E), summed in residual order."""
    return _sum(np.swapaxes(J[:, :, :, None] * J[:, :, None, :], 1, 3)), _sum(
        np.swapaxes(J * r[:, :, None], 1, 2)
    )


def _damped(jtj: F64, diag: F64, lam: F64) -> tuple[F64, F64]:
    """J^T J with its diagonal replaced by ``diag + lmDiag``; lmDiag = clamp(lambda diag)."""
    lm_diag = np.minimum(np.maximum(diag * lam[:, None], MIN_DIAG), MAX_DIAG)
    A = jtj.copy()
    A[:, _IDX6, _IDX6] = lm_diag + diag
    return A, lm_diag


def refine_cv_lm(
    K: F64, dist: F64, rvec: F64, tvec: F64, obj: F64, px: F64, max_iter: int = MAX_ITER
) -> tuple[F64, F64, F64, NDArray[np.int64]]:
    """``cv2.solvePnPRefineLM(obj, px[i], K, dist, rvec[i], tvec[i])`` for each row i (default
    criteria): rotation vectors (M, 3) and translations (M, 3) m of the marker points ``obj``
    (P, 3) on pixels ``px`` (M, P, 2), camera ``K`` (3, 3), ``dist`` (k1, k2, p1, p2, k3).

    Returns the refined rvec (M, 3), tvec (M, 3), the energies (M,) px^2 (sum of squared
    residuals) at them, and the tried steps (M,). A row whose energy becomes NaN keeps its last
    accepted pose (as cv2).
    """
    cam = _Camera(K, dist)
    p_out = np.concatenate([rvec, tvec], axis=1).astype(np.float64)
    n = len(p_out)
    iters = np.zeros(n, dtype=np.int64)
    with np.errstate(all="ignore"):
        res, J = project(cam, obj, p_out, px, True)
        e_out = _sum(res * res)
        if max_iter <= 0 or n == 0:
            return p_out[:, :3].copy(), p_out[:, 3:].copy(), e_out, iters
        rows = np.arange(n)
        p, e, pxw = p_out, e_out.copy(), px
        jtj, jtb = _normal(J, res)
        diag = jtj[:, _IDX6, _IDX6].copy()
        gmax = np.abs(jtb).max(axis=1)
        lam, up = np.full(n, LAMBDA0), np.full(n, UP0)
        it = np.zeros(n, dtype=np.int64)
        while len(rows):
            A, lm_diag = _damped(jtj, diag, lam)
            x = solve6(A, -jtb)
            jac_change = -0.5 * _sum(x * (jtb - lm_diag * x))
            x_norm = _sum(x * x)
            # geodesic acceleration
            r_v, _ = project(cam, obj, p + x * H_GEO, pxw, False)
            jtbv = _sum(np.swapaxes(J * r_v[:, :, None], 1, 2))
            jtrvv = (jtbv + jtb * (H_GEO - 1.0) + lm_diag * x * H_GEO) / (H_GEO * H_GEO)
            x_geo = solve6(A, -jtrvv)
            good = np.sqrt(_sum(x_geo * x_geo) / _sum(x * x)) < 1.0
            x = np.where(good[:, None], x + x_geo * GEO_SCALE, x)
            probe = p + x
            r_new, J_new = project(cam, obj, probe, pxw, True)
            e_new = _sum(r_new * r_new)
            failed = np.isnan(e_new) | (e_new < 0)
            change = e - e_new
            quality = change / jac_change
            acc = ~failed & ~(change < 0)
            rej = ~failed & ~acc
            f = 1.0 - (2.0 * quality - 1.0) ** 3
            down = np.where(1.0 / DOWN < f, f, 1.0 / DOWN)  # std::max(1/3, f): 1/3 when f is NaN
            lam = np.where(acc, lam * down, np.where(rej, lam * up, lam))
            up = np.where(acc, UP0, np.where(rej, up * 2.0, up))
            it += 1
            stop = failed | (it >= max_iter) | (lam >= MAX_LAMBDA)
            stop |= acc & (
                (gmax < MIN_GRADIENT)
                | (x_norm < STEP_TOL)
                | (change / e_new < REL_ENERGY_TOL)
                | (e_new < SMALL_ENERGY)
            )
            p = np.where(acc[:, None], probe, p)
            e = np.where(acc, e_new, e)
            J = np.where(acc[:, None, None], J_new, J)
            res_acc = np.where(acc[:, None], r_new, 0.0)
            if acc.any():
                jtj_new, jtb_new = _normal(J, res_acc)
                jtj = np.where(acc[:, None, None], jtj_new, jtj)
                jtb = np.where(acc[:, None], jtb_new, jtb)
                diag = np.where(acc[:, None], jtj_new[:, _IDX6, _IDX6], diag)
                gmax = np.where(acc, np.abs(jtb_new).max(axis=1), gmax)
            if stop.any():
                done = rows[stop]
                p_out[done], e_out[done], iters[done] = p[stop], e[stop], it[stop]
                keep = ~stop
                rows = rows[keep]
                it = it[keep]
                p, e, pxw, J, jtj, jtb, diag, gmax, lam, up = (
                    a[keep] for a in (p, e, pxw, J, jtj, jtb, diag, gmax, lam, up)
                )
    return p_out[:, :3].copy(), p_out[:, 3:].copy(), e_out, iters


__all__ = [
    "MAX_ITER",
    "MIN_GRADIENT",
    "REL_ENERGY_TOL",
    "SMALL_ENERGY",
    "STEP_TOL",
    "project",
    "refine_cv_lm",
    "rodrigues",
    "rodrigues_vector",
]
