"""Running a per-env JAX function over a batch of envs in cache-sized chunks.

``jax.vmap`` over N envs turns every operation of the step into one loop over N rows: past a few
hundred envs the intermediate arrays of one operation no longer fit the CPU's caches, and each of
the step's thousands of small operations streams its rows through memory. :func:`map_envs` runs
the vmapped function over chunks of :data:`CHUNK` envs one after another (``jax.lax.map`` with a
batch size), so that a chunk's intermediates stay in cache; the result is the vmapped one's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax

__all__ = ["CHUNK", "map_envs"]

#: Envs per chunk: the step's per-env rate peaks at a few hundred envs per vmap on CPU.
CHUNK = 256


def map_envs(fn: Callable[..., Any], *batched: Any, chunk: int = CHUNK) -> Any:
    """``jax.vmap(fn)(*batched)`` (every argument batched along its leading axis), computed in chunks
    of ``chunk`` envs (all at once when there are no more)."""
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise ValueError(f"chunk must be a positive int, got {chunk!r}")
    n = jax.tree_util.tree_leaves(batched)[0].shape[0]
    if n <= chunk:
        return jax.vmap(fn)(*batched)
    return jax.lax.map(lambda args: fn(*args), batched, batch_size=chunk)
