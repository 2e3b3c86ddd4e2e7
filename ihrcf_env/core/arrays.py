"""Small-array helpers for per-step code, where numpy's per-call overhead dominates."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def clip(x: ArrayLike, low: float, high: float) -> NDArray[np.float64]:
    """``np.clip(x, low, high)`` (the same values, NaN kept) as float64, without ``np.clip``'s
    Python-level overhead on arrays of a few elements."""
    out: NDArray[np.float64] = np.minimum(np.maximum(np.asarray(x, dtype=np.float64), low), high)
    return out


__all__ = [
    "clip",
]
