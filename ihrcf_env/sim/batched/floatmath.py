"""Elementwise numpy versions of the scalar maths the simulator's per-drone code uses, rounded the
same way, so that a batched row equals its scalar counterpart bit for bit.

* :func:`hypot2`: Python's ``math.hypot(x, y)`` (CPython's own correctly-rounded-in-practice
  algorithm, which differs from C's ``hypot`` and so from ``numpy.hypot`` in the last bit);
* :func:`remainder`: ``math.remainder(x, y)`` (IEEE 754 remainder, ties to the even quotient);
* :func:`atan2`: ``math.atan2(y, x)`` (the C library's; numpy's own SIMD ``arctan2``, used on CPUs
  with AVX-512, differs from it in the last bit for some inputs);
* :func:`matrices_from_quaternions`: PyBullet's ``getMatrixFromQuaternion`` (Bullet's
  ``btMatrix3x3::setRotation`` formula, double precision).

All functions work on arrays of any shape (float64) and never branch per element: every result of
a row depends on that row's inputs only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Dekker's splitting constant for IEEE doubles (2^27 + 1).
_SPLIT = 134217729.0


def _two_square(x: Array) -> tuple[Array, Array]:
    """``x * x`` and its exact rounding error (Dekker's product, no FMA needed)."""
    hi = x * x
    t = _SPLIT * x
    xh = t - (t - x)
    xl = x - xh
    lo = ((xh * xh - hi) + 2.0 * xh * xl) + xl * xl
    return hi, lo


def hypot2(x: Array, y: Array) -> Array:
    """``math.hypot(x, y)`` elementwise, the same bits (finite inputs).

    CPython (3.10+) scales both values by a power of two, accumulates their squares in
    double-double arithmetic, takes a square root and applies one differential correction."""
    x = np.abs(np.asarray(x, dtype=np.float64))
    y = np.abs(np.asarray(y, dtype=np.float64))
    big = np.maximum(x, y)
    _, e = np.frexp(big)
    scale = np.ldexp(1.0, -e)
    xs, ys = x * scale, y * scale
    csum = np.ones_like(big)
    frac1 = np.zeros_like(big)
    frac2 = np.zeros_like(big)
    for v in (xs, ys):
        hi, lo = _two_square(v)
        s = csum + hi  # fast two-sum: csum >= 1 > hi
        frac2 = frac2 + ((csum - s) + hi)
        csum = s
        frac1 = frac1 + lo
    h = np.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _two_square(h)
    hi, lo = -hi, -lo
    s = csum + hi
    frac2 = frac2 + ((csum - s) + hi)
    csum = s
    frac1 = frac1 + lo
    corr = csum - 1.0 + (frac1 + frac2)
    with np.errstate(invalid="ignore", divide="ignore"):  # 0 / 0 where both are zero
        h = h + corr / (2.0 * h)
        out = h / scale
    # math.hypot returns max when the other value is zero (or both are zero)
    return np.where((x == 0.0) | (y == 0.0), big, out)


def hypot_over(x: Array, y: Array, limit: Array | float) -> tuple[NDArray[np.bool_], Array]:
    """``(math.hypot(x, y) > limit, h)`` elementwise, ``h`` equal to ``math.hypot(x, y)`` wherever
    the comparison is true. The exact :func:`hypot2` is computed only when some element is within
    1e-9 (relative) of its limit or above it: elsewhere ``sqrt(x^2 + y^2)`` decides the comparison
    just as well, so no element's result depends on the others."""
    approx = np.sqrt(x * x + y * y)
    lim = np.asarray(limit, dtype=np.float64)
    near = ~(approx < lim * (1.0 - 1e-9)) | (lim < 1e-100)
    if not near.any():
        return near, approx
    h = hypot2(x, y)
    return h > lim, h


_ATAN2 = np.frompyfunc(math.atan2, 2, 1)


def atan2(y: Array, x: Array) -> Array:
    """``math.atan2(y, x)`` elementwise (float64, the C library's result on every CPU)."""
    return np.asarray(
        _ATAN2(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64)), dtype=np.float64
    )


def remainder(x: Array, y: float) -> Array:
    """``math.remainder(x, y)`` elementwise for a positive finite ``y``: ``x - n y`` with ``n`` the
    integer nearest ``x / y`` (ties to even), computed exactly."""
    x = np.asarray(x, dtype=np.float64)
    r2 = np.fmod(x, 2.0 * y)  # exact; the quotient's parity is kept
    a = np.abs(r2)
    half = 0.5 * y
    b = a - y  # exact for a in [y/2, 2y] (Sterbenz)
    r = np.where(a <= half, a, np.where(a < y, b, np.where(b < half, b, b - y)))
    return np.where(np.signbit(r2), -r, r)


def matrices_from_quaternions(q: Array) -> Array:
    """Rotation matrices ``(..., 3, 3)`` of quaternions ``(..., 4)`` (x, y, z, w), with Bullet's
    formula and rounding (a non-unit quaternion is normalised through ``s = 2 / |q|^2``)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz = w * xs, w * ys, w * zs
    xx, xy, xz = x * xs, x * ys, x * zs
    yy, yz, zz = y * ys, y * zs, z * zs
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = 1.0 - (yy + zz)
    out[..., 0, 1] = xy - wz
    out[..., 0, 2] = xz + wy
    out[..., 1, 0] = xy + wz
    out[..., 1, 1] = 1.0 - (xx + zz)
    out[..., 1, 2] = yz - wx
    out[..., 2, 0] = xz - wy
    out[..., 2, 1] = yz + wx
    out[..., 2, 2] = 1.0 - (xx + yy)
    return out


def yaw_quaternions(yaw: Array) -> Array:
    """Quaternions ``(N, 4)`` (x, y, z, w) of headings ``yaw`` (rad) about world z, as PyBullet's
    ``getQuaternionFromEuler((0, 0, yaw))`` builds them."""
    yaw = np.asarray(yaw, dtype=np.float64)
    half = 0.5 * yaw
    s, c = np.sin(half), np.cos(half)
    # Bullet's setEulerZYX with roll = pitch = 0 (sin 0 = 0, cos 0 = 1), then normalised
    x = 0.0 * c - 0.0 * s
    y = 0.0 * c + 0.0 * s
    z = s - 0.0 * c
    w = c + 0.0 * s
    n = np.sqrt(x * x + y * y + z * z + w * w)
    return np.stack([x / n, y / n, z / n, w / n], axis=-1)


def quaternions_from_matrices(m: Array) -> Array:
    """Quaternions ``(N, 4)`` (x, y, z, w) of rotation matrices ``(N, 3, 3)``, with Bullet's
    ``btMatrix3x3::getRotation`` (Shepperd's method: the branch, hence the sign, chosen from the
    trace and the largest diagonal element), the way PyBullet reports a body's orientation."""
    d0, d1, d2 = m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]
    trace = d0 + d1 + d2
    out = np.empty((m.shape[0], 4))
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.sqrt(trace + 1.0)
        h = 0.5 / s
        out[:, 0] = (m[:, 2, 1] - m[:, 1, 2]) * h
        out[:, 1] = (m[:, 0, 2] - m[:, 2, 0]) * h
        out[:, 2] = (m[:, 1, 0] - m[:, 0, 1]) * h
        out[:, 3] = s * 0.5
    other = np.flatnonzero(trace <= 0.0)
    if other.size:  # rotations beyond 120 degrees: the largest diagonal element's branch
        mo = m[other]
        e0, e1, e2 = d0[other], d1[other], d2[other]
        i_big = np.where(e0 < e1, np.where(e1 < e2, 2, 1), np.where(e0 < e2, 2, 0))
        for i in range(3):
            rows = np.flatnonzero(i_big == i)
            if not rows.size:
                continue
            j, k = (i + 1) % 3, (i + 2) % 3
            mi = mo[rows]
            si = np.sqrt(mi[:, i, i] - mi[:, j, j] - mi[:, k, k] + 1.0)
            hi = 0.5 / si
            alt = np.empty((rows.size, 4))
            alt[:, i] = si * 0.5
            alt[:, 3] = (mi[:, k, j] - mi[:, j, k]) * hi
            alt[:, j] = (mi[:, j, i] + mi[:, i, j]) * hi
            alt[:, k] = (mi[:, k, i] + mi[:, i, k]) * hi
            out[other[rows]] = alt
    return out


__all__ = [
    "Array",
    "atan2",
    "hypot2",
    "hypot_over",
    "matrices_from_quaternions",
    "quaternions_from_matrices",
    "remainder",
    "yaw_quaternions",
]
