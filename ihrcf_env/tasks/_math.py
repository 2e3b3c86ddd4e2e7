"""Array helpers of the task rules: the namespace of the inputs and exact small reductions.

Each helper takes arrays of one namespace (numpy through ``array-api-compat``, or ``jax.numpy``)
and works elementwise over any leading axes; none branches in Python on array values.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from array_api_compat import array_namespace

__all__ = ["dot3", "hypot", "namespace", "norm3"]

_NUMPY = array_namespace(np.zeros(1))
_NUMPY_TYPES = (np.ndarray,)
#: Below this (2**-1024) Python's hypot takes its unscaled path.
_TINY = 2.0**-1024
#: Veltkamp's splitting constant for float64, 2**27 + 1.
_SPLIT = 134217729.0


def namespace(*arrays: Any) -> Any:
    """The array namespace of ``arrays`` (``array_api_compat.array_namespace``; Python scalars and
    None are skipped); TypeError if none of them is an array or they mix array libraries."""
    found = [a for a in arrays if a is not None and not isinstance(a, bool | int | float)]
    if found and all(type(a) in _NUMPY_TYPES or isinstance(a, np.generic) for a in found):
        return _NUMPY  # the common case, without the look-up's cost
    if not found:
        raise TypeError("the task rules need at least one array argument (numpy or jax.numpy)")
    return array_namespace(*found)


def dot3(a: Any, b: Any) -> Any:
    """``sum(a[..., i] * b[..., i])`` over the last axis of length 3, added left to right (as
    numpy's ``a @ b`` of two 3-vectors does)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def norm3(xp: Any, a: Any) -> Any:
    """Euclidean norm over the last axis of length 3 (``sqrt(dot3(a, a))``)."""
    return xp.sqrt(dot3(a, a))


def _split(x: Any) -> tuple[Any, Any]:
    t = x * _SPLIT
    hi = t - (t - x)
    return hi, x - hi


def _two_product(x: Any, y: Any) -> tuple[Any, Any]:
    """``x * y`` as an unevaluated sum ``hi + lo`` (Dekker's product, no fused multiply-add)."""
    xh, xl = _split(x)
    yh, yl = _split(y)
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


def _fast_two_sum(a: Any, b: Any) -> tuple[Any, Any]:
    """``a + b`` as ``hi + lo`` for ``|a| >= |b|``."""
    x = a + b
    return x, b - (x - a)


def hypot(xp: Any, x: Any, y: Any) -> Any:
    """``sqrt(x**2 + y**2)`` elementwise, within one unit in the last place of the exact value, as
    Python's ``math.hypot(x, y)`` is: CPython 3.11's algorithm (scaled, compensated, with one
    differential correction; below ``2**-1024`` the plain sum of squares over the larger value),
    equal to that version's bit for bit; later versions may differ from it in the last bit for
    subnormal inputs. inf if either is infinite, NaN if either is NaN (and neither infinite), 0 if
    both are 0."""
    if xp is _NUMPY and np.ndim(x) == 0 and np.ndim(y) == 0:  # one pair: the same figure, faster
        return np.float64(math.hypot(float(x), float(y)))
    ax, ay = xp.abs(x), xp.abs(y)
    big = xp.maximum(ax, ay)
    special = ~xp.isfinite(big) | (big == 0.0)
    tiny = big < _TINY
    big = xp.where(special, 0.5, big)
    _, exponent = xp.frexp(big)
    scale = xp.ldexp(xp.ones_like(big), -xp.where(tiny, 0, exponent))  # a power of two: exact
    unused = special | tiny
    sx, sy = xp.where(unused, 0.5, ax * scale), xp.where(unused, 0.5, ay * scale)
    hx, lx = _two_product(sx, sx)
    csum, low = _fast_two_sum(1.0, hx)
    hy, ly = _two_product(sy, sy)
    csum, low2 = _fast_two_sum(csum, hy)
    frac1, frac2 = 0.0 + lx + ly, 0.0 + low + low2
    h = xp.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _two_product(-h, h)
    csum, low = _fast_two_sum(csum, hi)
    h = h + (csum - 1.0 + ((frac1 + lo) + (frac2 + low))) / (2.0 * h)
    qx, qy = xp.where(special, 0.5, ax) / big, xp.where(special, 0.5, ay) / big
    out = xp.where(tiny, big * xp.sqrt(qx * qx + qy * qy), h / scale)
    out = xp.where(special, 0.0, out)
    out = xp.where(xp.isnan(x) | xp.isnan(y), xp.nan, out)
    return xp.where(xp.isinf(x) | xp.isinf(y), xp.inf, out)
