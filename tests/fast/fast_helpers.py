"""Shared helpers of the JAX kernel tests: seeded random poses, relative errors, compile counting."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import numpy as np
from scipy.spatial.transform import Rotation


def rel_err(got: Any, want: Any, floor: float = 1.0) -> float:
    """Largest ``|got - want| / max(|want|, floor)`` over all entries (0 for empty)."""
    g = np.asarray(got, dtype=np.float64)
    w = np.asarray(want, dtype=np.float64)
    assert g.shape == w.shape, (g.shape, w.shape)
    if g.size == 0:
        return 0.0
    return float(np.max(np.abs(g - w) / np.maximum(np.abs(w), floor)))


def rotations(rng: np.random.Generator, n: int, tilt: float = 0.3) -> np.ndarray:
    """(n, 3, 3) world-from-body rotations: any yaw, roll and pitch within ``tilt`` rad."""
    e = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-tilt, tilt, (n, 2))])
    return Rotation.from_euler("ZYX", e).as_matrix()


class Counted:
    """``jax.jit(jax.vmap(fn))`` that counts its traces (a Python side effect runs once per trace)."""

    def __init__(self, fn: Callable[..., Any], in_axes: Any = 0) -> None:
        self.traces = 0

        def traced(*args: Any) -> Any:
            self.traces += 1
            return fn(*args)

        self.fn = jax.jit(jax.vmap(traced, in_axes=in_axes))

    def __call__(self, *args: Any) -> Any:
        return self.fn(*args)
