"""Batched Levenberg-Marquardt refinement of square-tag poses on their four corners.

Minimises the squared reprojection error of the marker points (OpenCV's pinhole camera with the
(k1, k2, p1, p2, k3) distortion model) over poses ``X_cam = R X_marker + t``, with the update
``R <- exp(w) R``, ``t <- exp(w) t + dt`` (a rotation about the camera centre, then a shift).

Every row is refined independently with elementwise array arithmetic only: sums over the corners
and the normal-equation solve (Gauss-Jordan, written out) are explicit, in a fixed order, so a
row's result does not depend on how many rows are refined with it (no reduction whose order
depends on N, no BLAS / LAPACK call). Rows stop on their own convergence test (a per-row mask) and
stop being updated; the working set shrinks when many rows have stopped.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: Iteration cap of :func:`refine_lm`.
MAX_ITER = 30
#: Convergence: the predicted decrease of the squared error below this fraction of it ...
PRED_TOL = 1e-15
#: ... or every step component below this fraction of (1 + the largest |t| component, m).
STEP_TOL = 1e-12
#: Damping: initial and bounds (beyond the upper bound a row stops).
LAM0, LAM_MIN, LAM_MAX = 1e-6, 1e-9, 1e8
#: Flip pairs: a row stops when its squared error exceeds this times its partner's (RMS ratio 4) ...
CLEAR_RATIO2 = 16.0
#: ... or when it is within these of its converged partner (then it takes the partner's result).
DUP_T, DUP_R = 1e-4, 1e-4
#: Damping after a rejected step: at least this, else ten times the last.
LAM_REJECT = 1e-3

_EYE3 = np.eye(3)
_DIAG6 = (np.arange(6), np.arange(6))
#: (M, 3) rotation vectors @ HAT -> (M, 9) skew matrices [w]x, row-major (exact: one term per
#: entry); row i is also d [w]x / d w_i.
HAT = np.zeros((3, 9))
HAT[2, 1], HAT[1, 2], HAT[0, 5] = -1.0, 1.0, -1.0
HAT[2, 3], HAT[1, 6], HAT[0, 7] = 1.0, -1.0, 1.0


def _sum_last(a: F64) -> F64:
    """Sum over the last axis (length 4, 6 or 8) in a fixed order, whatever the leading shape."""
    n = a.shape[-1]
    s = a[..., 0] + a[..., 1]
    for k in range(2, n):
        s = s + a[..., k]
    return s


class Camera:
    """The pinhole + distortion model's constants as floats (one camera for all rows)."""

    def __init__(self, K: F64, dist: F64) -> None:
        self.fx, self.s, self.cx = float(K[0, 0]), float(K[0, 1]), float(K[0, 2])
        self.fy, self.cy = float(K[1, 1]), float(K[1, 2])
        self.k1, self.k2, self.p1, self.p2, self.k3 = (float(v) for v in dist)


def evaluate(
    cam: Camera, ox: F64, oy: F64, R: F64, t: F64, pu: F64, pv: F64, jacobian: bool = True
) -> tuple[F64, F64, F64]:
    """Squared reprojection error (M,) px^2 of poses R (M, 3, 3), t (M, 3) of the marker points
    (ox, oy, 0) (4,) against pixels (pu, pv) (M, 4); with ``jacobian``, the normal equations' J^T J
    (M, 6, 6) and J^T r (M, 6) in the (w, dt) parameters (else two empty arrays)."""
    X = R[:, :, 0, None] * ox + R[:, :, 1, None] * oy + t[:, :, None]  # (M, 3, 4)
    iz = 1.0 / X[:, 2]
    x, y = X[:, 0] * iz, X[:, 1] * iz
    xx, yy, xy = x * x, y * y, x * y
    r2 = xx + yy
    k1, k2, k3, p1, p2 = cam.k1, cam.k2, cam.k3, cam.p1, cam.p2
    rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * rad + (2.0 * p1) * xy + p2 * (r2 + 2.0 * xx)
    yd = y * rad + p1 * (r2 + 2.0 * yy) + (2.0 * p2) * xy
    r = np.concatenate([cam.fx * xd + cam.s * yd + cam.cx - pu, cam.fy * yd + cam.cy - pv], axis=1)
    cost = _sum_last(r * r)
    if not jacobian:
        return cost, np.empty(0), np.empty(0)
    drad = 2.0 * (k1 + r2 * (2.0 * k2 + (3.0 * k3) * r2))  # 2 d rad / d r2
    a = rad + xx * drad + (2.0 * p1) * y + (6.0 * p2) * x  # d(xd, yd) / d(x, y) = [[a, b], [b, d]]
    b = xy * drad + (2.0 * p1) * x + (2.0 * p2) * y
    d = rad + yy * drad + (6.0 * p1) * y + (2.0 * p2) * x
    # d(x, y) / d(w, dt) for X' = X + w x X + dt
    zero = np.zeros_like(x)
    dx = np.stack([-xy, 1.0 + xx, -y, iz, zero, -x * iz], axis=1)  # (M, 6, 4)
    dy = np.stack([-1.0 - yy, xy, x, zero, iz, -y * iz], axis=1)
    fa, fb = (cam.fx * a + cam.s * b)[:, None], (cam.fx * b + cam.s * d)[:, None]
    J = np.concatenate([fa * dx + fb * dy, (cam.fy * b)[:, None] * dx + (cam.fy * d)[:, None] * dy], axis=2)
    A = _sum_last(J[:, :, None, :] * J[:, None, :, :])  # (M, 6, 6)
    g = _sum_last(J * r[:, None, :])  # (M, 6)
    return cost, A, g


def solve6(A: F64, b: F64) -> F64:
    """Solutions x (M, 6) of symmetric positive definite systems A (M, 6, 6) x = b (M, 6) by
    Gauss-Jordan elimination without pivoting (written out: the same arithmetic for every row)."""
    T = np.concatenate([A, b[:, :, None]], axis=2)
    for k in range(6):
        row = T[:, k, k:] / T[:, k, k, None]
        T[:, :, k:] = T[:, :, k:] - T[:, :, k, None] * row[:, None, :]
        T[:, k, k:] = row
    return T[:, :, 6]


def _rotation(w: F64) -> F64:
    """exp([w]x) (M, 3, 3) of rotation vectors w (M, 3) (Rodrigues)."""
    th2 = _sum_last(w * w)
    small = th2 < 1e-16
    th = np.sqrt(np.where(small, 1.0, th2))
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(th) / th)
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(th)) / (th * th))
    W = (w @ HAT).reshape(-1, 3, 3)
    return (
        (1.0 - b * th2)[:, None, None] * _EYE3
        + a[:, None, None] * W
        + b[:, None, None] * (w[:, :, None] * w[:, None, :])
    )


def _apply(E: F64, R: F64, t: F64, dt: F64) -> tuple[F64, F64]:
    """(E R, E t + dt) with the 3-term sums written out."""
    R_new = (
        E[:, :, 0, None] * R[:, None, 0, :]
        + E[:, :, 1, None] * R[:, None, 1, :]
        + E[:, :, 2, None] * R[:, None, 2, :]
    )
    t_new = E[:, :, 0] * t[:, 0, None] + E[:, :, 1] * t[:, 1, None] + E[:, :, 2] * t[:, 2, None] + dt
    return R_new, t_new


def refine_lm(
    K: F64,
    dist: F64,
    R: F64,
    t: F64,
    obj: F64,
    px: F64,
    max_iter: int | None = None,
    flip_pairs: bool = False,
) -> tuple[F64, F64, F64, NDArray[np.int64]]:
    """Levenberg-Marquardt (Marquardt scaling) of poses R (M, 3, 3), t (M, 3) of the marker points
    ``obj`` (4, 3) (z = 0) on pixels ``px`` (M, 4, 2). A row stops when the predicted decrease of
    its squared error falls below :data:`PRED_TOL` of it, its step below :data:`STEP_TOL`, its
    damping above ``LAM_MAX``, or after ``max_iter`` iterations.

    With ``flip_pairs`` (M even), rows 2i and 2i + 1 are the two IPPE solutions of one frame: a
    row also stops when its squared error exceeds :data:`CLEAR_RATIO2` times its partner's (it is
    then clearly the worse of the two and is left as it is), or when it comes within ``DUP_T`` m /
    ``DUP_R`` of its converged partner's pose (the same minimum: it takes the partner's result).

    Returns the polished R, t, the RMS reprojection errors (M,) px, and the iterations used (M,).
    """
    max_iter = MAX_ITER if max_iter is None else max_iter
    cam = Camera(K, dist)
    ox, oy = np.ascontiguousarray(obj[:, 0]), np.ascontiguousarray(obj[:, 1])
    pu_all, pv_all = np.ascontiguousarray(px[:, :, 0]), np.ascontiguousarray(px[:, :, 1])
    R_out, t_out = np.array(R, dtype=np.float64), np.array(t, dtype=np.float64)
    with np.errstate(all="ignore"):
        cost_out, A, g = evaluate(cam, ox, oy, R_out, t_out, pu_all, pv_all, jacobian=max_iter > 0)
        iters = np.zeros(len(R_out), dtype=np.int64)
        if max_iter <= 0:
            return R_out, t_out, np.sqrt(cost_out / 4.0), iters
        rows = np.flatnonzero(np.isfinite(cost_out))
        Rw, tw, cost, pu, pv = R_out[rows], t_out[rows], cost_out[rows], pu_all[rows], pv_all[rows]
        A, g = A[rows], g[rows]
        lam = np.full(len(rows), LAM0)
        active = np.ones(len(rows), dtype=bool)
        it = np.zeros(len(rows), dtype=np.int64)
        converged = np.zeros(len(R_out), dtype=bool)  # stopped on the convergence test
        duplicate = np.zeros(len(R_out), dtype=bool)
        for _ in range(max_iter):
            Ad = A.copy()
            Ad[:, _DIAG6[0], _DIAG6[1]] *= 1.0 + lam[:, None]
            step = solve6(Ad, -g)
            pred = -_sum_last(g * step)
            size = np.abs(step).max(axis=1)
            done = active & (~(pred > PRED_TOL * cost) | (size <= STEP_TOL * (1.0 + np.abs(tw).max(axis=1))))
            active &= ~done
            if flip_pairs:
                converged[rows[done]] = True
                part = rows ^ 1
                cost_out[rows], t_out[rows], R_out[rows] = cost, tw, Rw
                near = (
                    active
                    & converged[part]
                    & (np.abs(tw - t_out[part]).max(axis=1) < DUP_T)
                    & (np.abs(Rw - R_out[part]).max(axis=(1, 2)) < DUP_R)
                )
                duplicate[rows[near]] = True
                active &= ~near & ~(cost > CLEAR_RATIO2 * cost_out[part])
            if active.any():
                R_new, t_new = _apply(_rotation(step[:, :3]), Rw, tw, step[:, 3:])
                cost_new, A_new, g_new = evaluate(cam, ox, oy, R_new, t_new, pu, pv)
                acc = active & (cost_new <= cost)
                it += active
                Rw = np.where(acc[:, None, None], R_new, Rw)
                tw = np.where(acc[:, None], t_new, tw)
                A = np.where(acc[:, None, None], A_new, A)
                g = np.where(acc[:, None], g_new, g)
                cost = np.where(acc, cost_new, cost)
                lam = np.where(acc, np.maximum(lam / 10.0, LAM_MIN), np.maximum(lam * 10.0, LAM_REJECT))
                active &= lam <= LAM_MAX
            n_active = int(active.sum())
            if n_active == 0 or 2 * n_active <= len(rows) and len(rows) > 8:
                # store the finished rows; carry on with the active ones only
                R_out[rows], t_out[rows], cost_out[rows], iters[rows] = Rw, tw, cost, it
                if n_active == 0:
                    break
                keep = active
                rows, it = rows[keep], it[keep]
                Rw, tw, cost, pu, pv, A, g, lam = (a[keep] for a in (Rw, tw, cost, pu, pv, A, g, lam))
                active = active[keep]
        else:
            R_out[rows], t_out[rows], cost_out[rows], iters[rows] = Rw, tw, cost, it
        dup = np.flatnonzero(duplicate)
        R_out[dup], t_out[dup], cost_out[dup] = R_out[dup ^ 1], t_out[dup ^ 1], cost_out[dup ^ 1]
        return R_out, t_out, np.sqrt(cost_out / 4.0), iters


__all__ = [
    "CLEAR_RATIO2",
    "HAT",
    "LAM_REJECT",
    "MAX_ITER",
    "PRED_TOL",
    "STEP_TOL",
    "Camera",
    "evaluate",
    "refine_lm",
    "solve6",
]
