"""The landing tasks' Gymnasium vector envs: ``gym.make_vec(id, num_envs=N)`` (and ``workers=K``).

* :class:`DeckLandingVectorEnv` (:mod:`ihrcf_env.vector.env`): N envs in this process, stepped
  together (each env's world advanced by PyBullet, its observation through its own estimators);
* :class:`WorkerVectorEnv` (:mod:`ihrcf_env.vector.workers`): N envs over K worker processes, each
  holding a ``DeckLandingVectorEnv`` of its share;
* :func:`make_landing_v1` / :func:`make_landing_v2`: the ids' ``vector_entry_point`` (``workers``
  picks the kind);
* :mod:`ihrcf_env.vector.checks` (the arguments checked whole), :mod:`ihrcf_env.vector.info`
  (the vector ``info``).
"""

from __future__ import annotations

from typing import Any

from gymnasium.vector import VectorEnv

from ihrcf_env.core.checks import check_int
from ihrcf_env.vector.checks import MAX_ENVS
from ihrcf_env.vector.env import DeckLandingVectorEnv
from ihrcf_env.vector.info import stack_infos, unbatch_info
from ihrcf_env.vector.workers import MAX_WORKERS, WorkerError, WorkerVectorEnv

__all__ = [
    "MAX_ENVS",
    "MAX_WORKERS",
    "DeckLandingVectorEnv",
    "WorkerError",
    "WorkerVectorEnv",
    "make_landing_v1",
    "make_landing_v2",
    "make_vector_env",
    "stack_infos",
    "unbatch_info",
]


def make_vector_env(
    env_id: str, num_envs: int = 1, workers: int = 1, backend: str = "pybullet", **options: Any
) -> VectorEnv:
    """The vector env of ``num_envs`` envs of ``env_id``: PyBullet envs in this process
    (``workers=1``) or over ``workers`` processes; ``options`` as ``gym.make`` takes them (and
    ``autoreset_mode``). ``backend="jax"``: the compiled JAX step
    (:mod:`ihrcf_env.vector.jax_make`; needs the ``[jax]`` extra; also ``seeding``, ``dtype``)."""
    if backend == "jax":
        if workers != 1:
            raise ValueError("workers: the JAX backend runs in this process (workers=1)")
        try:
            import jax  # noqa: F401
        except ImportError:
            raise ImportError("backend='jax' needs JAX: pip install 'ihrcf_env[jax]'") from None
        from ihrcf_env.vector.jax_make import make_jax_vector_env

        return make_jax_vector_env(env_id, num_envs, **options)
    if backend != "pybullet":
        raise ValueError(f"backend must be 'pybullet' or 'jax', got {backend!r}")
    if check_int("workers", workers, low=1, high=MAX_WORKERS) > 1:
        return WorkerVectorEnv(env_id, num_envs, workers, **options)
    return DeckLandingVectorEnv(env_id, num_envs, **options)


def make_landing_v1(num_envs: int = 1, workers: int = 1, **options: Any) -> VectorEnv:
    """``vector_entry_point`` of ``ihrcf_env/DeckLanding-v1`` (:func:`make_vector_env`)."""
    from ihrcf_env import LANDING_V1_ID

    return make_vector_env(LANDING_V1_ID, num_envs, workers, **options)


def make_landing_v2(num_envs: int = 1, workers: int = 1, **options: Any) -> VectorEnv:
    """``vector_entry_point`` of ``ihrcf_env/DeckLanding-v2`` (:func:`make_vector_env`)."""
    from ihrcf_env import LANDING_V2_ID

    return make_vector_env(LANDING_V2_ID, num_envs, workers, **options)
