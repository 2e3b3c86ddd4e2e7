"""Plane, homography and rigid-fit geometry for the IHRCF estimator (numpy and OpenCV, no simulator).

The public functions check their inputs; the ``_``-prefixed kernels under them do not, for callers
that already did (the per-frame estimators).

Frames are whatever the caller passes in; :mod:`ihrcf_env.core.estimators` uses the camera frame
(OpenCV: x right, y down, z along the optical axis, metres) for 3-D points and OpenCV pixel
coordinates (pixel centres at integers) for image points.
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import as_array
from ihrcf_env.core.linalg import svd

#: Relative singular-value threshold below which a linear system is treated as rank deficient.
_RANK_TOL = 1e-10


def _points(x: ArrayLike, dim: int, name: str, min_n: int) -> NDArray[np.float64]:
    """Return ``x`` as a finite (N, dim) float64 array with N >= min_n; ValueError otherwise."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != dim:
        raise ValueError(f"{name} must have shape (N, {dim}), got {a.shape}")
    if a.shape[0] < min_n:
        raise ValueError(f"{name} needs at least {min_n} points, got shape {a.shape}")
    return as_array(a, a.shape, name)


def _normalising_transform(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hartley normalisation: 3x3 similarity moving the centroid to 0 and the mean distance to sqrt(2)."""
    c = p.mean(axis=0)
    mean_dist = float(np.mean(np.linalg.norm(p - c, axis=1)))
    if mean_dist <= 0.0:
        raise ValueError("points are all coincident")
    s = np.sqrt(2.0) / mean_dist
    return np.array([[s, 0.0, -s * c[0]], [0.0, s, -s * c[1]], [0.0, 0.0, 1.0]])


Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _square_to_quad(q: list[list[float]]) -> Matrix3:
    """The homography taking the unit square's corners (0, 0), (1, 0), (1, 1), (0, 1) to the four
    points ``q`` (Heckbert's closed form); ValueError when three of them are collinear."""
    (x0, y0), (x1, y1), (x2, y2), (x3, y3) = q
    sx, sy = x0 - x1 + x2 - x3, y0 - y1 + y2 - y3
    dx1, dx2, dy1, dy2 = x1 - x2, x3 - x2, y1 - y2, y3 - y2
    den = dx1 * dy2 - dx2 * dy1
    if den == 0.0 or not math.isfinite(den):
        raise ValueError("degenerate point configuration: homography is not unique")
    g = (sx * dy2 - dx2 * sy) / den
    h = (dx1 * sy - sx * dy1) / den
    m = (
        (x1 - x0 + g * x1, x3 - x0 + h * x3, x0),
        (y1 - y0 + g * y1, y3 - y0 + h * y3, y0),
        (g, h, 1.0),
    )
    terms = _det_terms(m)
    if not abs(terms[0] - terms[1] + terms[2]) > _RANK_TOL * sum(map(abs, terms)):
        raise ValueError("degenerate point configuration: homography is not unique")  # singular map
    return m


def _det_terms(m: Matrix3 | list[list[float]]) -> tuple[float, float, float]:
    """The three terms of a 3x3 determinant's expansion along its first row (det = t0 - t1 + t2)."""
    (a, b, c), (d, e, f), (g, h, i) = m
    return a * (e * i - f * h), b * (d * i - f * g), c * (d * h - e * g)


def _adjugate(m: Matrix3) -> Matrix3:
    """Adjugate of a 3x3 matrix (its inverse times its determinant: the same homography)."""
    (a, b, c), (d, e, f), (g, h, i) = m
    return (
        (e * i - f * h, c * h - b * i, b * f - c * e),
        (f * g - d * i, a * i - c * g, c * d - a * f),
        (d * h - e * g, b * g - a * h, a * e - b * d),
    )


def _product(m: Matrix3, n: Matrix3) -> Matrix3:
    return tuple(  # type: ignore[return-value]
        tuple(m[r][0] * n[0][k] + m[r][1] * n[1][k] + m[r][2] * n[2][k] for k in range(3)) for r in range(3)
    )


def homography_from_points(src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """Homography ``H`` (3, 3) with ``dst ~ H [src, 1]``; ``H[2, 2] = 1``.

    ``src`` and ``dst`` are (N, 2) corresponding points, N >= 4, row i of ``src`` mapping to row i
    of ``dst`` (eq. 13-16 of the paper). With N == 4 the fit is exact and computed in closed form
    (about the centroids, through the unit square: ``H = Q_dst Q_src^-1``, Heckbert 1989), with
    N > 4 by normalised DLT.
    Raises ValueError for degenerate configurations (three of four points collinear, or a
    rank-deficient DLT system) or when ``H[2, 2]`` is 0 and the matrix cannot be normalised. Note
    that these tests only catch exact degeneracy; use :func:`quad_is_degenerate` for a
    tolerance-based check.
    """
    src = _points(src, 2, "src", 4)
    dst = _points(dst, 2, "dst", 4)
    if src.shape != dst.shape:
        raise ValueError(f"src and dst must have the same shape, got {src.shape} and {dst.shape}")
    return _homography(src, dst)


def _homography(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`homography_from_points` of checked, finite, same-shape (N >= 4, 2) float64 points."""
    if src.shape[0] == 4:
        # about the centroids (the closed form loses precision far from the origin), then shifted back
        cs, cd = src.sum(axis=0) / 4.0, dst.sum(axis=0) / 4.0
        Hc = _product(_square_to_quad((dst - cd).tolist()), _adjugate(_square_to_quad((src - cs).tolist())))
        shift_d = ((1.0, 0.0, float(cd[0])), (0.0, 1.0, float(cd[1])), (0.0, 0.0, 1.0))
        shift_s = ((1.0, 0.0, -float(cs[0])), (0.0, 1.0, -float(cs[1])), (0.0, 0.0, 1.0))
        H = np.array(_product(_product(shift_d, Hc), shift_s))
        if not np.isfinite(H).all():
            raise ValueError("degenerate point configuration: homography is not unique")
    else:
        H = _dlt(src, dst)
    if abs(H[2, 2]) <= _RANK_TOL * np.abs(H).max():
        raise ValueError("homography has H[2, 2] = 0 and cannot be normalised")
    return H / H[2, 2]


def _dlt(src: NDArray[np.float64], dst: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised DLT homography (3, 3) of N >= 4 point pairs, up to scale."""
    T_s = _normalising_transform(src)
    T_d = _normalising_transform(dst)
    n = src.shape[0]
    s = np.column_stack([src, np.ones(n)]) @ T_s.T
    d = np.column_stack([dst, np.ones(n)]) @ T_d.T
    A = np.zeros((2 * n, 9))
    A[0::2, 0:3] = s
    A[0::2, 6:9] = -d[:, 0:1] * s
    A[1::2, 3:6] = s
    A[1::2, 6:9] = -d[:, 1:2] * s
    _, sv, vt = np.linalg.svd(A)
    # A has 9 columns; a unique solution needs rank 8 (singular value #8 clearly non-zero).
    if sv[7] <= _RANK_TOL * sv[0]:
        raise ValueError("degenerate point configuration: homography is not unique")
    Hn = vt[-1].reshape(3, 3)
    H: NDArray[np.float64] = np.linalg.inv(T_d) @ Hn @ T_s
    return H


def apply_homography(H: ArrayLike, pts: ArrayLike) -> NDArray[np.float64]:
    """Map (N, 2) points through ``H`` (3, 3): ``[x', y'] = (H [x, y, 1])[:2] / (H [x, y, 1])[2]``.

    Points mapped to infinity (zero homogeneous coordinate) come out as inf/NaN.
    """
    return _apply_homography(as_array(H, (3, 3), "H"), _points(pts, 2, "pts", 1))


def _apply_homography(H: NDArray[np.float64], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`apply_homography` of a checked (3, 3) ``H`` and checked (N, 2) float64 points."""
    h = pts @ H[:, :2].T + H[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        return h[:, :2] / h[:, 2:3]


def collinear(pts: ArrayLike, tol: float = 1e-3) -> bool:
    """True if any three of the (N, 2) points (N >= 3) are collinear within ``tol`` (scale-invariant).

    For each triple the measure is ``2 * area / longest_side**2`` (the triangle's height over its
    longest side, divided by that side): 0 for collinear or coincident points, sqrt(3)/2 ~ 0.87 for
    an equilateral triangle. The triple is collinear when this is <= ``tol``.
    """
    pts = _points(pts, 2, "pts", 3)
    if not (np.isfinite(tol) and tol >= 0):
        raise ValueError(f"tol must be a non-negative number, got {tol!r}")
    return _collinear(pts.tolist(), tol)


def _collinear(p: list[list[float]], tol: float) -> bool:
    """:func:`collinear` of finite points given as plain floats (cheaper than numpy calls for a
    handful of triples) and a checked ``tol``."""
    for i, j, k in itertools.combinations(range(len(p)), 3):
        (ax, ay), (bx, by), (cx, cy) = p[i], p[j], p[k]
        ux, uy, vx, vy, wx, wy = bx - ax, by - ay, cx - ax, cy - ay, cx - bx, cy - by
        area2 = abs(ux * vy - uy * vx)
        longest2 = max(ux * ux + uy * uy, vx * vx + vy * vy, wx * wx + wy * wy)
        if longest2 == 0.0 or area2 <= tol * longest2:
            return True
    return False


def quad_is_degenerate(pts: ArrayLike, rel_tol: float = 1e-3) -> bool:
    """True if the quadrilateral (4, 2) has three (nearly) collinear corners; see :func:`collinear`."""
    return collinear(as_array(pts, (4, 2), "pts"), rel_tol)


def fit_plane(points: ArrayLike) -> tuple[NDArray[np.float64], float]:
    """Plane ``n . x = d`` through (N, 3) points: unit normal ``n`` (3,) and offset ``d`` (m).

    N >= 4: total least squares (SVD of the centred points: the normal is the direction of least
    spread). N == 3: the paper's eq. (20), ``n = (p1 - p2) x (p2 - p3)``, normalised.

    Sign convention: the normal has a non-negative z component (in the camera frame, it points
    along the optical axis, away from the camera, i.e. *into* the deck); for a vertical plane
    (n_z == 0) the first non-zero component is made positive. With this convention ``d`` is the
    plane's depth along +z scaled by n_z, positive for a plane in front of the camera.

    Raises ValueError for fewer than 3 points or (nearly) collinear / coincident points.
    """
    return _fit_plane(_points(points, 3, "points", 3))


def _fit_plane(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """:func:`fit_plane` of checked, finite (N >= 3, 3) float64 points."""
    centroid = points.sum(axis=0) / points.shape[0]
    centred = points - centroid
    scale = math.sqrt(float(np.max(np.einsum("ij,ij->i", centred, centred))))
    if scale == 0.0:
        raise ValueError("points are all coincident: plane undefined")
    if points.shape[0] == 3:
        p1, p2, p3 = points
        n = np.cross(p1 - p2, p2 - p3)
        norm = math.sqrt(float(n @ n))
        if norm <= 1e-9 * scale * scale:
            raise ValueError("points are collinear: plane undefined")
    else:
        _, sv, vt = svd(centred / scale)
        if sv[1] <= 1e-9 * sv[0]:
            raise ValueError("points are collinear: plane undefined")
        n = vt[2]
        norm = math.sqrt(float(n @ n))
    n = n / norm
    if n[2] < 0 or (n[2] == 0 and n[np.flatnonzero(n)[0]] < 0):
        n = -n
    return n, float(n @ centroid)


def plane_z(normal: ArrayLike, d: float, xy: ArrayLike) -> NDArray[np.float64]:
    """Z (N,) of the plane ``n . x = d`` above (N, 2) points ``xy``: eq. (22), ``(d - n1 x - n2 y) / n3``.

    Raises ValueError if the plane is (nearly) parallel to z (|n3| < 1e-9 |n|).
    """
    n = as_array(normal, (3,), "normal")
    xy = _points(xy, 2, "xy", 1)
    if not np.isfinite(d):
        raise ValueError(f"d must be finite, got {d!r}")
    return _plane_z(n, float(d), xy)


def _plane_z(n: NDArray[np.float64], d: float, xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`plane_z` of a checked normal (3,), finite ``d`` and checked (N, 2) float64 points."""
    if abs(n[2]) < 1e-9 * math.sqrt(float(n @ n)) or not np.any(n):
        raise ValueError("plane is parallel to the z axis: z is undefined")
    return (d - n[0] * xy[:, 0] - n[1] * xy[:, 1]) / n[2]


@functools.lru_cache(maxsize=16)
def _collinear_3d(centred: bytes) -> bool:
    """True if the centred (N, 3) points (float64 bytes) are collinear or coincident (second singular
    value <= 1e-9 of the first). Cached: the model points of a rigid fit rarely change."""
    sp = np.linalg.svd(np.frombuffer(centred, dtype=np.float64).reshape(-1, 3), compute_uv=False)
    return bool(sp[1] <= 1e-9 * max(sp[0], 1e-300))


def rigid_fit(P: ArrayLike, Q: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Least-squares rigid transform ``Q ~ R P + t`` (Kabsch / Umeyama without scale).

    ``P`` and ``Q`` are (N, 3) corresponding points (N >= 3, ``P`` not collinear). Returns
    ``R`` (3, 3) with det +1 (a reflection is never returned: the SVD is corrected with
    ``diag(1, 1, sign(det))``, which also handles coplanar points), ``t`` (3,) and the RMS of the
    residuals ``|R p_i + t - q_i|`` in the units of the points (m).
    """
    P = _points(P, 3, "P", 3)
    Q = _points(Q, 3, "Q", 3)
    if P.shape != Q.shape:
        raise ValueError(f"P and Q must have the same shape, got {P.shape} and {Q.shape}")
    return _rigid_fit(P, Q)


def _rigid_fit(
    P: NDArray[np.float64], Q: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """:func:`rigid_fit` of checked, finite, same-shape (N >= 3, 3) float64 point sets."""
    cp, cq = P.sum(axis=0) / len(P), Q.sum(axis=0) / len(Q)
    Pc, Qc = P - cp, Q - cq
    if _collinear_3d(Pc.tobytes()):
        raise ValueError("P is collinear or coincident: rotation undefined")
    U, _, Vt = svd(Qc.T @ Pc)  # of the cross-covariance, maps P directions to Q directions
    R = U @ Vt
    t0, t1, t2 = _det_terms(R.tolist())
    if t0 - t1 + t2 < 0:  # a reflection
        U[:, 2] = -U[:, 2]
        R = U @ Vt
    t = cq - R @ cp
    res = P @ R.T + t - Q
    rms = math.sqrt(float(np.einsum("ij,ij->", res, res)) / len(P))
    return R, t, rms


__all__ = [
    "Matrix3",
    "apply_homography",
    "collinear",
    "fit_plane",
    "homography_from_points",
    "plane_z",
    "quad_is_degenerate",
    "rigid_fit",
]
