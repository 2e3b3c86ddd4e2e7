"""Flat observation layouts: one field spec for every flat vector the wrappers produce.

A layout is a sequence of blocks; a block is a prefix (``""`` for top-level fields) and its
:class:`Field` s. :func:`build_layout` turns them into named slices (``"ranges"``,
``"fused.position"``, each prefixed block under its prefix, and ``"all"``), the scales that turn a
slice back into physical units (``physical = value * scale``) and the per-element bounds of the
Box. Pure numpy: every backend builds its observation from the same layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class Field:
    """``size`` values named ``name``; stored as ``physical / scale`` within [low, high]; ``unit``
    of the physical value and ``meaning`` document it (the tables in ``docs/observations.md``)."""

    name: str
    size: int
    low: float
    high: float
    scale: float = 1.0
    unit: str = ""
    meaning: str = ""


@dataclass(frozen=True)
class Layout:
    """Named slices, scales and bounds of a flat observation."""

    slices: dict[str, slice]
    scales: dict[str, float]
    low: NDArray[np.float32]
    high: NDArray[np.float32]

    @property
    def size(self) -> int:
        return self.slices["all"].stop


Block = tuple[str, Sequence[Field]]


def layout_table(blocks: Sequence[Block]) -> str:
    """The Markdown table of ``blocks``: each field's name (prefixed as in the slices), its slice
    of the flat vector, size, scale (``physical = value * scale``) and meaning."""
    layout = build_layout(blocks)
    rows = ["| name | slice | size | scale | meaning |", "|---|---|---|---|---|"]
    for prefix, fields in blocks:
        for f in fields:
            name = f"{prefix}.{f.name}" if prefix else f.name
            sl = layout.slices[name]
            scale = f"{f.scale:.4g} {f.unit}".strip()
            rows.append(f"| `{name}` | {sl.start}:{sl.stop} | {f.size} | {scale} | {f.meaning} |")
    return "\n".join(rows)


def build_layout(blocks: Sequence[Block]) -> Layout:
    """The :class:`Layout` of ``blocks`` (module docstring), in order."""
    slices: dict[str, slice] = {}
    scales: dict[str, float] = {}
    lows: list[float] = []
    highs: list[float] = []
    i = 0
    for prefix, fields in blocks:
        start = i
        for f in fields:
            name = f"{prefix}.{f.name}" if prefix else f.name
            if name in slices:
                raise ValueError(f"flat layout: the field {name!r} is given twice")
            slices[name] = slice(i, i + f.size)
            scales[name] = f.scale
            lows += [f.low] * f.size
            highs += [f.high] * f.size
            i += f.size
        if prefix:
            slices[prefix] = slice(start, i)
    slices["all"] = slice(0, i)
    return Layout(slices, scales, np.array(lows, np.float32), np.array(highs, np.float32))


__all__ = [
    "Block",
    "Field",
    "Layout",
    "build_layout",
    "layout_table",
]
