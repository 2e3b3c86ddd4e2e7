"""The one set of input checks: every option, parameter and file field is validated with these.

Every function takes the **name** of the thing checked first (as the user wrote it: an option
``"tof_noise['sigma_floor']"``, a file field ``"rig.camera_position"``), then the value, and raises

* ``TypeError`` for a value of the wrong kind (a string, None, a bool where a number belongs, a float
  where an integer belongs), and
* ``ValueError`` for a value of the right kind out of its range: NaN/inf, below ``low`` or above
  ``high``. Physical upper bounds are passed by the caller, so an absurd magnitude (``1e300`` m) is
  refused where it is given, not when it overflows later.

Pure Python + numpy; no simulator.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


def describe(value: Any) -> str:
    """A short description of ``value`` for error messages (kind and value, long text cut)."""
    if value is None:
        return "None"
    if isinstance(value, bool | np.bool_):
        return f"a bool ({bool(value)!r})"
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return f"a str ({text!r})"
    if isinstance(value, numbers.Integral):
        text = str(int(value))
        return f"an int ({text if len(text) <= 24 else text[:10] + '...' + f' ({len(text)} digits)'})"
    if isinstance(value, numbers.Real):
        return f"a float ({float(value)!r})"
    if isinstance(value, Mapping):
        return f"a {type(value).__name__} with keys {sorted(map(str, value))[:8]}"
    if isinstance(value, np.ndarray):
        return f"an array of {value.dtype} with shape {value.shape}"
    if isinstance(value, list | tuple):
        return f"a {type(value).__name__} of length {len(value)}"
    text = repr(value)
    return f"a {type(value).__name__} ({text if len(text) <= 40 else text[:37] + '...'})"


def is_int(value: Any) -> bool:
    """An integer, not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_)


def is_real(value: Any) -> bool:
    """A real number (int or float, numpy's too), not a bool and not complex."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _range_text(low: float, high: float, low_open: bool, high_open: bool) -> str:
    if low == -math.inf and high == math.inf:
        return "finite"
    if high == math.inf:
        return f"finite and {'>' if low_open else '>='} {low:g}"
    if low == -math.inf:
        return f"finite and {'<' if high_open else '<='} {high:g}"
    return f"in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


def check_real(
    name: str,
    value: Any,
    unit: str = "",
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """``value`` as a finite float in the range [low, high] (``low_open`` / ``high_open``: exclusive)."""
    if not is_real(value):
        raise TypeError(f"{name} must be a real number{_unit(unit)}, got {describe(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int too large for a float
        raise ValueError(
            f"{name} must be {_range_text(low, high, low_open, high_open)}{_unit(unit)}, "
            f"got {describe(value)}"
        ) from None
    ok = math.isfinite(v) and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        raise ValueError(
            f"{name} must be {_range_text(low, high, low_open, high_open)}{_unit(unit)}, got {value!r}"
        )
    return v


def check_positive(name: str, value: Any, unit: str = "", *, high: float = math.inf) -> float:
    """``value`` as a finite float in (0, high]."""
    return check_real(name, value, unit, low=0.0, low_open=True, high=high)


def check_non_negative(name: str, value: Any, unit: str = "", *, high: float = math.inf) -> float:
    """``value`` as a finite float in [0, high]."""
    return check_real(name, value, unit, low=0.0, high=high)


def check_int(name: str, value: Any, *, low: int | None = None, high: int | None = None) -> int:
    """``value`` as an int (not a float such as 20.0, not a bool) in [low, high]."""
    if not is_int(value):
        raise TypeError(f"{name} must be an integer, got {describe(value)}")
    v = int(value)
    if (low is not None and v < low) or (high is not None and v > high):
        lo = "-inf" if low is None else str(low)
        hi = "inf" if high is None else str(high)
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {describe(value)}")
    return v


def check_bool(name: str, value: Any) -> bool:
    """``value`` as a bool (True or False only, numpy's included)."""
    if not isinstance(value, bool | np.bool_):
        raise TypeError(f"{name} must be True or False, got {describe(value)}")
    return bool(value)


def check_str(name: str, value: Any, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be one of {tuple(choices)}, got {describe(value)}")
    if value not in choices:
        raise ValueError(f"{name} must be one of {tuple(choices)}, got {value!r}")
    return value


def check_reals(
    name: str,
    value: Any,
    n: int,
    unit: str = "",
    *,
    low: float = -math.inf,
    high: float = math.inf,
) -> tuple[float, ...]:
    """``value`` (a sequence or 1-D array, not a string) as a tuple of ``n`` floats in [low, high]."""
    items = list(value) if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str) else None
    if items is None or len(items) != n:
        raise TypeError(f"{name} must be {n} real numbers{_unit(unit)}, got {describe(value)}")
    return tuple(check_real(f"{name}[{i}]", v, unit, low=low, high=high) for i, v in enumerate(items))


def check_mapping(name: str, value: Any) -> Mapping[str, Any]:
    """``value`` if it is a mapping with string keys."""
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a dict, got {describe(value)}")
    for key in value:
        if not isinstance(key, str):
            raise TypeError(f"{name} keys must be strings, got {describe(key)}")
    return value


def set_field(obj: object, attr: str, value: object) -> None:
    """Store a normalised field of a frozen dataclass (in its ``__post_init__``)."""
    object.__setattr__(obj, attr, value)


def check_fields(
    obj: object,
    name: Callable[[str], str],
    bounds: Mapping[str, tuple[float, float]],
    unit: Mapping[str, str] | None = None,
) -> None:
    """Check the real-valued fields of the frozen dataclass ``obj`` named in ``bounds`` (field ->
    (low, high), inclusive) and store each as a float; errors name ``name(field)``."""
    units = unit or {}
    for attr, (low, high) in bounds.items():
        v = check_real(name(attr), getattr(obj, attr), units.get(attr, ""), low=low, high=high)
        set_field(obj, attr, v)


def from_fields(name: str, cls: type[T], value: Any, default: T | None = None) -> T:
    """``value`` if it is a ``cls`` (a dataclass), else a ``cls`` built from a mapping of some of its
    fields: over ``default`` when given (``dataclasses.replace``), else ``cls(**value)``. Unknown
    keys and the dataclass' own TypeError / ValueError are raised naming ``name`` and the key."""
    if isinstance(value, cls):
        return value
    if not isinstance(value, Mapping):
        raise TypeError(f"{name} must be a {cls.__name__} or a dict of its fields, got {describe(value)}")
    known = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    for key in value:
        if key not in known:
            raise ValueError(f"{name} has no parameter {key!r}; known: {', '.join(known)}")
    base = default if default is not None else cls()
    try:
        return dataclasses.replace(base, **value)  # type: ignore[type-var]
    except (TypeError, ValueError) as e:
        error = e
    for key, v in value.items():  # pin the error on the key that fails alone, if one does
        try:
            dataclasses.replace(base, **{key: v})  # type: ignore[type-var]
        except (TypeError, ValueError) as e:
            raise type(e)(f"{name}[{key!r}]: {e}") from None
    raise type(error)(f"{name}: {error}") from None


__all__ = [
    "check_bool",
    "check_fields",
    "check_int",
    "check_mapping",
    "check_non_negative",
    "check_positive",
    "check_real",
    "check_reals",
    "check_str",
    "describe",
    "from_fields",
    "is_int",
    "is_real",
    "set_field",
]
