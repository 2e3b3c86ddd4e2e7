"""Reading the package's JSON data files (calibration, detector model) with one set of failure modes.

:func:`read_json` returns the parsed document or raises the caller's error class with a message
naming the file: missing, unreadable, not JSON, a non-finite constant (``NaN``, ``Infinity``), or
nested too deeply for the parser. Pure Python.
"""

from __future__ import annotations

import json
import os
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} in JSON")


def read_json(
    path: str | os.PathLike[str] | Traversable,
    error: type[Exception],
    what: str,
    missing_hint: str = "",
    invalid_hint: str = "",
) -> Any:
    """The JSON document at ``path``; ``error`` naming the file and ``what`` it should be (e.g. "a
    calibration file") otherwise, with ``missing_hint`` / ``invalid_hint`` appended ("; <hint>")."""
    name = str(path)
    missing = f"; {missing_hint}" if missing_hint else ""
    invalid = f"; {invalid_hint}" if invalid_hint else ""
    try:
        text = (
            Path(path).read_text(encoding="utf-8")
            if isinstance(path, str | os.PathLike)
            else path.read_text(encoding="utf-8")
        )
    except FileNotFoundError:
        raise error(f"{name}: {what} not found{missing}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise error(f"{name}: cannot read {what} ({e}){invalid}") from None
    try:
        return json.loads(text, parse_constant=_reject_constant)
    except RecursionError:  # json.loads recurses once per nesting level
        raise error(f"{name}: not a valid {what} (JSON nested too deeply){invalid}") from None
    except ValueError as e:
        raise error(f"{name}: not a valid {what} ({e}){invalid}") from None


__all__ = [
    "read_json",
]
