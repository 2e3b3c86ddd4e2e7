"""The options only a vector env takes, refused by name when a single env is made.

``gym.make(id, backend="jax")`` and ``gym.make_vec(id, ..., vectorization_mode="sync")`` (or
``"async"``) build single envs, which have no backend, workers, seeding or dtype: these options
belong to the ids' native vector env, ``gym.make_vec(id, num_envs=N,
vectorization_mode="vector_entry_point", ...)`` (:mod:`ihrcf_env.vector`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["VECTOR_ONLY_OPTIONS", "refuse_vector_options"]

#: Options of the native vector env that a single env does not take.
VECTOR_ONLY_OPTIONS = ("backend", "workers", "seeding", "dtype")


def refuse_vector_options(options: Mapping[str, Any]) -> None:
    """ValueError naming the first of :data:`VECTOR_ONLY_OPTIONS` in ``options`` and saying where it
    belongs."""
    bad = [name for name in VECTOR_ONLY_OPTIONS if name in options]
    if bad:
        raise ValueError(
            f"{bad[0]}={options[bad[0]]!r}: an option of the native vector env only; it needs "
            f'gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", {bad[0]}=...) '
            "(gym.make and vectorization_mode='sync' or 'async' build single envs, which do not take it)"
        )
