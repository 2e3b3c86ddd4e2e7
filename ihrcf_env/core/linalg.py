"""Dense linear algebra on tiny matrices (2x2 to 4x3) for per-frame estimator code.

``numpy.linalg`` spends 3-7 us per call on a 3x3 matrix, almost all of it in Python-level checks
and dispatch; OpenCV's compiled routines do the same work in 0.3-1.5 us. The estimators call these
a few dozen times per camera frame, so they use the wrappers below. The results equal numpy's to
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
    ``S`` (k, k); ``inf`` if its determinant is not positive and finite or the result is not finite."""
    S = np.ascontiguousarray(S, dtype=np.float64)
    det = cv2.determinant(S)
    if not det > 0.0 or not math.isfinite(det):
        return math.inf
    ok, x = cv2.solve(S, np.ascontiguousarray(v, dtype=np.float64).reshape(-1, 1), flags=cv2.DECOMP_CHOLESKY)
    d2 = float(v @ x[:, 0])
    return d2 if ok and math.isfinite(d2) else math.inf
