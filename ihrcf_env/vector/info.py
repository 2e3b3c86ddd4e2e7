"""The ``info`` of a vector env from its envs' own, in one pass: :func:`stack_infos`.

Gymnasium's vector envs build their ``info`` with ``VectorEnv._add_info``, one env at a time: each
key becomes an array over the envs (its dtype from the first env that has the key: ``int``,
``float``, ``bool`` and numpy scalars give arrays of that type, numpy arrays give arrays of their
shape and dtype per env, anything else an object array) with a boolean ``_key`` mask of the envs
that have it; a dict value gives a nested ``info`` of the same form; ``final_obs`` is always an
object array. :func:`stack_infos` gives the same dict (keys in the same order, the same dtypes
and values) with one array assignment per key instead of one per env and key; :func:`unbatch_info`
gives one env's dict back.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["stack_infos", "unbatch_info"]


def stack_infos(infos: Sequence[dict[str, Any] | None], n: int | None = None) -> dict[str, Any]:
    """The vector ``info`` of ``n`` envs (default ``len(infos)``) whose own ``info`` is
    ``infos[i]`` (None or a missing trailing entry: that env adds nothing)."""
    size = len(infos) if n is None else n
    if len(infos) > size:
        raise ValueError(f"infos: at most n = {size} dicts, got {len(infos)}")
    columns: dict[str, tuple[list[int], list[Any]]] = {}
    for i, info in enumerate(infos):
        if not info:
            continue
        for key, value in info.items():
            rows, values = columns.setdefault(key, ([], []))
            rows.append(i)
            values.append(value)
    out: dict[str, Any] = {}
    for key, (rows, values) in columns.items():
        out[key] = _column(key, rows, values, size)
        mask = np.zeros(size, dtype=np.bool_)
        mask[rows] = True
        out[f"_{key}"] = mask
    return out


def _column(key: str, rows: list[int], values: list[Any], size: int) -> Any:
    """The array (or nested info) of one key over ``size`` envs: ``values[k]`` for env ``rows[k]``."""
    first = values[0]
    if key != "final_obs" and isinstance(first, dict):
        nested: list[dict[str, Any] | None] = [None] * size
        for i, v in zip(rows, values, strict=True):
            nested[i] = v
        return stack_infos(nested, size)
    if key == "final_obs" or not (
        type(first) in (int, float, bool)
        or issubclass(type(first), np.number)
        or isinstance(first, np.ndarray)
    ):
        array = np.full(size, fill_value=None, dtype=object)
        for i, v in zip(rows, values, strict=True):
            array[i] = v
        return array
    if isinstance(first, np.ndarray):
        array = np.zeros((size, *first.shape), dtype=first.dtype)
        for i, v in zip(rows, values, strict=True):
            array[i] = v
        return array
    array = np.zeros(size, dtype=type(first))
    array[rows] = values
    return array


def unbatch_info(infos: dict[str, Any], i: int) -> dict[str, Any]:
    """Env ``i``'s info dict from a Gymnasium vector ``infos`` (each key with its ``_key`` mask;
    nested dicts recursively)."""
    out: dict[str, Any] = {}
    for key, value in infos.items():
        if key.startswith("_") and key[1:] in infos:
            continue  # a mask
        mask = infos.get(f"_{key}")
        if mask is not None and not bool(mask[i]):
            continue
        if isinstance(value, dict):
            out[key] = unbatch_info(value, i)
        else:
            item = value[i]
            out[key] = item.item() if isinstance(item, np.generic) else item
    return out
