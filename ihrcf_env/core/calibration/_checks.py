"""Checks of calibration fields that :mod:`ihrcf_env.core.checks` lacks: shaped arrays of numbers
(:func:`check_real_array`) and JSON objects with known keys (:func:`check_keys`).

Name first, as in :mod:`ihrcf_env.core.checks` (whose scalar checks they use): TypeError for a
value of the wrong kind (a string, null, a bool where a number belongs), ValueError for a value of
the right kind out of range (wrong shape, NaN/inf, beyond the bounds, an integer too large for a
float), both naming the field (e.g. ``"rig.camera_position"``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_real, describe, is_real

#: Deepest nesting of an array field: a calibration array has at most this many dimensions.
MAX_ARRAY_DEPTH = 8


def _shape_text(shape: tuple[int | None, ...]) -> str:
    dims = ["N" if n is None else str(n) for n in shape]
    return "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"


def _index_text(index: tuple[int, ...]) -> str:
    return "[" + ", ".join(str(i) for i in index) + "]"


def _leaves(name: str, value: list[Any] | tuple[Any, ...], want: str) -> list[tuple[tuple[int, ...], Any]]:
    """The non-sequence elements of nested lists / tuples with their indices (breadth first, no
    recursion); ValueError beyond :data:`MAX_ARRAY_DEPTH` levels."""
    leaves: list[tuple[tuple[int, ...], Any]] = []
    level: list[tuple[tuple[int, ...], Any]] = [((), value)]
    depth = 0
    while level:
        if depth > MAX_ARRAY_DEPTH:
            raise ValueError(f"{name} must be an array with shape {want}, got one nested too deeply")
        nxt: list[tuple[tuple[int, ...], Any]] = []
        for index, v in level:
            if isinstance(v, list | tuple):
                nxt.extend(((*index, i), x) for i, x in enumerate(v))
            else:
                leaves.append((index, v))
        level = nxt
        depth += 1
    return leaves


def check_real_array(
    name: str,
    value: Any,
    shape: tuple[int | None, ...],
    unit: str = "",
    *,
    low: float = -math.inf,
    high: float = math.inf,
) -> NDArray[np.float64]:
    """``value`` (nested lists / tuples of numbers, or a numeric ndarray) as a float64 array of
    ``shape`` (``None`` = any length); every element a number (no bool, null or string), finite and
    in [low, high] (an element out of range is named by its index, e.g. ``K[0, 0]``)."""
    want = _shape_text(shape)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise TypeError(f"{name} must be an array of numbers with shape {want}, got {describe(value)}")
        a = np.array(value, dtype=np.float64)
    elif isinstance(value, list | tuple):
        for index, v in _leaves(name, value, want):
            if not is_real(v):
                raise TypeError(f"{name} must contain only numbers (shape {want}), found {describe(v)}")
            if not -1e300 < v < 1e300:  # an int too large for a float, or a huge float: named here
                check_real(f"{name}{_index_text(index)}", v, unit, low=low, high=high)
        try:
            a = np.array(value, dtype=np.float64)
        except ValueError:
            raise ValueError(
                f"{name} must be an array with shape {want}, got a ragged nested array"
            ) from None
    else:
        raise TypeError(f"{name} must be an array of numbers with shape {want}, got {describe(value)}")
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape, strict=True)):
        raise ValueError(f"{name} must have shape {want}, got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    bad = np.argwhere((a < low) | (a > high))
    if bad.size:
        index = tuple(int(i) for i in bad[0])
        check_real(f"{name}{_index_text(index)}", float(a[index]), unit, low=low, high=high)
    return a


def check_keys(
    name: str, value: Any, required: Iterable[str], optional: Iterable[str] = ()
) -> Mapping[str, Any]:
    """``value`` as a mapping with all ``required`` keys and no keys other than ``required`` /
    ``optional``."""
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be an object, got {describe(value)}")
    req = tuple(required)
    missing = [k for k in req if k not in value]
    if missing:
        raise ValueError(f"{name}: missing key(s) {missing}")
    known = set(req) | set(optional)
    unknown = sorted(str(k) for k in value if k not in known)
    if unknown:
        raise ValueError(f"{name}: unknown key(s) {unknown}; known: {sorted(known)}")
    return value
