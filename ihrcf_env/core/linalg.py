"""Dense linear algebra on tiny matrices (2x2 to 4x3) for per-frame estimator code.

On matrices this small ``numpy.linalg``'s cost is mostly Python-level checks and dispatch, which
OpenCV's compiled routines avoid. The estimators call these a few dozen times per camera frame, so
they use the wrappers below. The results equal numpy's to
floating-point rounding (``tests/core/test_linalg.py``), not bit for bit: the algorithms differ
(one-sided Jacobi SVD; for k <= 3 OpenCV inverts and solves in closed form, by the adjugate
and Cramer's rule, which is accurate for the well-conditioned covariances met here).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray


def svd(a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Thin SVD ``a = U diag(s) Vt`` of a float64 (M, N) matrix, M >= N: ``U`` (M, N), ``s`` (N,)
    in decreasing order, ``Vt`` (N, N). Non-finite input gives NaN factors (no exception)."""
    s, u, vt = cv2.SVDecomp(np.ascontiguousarray(a, dtype=np.float64))
    return (
        np.asarray(u, dtype=np.float64),
        np.asarray(s, dtype=np.float64).ravel(),
        np.asarray(vt, dtype=np.float64),
    )


def spd_inverse(S: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """Inverses (n, k, k) and log-determinants (n,) of a stack of symmetric positive-definite
    (n, k, k) matrices, or None if a determinant is not positive and finite (the only check: the
    callers' matrices are a covariance plus a positive-definite noise)."""
    S = np.ascontiguousarray(S, dtype=np.float64)
    inv = np.empty_like(S)
    logdet = np.empty(len(S))
    for i in range(len(S)):
        det = cv2.determinant(S[i])
        if not det > 0.0 or not math.isfinite(det):
            return None
        logdet[i] = math.log(det)
        cv2.invert(S[i], inv[i], cv2.DECOMP_CHOLESKY)
    return inv, logdet


def mahalanobis2(S: NDArray[np.float64], v: NDArray[np.float64]) -> float:
    """Squared Mahalanobis length ``v^T S^-1 v`` of ``v`` (k,) under a symmetric positive-definite
    ``S`` (k, k; for k <= 3 only its upper triangle is read, in plain floats by the adjugate);
    ``inf`` if ``S`` is not positive definite (Sylvester's criterion for k <= 3, the determinant
    otherwise) or the result is not finite."""
    k = len(v)
    q = math.inf
    if k == 1:
        a = float(S[0, 0])
        x = float(v[0])
        if a > 0.0:
            q = x * x / a
    elif k == 2:
        (a, b), (_, d) = S.tolist()
        x, y = v.tolist()
        det = a * d - b * b
        if a > 0.0 and det > 0.0:
            q = (d * x * x - 2.0 * b * x * y + a * y * y) / det
    elif k == 3:
        (a, b, c), (_, d, e), (_, _, f) = S.tolist()
        x, y, z = v.tolist()
        c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d  # cofactors (symmetric)
        c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
        det = a * c00 + b * c01 + c * c02
        if a > 0.0 and c22 > 0.0 and det > 0.0:
            q = (
                c00 * x * x + c11 * y * y + c22 * z * z + 2.0 * (c01 * x * y + c02 * x * z + c12 * y * z)
            ) / det
    else:
        S = np.ascontiguousarray(S, dtype=np.float64)
        det = cv2.determinant(S)
        if det > 0.0 and math.isfinite(det):
            ok, sol = cv2.solve(
                S, np.ascontiguousarray(v, dtype=np.float64).reshape(-1, 1), flags=cv2.DECOMP_CHOLESKY
            )
            q = float(v @ sol[:, 0]) if ok else math.inf
    return q if math.isfinite(q) else math.inf


__all__ = [
    "mahalanobis2",
    "spd_inverse",
    "svd",
]
