"""Strict type checks of calibration fields (JSON values or their numpy equivalents).

Each check names the field (e.g. ``"rig.camera_position"``) and raises TypeError for a value of the
wrong kind (a string, null, a bool, a float where an int belongs) and ValueError for a value of the
right kind but out of range (wrong shape, NaN/inf, a non-positive size).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray


def describe(value: Any) -> str:
    """A JSON-flavoured description of ``value`` for error messages."""
    if value is None:
        return "null"
    if isinstance(value, bool | np.bool_):
        return f"a boolean ({bool(value)!r})"
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return f"a string ({text!r})"
    if isinstance(value, numbers.Integral):
        return f"an integer ({int(value)})"
    if isinstance(value, numbers.Real):
        return f"a number ({float(value)!r})"
    if isinstance(value, Mapping):
        return "an object"
    if isinstance(value, list | tuple):
        return f"an array of length {len(value)}"
    if isinstance(value, np.ndarray):
        return f"an array of {value.dtype} with shape {value.shape}"
    return f"a {type(value).__name__}"


def is_int(value: Any) -> bool:
    """An integer, not a bool (``True`` is an int in Python, not in a calibration file)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_)


def is_real(value: Any) -> bool:
    """A real number (int or float), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def check_int(value: Any, field: str, minimum: int | None = None) -> int:
    """``value`` as an int; it must be an integer (not a float such as 512.0 or 512.7, not a bool)."""
    if not is_int(value):
        raise TypeError(f"{field} must be an integer, got {describe(value)}")
    out = int(value)
    if minimum is not None and out < minimum:
        raise ValueError(f"{field} must be >= {minimum}, got {out}")
    return out


def check_real(value: Any, field: str, unit: str = "") -> float:
    """``value`` as a finite float; it must be a number (int or float), not a bool, null or string."""
    suffix = f" ({unit})" if unit else ""
    if not is_real(value):
        raise TypeError(f"{field} must be a finite number{suffix}, got {describe(value)}")
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(f"{field} must be finite{suffix}, got {out!r}")
    return out


def _first_non_number(value: Any) -> tuple[bool, Any]:
    """(True, offending element) for the first element of a nested list that is not a number."""
    if isinstance(value, list | tuple):
        for v in value:
            bad, what = _first_non_number(v)
            if bad:
                return True, what
        return False, None
    if isinstance(value, np.ndarray):
        return (value.dtype.kind not in "iuf", value)
    return (not is_real(value), value)


def _shape_text(shape: tuple[int | None, ...]) -> str:
    dims = ["N" if n is None else str(n) for n in shape]
    return "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"


def check_real_array(
    value: Any, shape: tuple[int | None, ...], field: str, finite: bool = True
) -> NDArray[np.float64]:
    """``value`` (nested lists / tuples of numbers, or a numeric ndarray) as a float64 array of
    ``shape`` (``None`` = any length); every element a number (no bool, null or string) and, with
    ``finite``, finite."""
    want = _shape_text(shape)
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "iuf":
            raise TypeError(f"{field} must be an array of numbers with shape {want}, got {describe(value)}")
    elif isinstance(value, list | tuple):
        bad, what = _first_non_number(value)
        if bad:
            raise TypeError(f"{field} must contain only numbers (shape {want}), found {describe(what)}")
    else:
        raise TypeError(f"{field} must be an array of numbers with shape {want}, got {describe(value)}")
    try:
        a = np.array(value, dtype=np.float64)
    except ValueError:
        raise ValueError(f"{field} must be an array with shape {want}, got a ragged nested array") from None
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape, strict=True)):
        raise ValueError(f"{field} must have shape {want}, got {a.shape}")
    if finite and not np.isfinite(a).all():
        raise ValueError(f"{field} must be finite, got NaN or inf")
    return a


def check_keys(
    d: Any, field: str, required: Iterable[str], optional: Iterable[str] = ()
) -> Mapping[str, Any]:
    """``d`` as a mapping with all ``required`` keys and no keys other than ``required``/``optional``."""
    if not isinstance(d, Mapping):
        raise TypeError(f"{field} must be an object, got {describe(d)}")
    req = tuple(required)
    missing = [k for k in req if k not in d]
    if missing:
        raise ValueError(f"{field}: missing key(s) {missing}")
    known = set(req) | set(optional)
    unknown = sorted(str(k) for k in d if k not in known)
    if unknown:
        raise ValueError(f"{field}: unknown key(s) {unknown}; known: {sorted(known)}")
    return d
