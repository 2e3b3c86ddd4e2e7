"""``cv2.solvePnPRefineLM``'s Levenberg-Marquardt for one pose, with a fixed number of iterations:
the port of OpenCV's algorithm (:mod:`ihrcf_env.core.estimators.cv_lm`: its parametrisation
``p = (rvec, tvec)``, residuals and Jacobian of ``projectPoints``, damping, geodesic acceleration and stopping
rules). The loop always runs ``max_iter`` steps under ``lax.scan``; once a stopping rule fires
the pose is frozen, so the result is the stopping algorithm's. The damped normal equations are
solved by an unrolled Cholesky factorisation (cv2 uses an SVD): the results agree with cv2's to
the rounding its geodesic step magnifies, not to the bit.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array, lax

from ihrcf_env.core.estimators import cv_lm as cvlm

__all__ = [
    "LMResult",
    "cholesky6",
    "cholesky_solve",
    "cholesky_solve6",
    "refine_lm",
    "residuals",
    "rodrigues",
    "rodrigues_vector",
]

_DBL_EPSILON = float(np.finfo(np.float64).eps)
_EYE9 = np.array([1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0])
_HAT = np.zeros((3, 9))
_HAT[2, 1], _HAT[1, 2], _HAT[0, 5] = -1.0, 1.0, -1.0
_HAT[2, 3], _HAT[1, 6], _HAT[0, 7] = 1.0, -1.0, 1.0


def rodrigues_vector(R: Array) -> Array:
    """Rotation vector (3,) of a rotation matrix (3, 3), as ``cv2.Rodrigues`` (with its branch rules
    near 0 and pi)."""
    Rf = R.reshape(9)
    rx, ry, rz = Rf[7] - Rf[5], Rf[2] - Rf[6], Rf[3] - Rf[1]
    s = jnp.sqrt((rx * rx + ry * ry + rz * rz) * 0.25)
    c = jnp.clip((Rf[0] + Rf[4] + Rf[8] - 1.0) * 0.5, -1.0, 1.0)
    theta = jnp.arccos(c)
    small = s < 1e-5
    vth = (1.0 / (2.0 * jnp.where(small, 1.0, s))) * theta
    out = jnp.stack([rx * vth, ry * vth, rz * vth])
    px = jnp.sqrt(jnp.maximum((Rf[0] + 1.0) * 0.5, 0.0))
    py = jnp.sqrt(jnp.maximum((Rf[4] + 1.0) * 0.5, 0.0)) * jnp.where(Rf[1] < 0, -1.0, 1.0)
    pz = jnp.sqrt(jnp.maximum((Rf[8] + 1.0) * 0.5, 0.0)) * jnp.where(Rf[2] < 0, -1.0, 1.0)
    flip = (jnp.abs(px) < jnp.abs(py)) & (jnp.abs(px) < jnp.abs(pz)) & ((Rf[5] > 0) != (py * pz > 0))
    pz = jnp.where(flip, -pz, pz)
    th = theta / jnp.sqrt(px * px + py * py + pz * pz)
    half = jnp.stack([px * th, py * th, pz * th])
    out = jnp.where(small & (c > 0), 0.0, out)
    return jnp.where(small & ~(c > 0), half, out)


def rodrigues(r: Array) -> tuple[Array, Array]:
    """Rotation matrix (9,) row-major of a rotation vector ``r`` (3,) and its derivatives (3, 9),
    ``[i, k] = d R_k / d r_i`` (``cv2.Rodrigues``' formulas)."""
    theta = jnp.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    tiny = theta < _DBL_EPSILON
    th = jnp.where(tiny, 1.0, theta)
    c, s = jnp.cos(th), jnp.sin(th)
    c1 = 1.0 - c
    it = 1.0 / th
    u = r * it
    ux, uy, uz = u[0], u[1], u[2]
    zero = jnp.zeros_like(ux)
    rrt = (u[:, None] * u[None, :]).reshape(9)  # u u^T row-major
    rx = jnp.stack([zero, -uz, uy, uz, zero, -ux, -uy, ux, zero])
    eye = jnp.asarray(_EYE9, r.dtype)  # the constants in the rotation vector's dtype
    R = c * eye + c1 * rrt + s * rx
    R = jnp.where(tiny, eye, R)
    drrt = jnp.stack(
        [
            jnp.stack([ux + ux, uy, uz, uy, zero, zero, uz, zero, zero]),
            jnp.stack([zero, ux, zero, ux, uy + uy, uz, zero, uz, zero]),
            jnp.stack([zero, zero, ux, zero, zero, uy, ux, uy, uz + uz]),
        ]
    )
    a0 = -s * u
    a1 = (s - 2.0 * c1 * it) * u
    a3 = (c - s * it) * u
    hat = jnp.asarray(_HAT, r.dtype)
    dR = (
        a0[:, None] * eye
        + a1[:, None] * rrt[None, :]
        + (c1 * it) * drrt
        + a3[:, None] * rx[None, :]
        + (s * it) * hat
    )
    dR = jnp.where(tiny, hat, dR)
    return R, dR


def residuals(
    K: Array, dist: Array, obj: Array, p: Array, px: Array, jacobian: bool = True
) -> tuple[Array, Array]:
    """Residuals (2 P,) px, projected minus observed ``px`` (P, 2), interleaved (u, v) per point, of
    the marker points ``obj`` (P, 3) at the pose ``p`` (6,) = (rvec, tvec); with ``jacobian`` also
    d residual / d p (2 P, 6) (else an empty array). ``projectPoints``' formulas (no skew)."""
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    k0, k1, k2, k3, k4 = dist[0], dist[1], dist[2], dist[3], dist[4]
    R, dR = rodrigues(p[:3])
    t = p[3:]
    X, Y, Z = obj[:, 0], obj[:, 1], obj[:, 2]
    R3 = R.reshape(3, 3)
    cam = R3[:, 0, None] * X + R3[:, 1, None] * Y + R3[:, 2, None] * Z + t[:, None]  # (3, P)
    x, y, z = cam[0], cam[1], cam[2]
    z = jnp.where(z != 0.0, 1.0 / jnp.where(z != 0.0, z, 1.0), 1.0)
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
    res = jnp.stack([xd * fx + cx - px[:, 0], yd * fy + cy - px[:, 1]], axis=-1).reshape(-1)
    if not jacobian:
        return res, jnp.zeros((0,), dtype=res.dtype)
    dc = k0 + 2.0 * k1 * r2 + 3.0 * k4 * r4

    def chain(dxd: Array, dyd: Array, rotation: bool) -> tuple[Array, Array]:
        dr2 = 2.0 * x * dxd + 2.0 * y * dyd
        dcdist = dc * dr2 if rotation else k0 * dr2 + 2.0 * k1 * r2 * dr2 + 3.0 * k4 * r4 * dr2
        da1 = 2.0 * (x * dyd + y * dxd)
        dmx = dxd * cdist + x * dcdist + k2 * da1 + k3 * (dr2 + 4.0 * x * dxd)
        dmy = dyd * cdist + y * dcdist + k2 * (dr2 + 4.0 * y * dyd) + k3 * da1
        return fx * dmx, fy * dmy

    zeros = jnp.zeros_like(x)
    dxt = jnp.stack([z, zeros, -x * z])  # (3 params, P)
    dyt = jnp.stack([zeros, z, -y * z])
    ju_t, jv_t = chain(dxt, dyt, False)
    dR3 = dR.reshape(3, 3, 3)  # (param, row, col)
    d_pts = dR3[:, :, 0, None] * X + dR3[:, :, 1, None] * Y + dR3[:, :, 2, None] * Z  # (3, 3, P)
    dx0, dy0, dz0 = d_pts[:, 0], d_pts[:, 1], d_pts[:, 2]
    ju_r, jv_r = chain(z * (dx0 - x * dz0), z * (dy0 - y * dz0), True)
    ju = jnp.concatenate([ju_r, ju_t], axis=0).T  # (P, 6)
    jv = jnp.concatenate([jv_r, jv_t], axis=0).T
    J = jnp.stack([ju, jv], axis=1).reshape(-1, 6)
    return res, J


def cholesky6(A: Array) -> list[list[Array]]:
    """The lower Cholesky factor of a symmetric positive definite 6x6 ``A`` (unrolled), as rows of
    scalars (the entries above the diagonal are zeros)."""
    n = 6
    L = [[jnp.zeros_like(A[0, 0]) for _ in range(n)] for _ in range(n)]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s = s - L[j][k] * L[j][k]
        d = jnp.sqrt(s)
        L[j][j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / d
    return L


def cholesky_solve(L: list[list[Array]], b: Array) -> Array:
    """``A^-1 b`` from the Cholesky factor ``L`` of ``A`` (forward and back substitution)."""
    n = len(L)
    y: list[Array] = []
    for i in range(n):
        s = b[i]
        for k in range(i):
            s = s - L[i][k] * y[k]
        y.append(s / L[i][i])
    x: list[Array] = [jnp.zeros_like(b[0])] * n
    for i in reversed(range(n)):
        s = y[i]
        for k in range(i + 1, n):
            s = s - L[k][i] * x[k]
        x[i] = s / L[i][i]
    return jnp.stack(x)


def cholesky_solve6(A: Array, b: Array) -> Array:
    """``A^-1 b`` of a symmetric positive definite 6x6 system by an unrolled Cholesky factorisation."""
    return cholesky_solve(cholesky6(A), b)


def _normal(J: Array, r: Array) -> tuple[Array, Array]:
    """``J^T J`` (6, 6) and ``J^T r`` (6,) as products summed over the residuals (element-wise: cheaper
    than a batched matrix product at this size)."""
    return jnp.sum(J[:, :, None] * J[:, None, :], axis=0), jnp.sum(J * r[:, None], axis=0)


class LMResult(NamedTuple):
    """The refined ``rvec`` (3,), ``tvec`` (3,) m, the ``energy`` (sum of squared residuals, px^2)
    at them and the steps tried before a stopping rule fired (``iterations``)."""

    rvec: Array
    tvec: Array
    energy: Array
    iterations: Array


class _State(NamedTuple):
    p: Array
    e: Array
    J: Array
    jtj: Array
    jtb: Array
    diag: Array
    gmax: Array
    lam: Array
    up: Array
    it: Array
    done: Array


def refine_lm(
    K: Array, dist: Array, rvec: Array, tvec: Array, obj: Array, px: Array, max_iter: int = cvlm.MAX_ITER
) -> LMResult:
    """``cv2.solvePnPRefineLM(obj, px, K, dist, rvec, tvec)`` with at most ``max_iter`` tried steps
    (cv2's default criteria at 20): marker points ``obj`` (P, 3), pixels ``px`` (P, 2), camera ``K``
    (3, 3), ``dist`` (k1, k2, p1, p2, k3). A pose whose energy becomes NaN keeps its last accepted
    value (as cv2)."""
    p0 = jnp.concatenate([rvec, tvec])
    res, J = residuals(K, dist, obj, p0, px)
    e0 = jnp.sum(res * res)
    jtj, jtb = _normal(J, res)
    diag = jnp.diagonal(jtj)
    init = _State(
        p0,
        e0,
        J,
        jtj,
        jtb,
        diag,
        jnp.max(jnp.abs(jtb)),
        jnp.asarray(cvlm.LAMBDA0, dtype=p0.dtype),
        jnp.asarray(cvlm.UP0, dtype=p0.dtype),
        jnp.asarray(0),
        jnp.asarray(max_iter <= 0),
    )
    h = cvlm.H_GEO

    def step(st: _State, _: None) -> tuple[_State, None]:
        lm_diag = jnp.minimum(jnp.maximum(st.diag * st.lam, cvlm.MIN_DIAG), cvlm.MAX_DIAG)
        A = st.jtj.at[jnp.arange(6), jnp.arange(6)].set(lm_diag + st.diag)
        L = cholesky6(A)  # one factorisation for the step and its geodesic correction
        x = cholesky_solve(L, -st.jtb)
        jac_change = -0.5 * jnp.sum(x * (st.jtb - lm_diag * x))
        x_norm = jnp.sum(x * x)
        r_v = residuals(K, dist, obj, st.p + x * h, px, jacobian=False)[0]
        jtbv = _normal(st.J, r_v)[1]
        jtrvv = (jtbv + st.jtb * (h - 1.0) + lm_diag * x * h) / (h * h)
        x_geo = cholesky_solve(L, -jtrvv)
        good = jnp.sqrt(jnp.sum(x_geo * x_geo) / jnp.sum(x * x)) < 1.0
        x = jnp.where(good, x + x_geo * cvlm.GEO_SCALE, x)
        probe = st.p + x
        r_new, J_new = residuals(K, dist, obj, probe, px)
        e_new = jnp.sum(r_new * r_new)
        failed = jnp.isnan(e_new) | (e_new < 0)
        change = st.e - e_new
        quality = change / jac_change
        acc = ~failed & ~(change < 0)
        rej = ~failed & ~acc
        f = 1.0 - (2.0 * quality - 1.0) ** 3
        down = jnp.where(1.0 / cvlm.DOWN < f, f, 1.0 / cvlm.DOWN)
        lam = jnp.where(acc, st.lam * down, jnp.where(rej, st.lam * st.up, st.lam))
        up = jnp.where(acc, cvlm.UP0, jnp.where(rej, st.up * 2.0, st.up))
        it = st.it + 1
        stop = failed | (it >= max_iter) | (lam >= cvlm.MAX_LAMBDA)
        stop |= acc & (
            (st.gmax < cvlm.MIN_GRADIENT)
            | (x_norm < cvlm.STEP_TOL)
            | (change / e_new < cvlm.REL_ENERGY_TOL)
            | (e_new < cvlm.SMALL_ENERGY)
        )
        J_acc = jnp.where(acc, J_new, st.J)
        jtj_new, jtb_new = _normal(J_acc, r_new)
        new = _State(
            jnp.where(acc, probe, st.p),
            jnp.where(acc, e_new, st.e),
            J_acc,
            jnp.where(acc, jtj_new, st.jtj),
            jnp.where(acc, jtb_new, st.jtb),
            jnp.where(acc, jnp.diagonal(jtj_new), st.diag),
            jnp.where(acc, jnp.max(jnp.abs(jtb_new)), st.gmax),
            lam,
            up,
            it,
            stop,
        )
        out = _State(*(jnp.where(st.done, old, nw) for old, nw in zip(st, new, strict=True)))
        return out, None

    final, _ = lax.scan(step, init, None, length=max(int(max_iter), 0))
    return LMResult(final.p[:3], final.p[3:], final.e, final.it)
