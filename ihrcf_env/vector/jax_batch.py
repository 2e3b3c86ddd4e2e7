"""Running a per-env JAX function over a batch of envs in cache-sized chunks.

``jax.vmap`` over N envs turns every operation of the step into one loop over N rows: past a few
hundred envs the intermediate arrays of one operation no longer fit the CPU's caches, and each of
the step's thousands of small operations streams its rows through memory. :func:`map_envs` runs
the vmapped function over chunks of :data:`CHUNK` envs one after another (``jax.lax.map`` with a
batch size), so that a chunk's intermediates stay in cache; the result is the vmapped one's.

A reset (a new episode drawn and its first observation) costs about two steps. A per-env
autoreset under ``vmap`` (gymnax's ``step``: step and reset, then select) runs it for every env on
every step, and a masked batch reset runs it for all envs whenever one ended. :func:`reset_ended`
runs it only for the rows that ended, gathered into blocks of :data:`RESET_BLOCK` rows;
:func:`autoreset_step` is a batched step with that autoreset (for trainers that step N envs at
once). The first reset of a batch is the same step with every row forced to reset, so one compiled
function serves the reset and the step.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

__all__ = ["CHUNK", "RESET_BLOCK", "autoreset_step", "map_envs", "reset_ended"]

#: Envs per chunk: on CPU the flight's rate per env peaks near 64 envs per vmap (the estimator
#: stage alone ran about a fifth cheaper per env over 256 envs per vmap; not re-tuned for both).
CHUNK = 64
#: Rows reset per block by :func:`reset_ended` (episodes end on a few envs per step).
RESET_BLOCK = 16


def map_envs(fn: Callable[..., Any], *batched: Any, chunk: int = CHUNK) -> Any:
    """``jax.vmap(fn)(*batched)`` (every argument batched along its leading axis), computed in chunks
    of ``chunk`` envs (all at once when there are no more)."""
    _check_positive("chunk", chunk)
    n = jax.tree_util.tree_leaves(batched)[0].shape[0]
    if n <= chunk:
        return jax.vmap(fn)(*batched)
    return jax.lax.map(lambda args: fn(*args), batched, batch_size=chunk)


def _check_positive(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be a positive int, got {value!r}")


def reset_ended(
    reset_one: Callable[[Any], Any],
    keys: Any,
    batch: Any,
    ended: Any,
    *,
    block: int = RESET_BLOCK,
) -> Any:
    """``batch`` (a pytree of N rows) with each row ``i`` where ``ended`` is true replaced by
    ``reset_one(keys[i])`` (``keys``: one key per row). The ended rows are gathered into blocks of
    ``block`` rows, and ``reset_one`` runs on as many blocks as rows ended (none when none ended);
    the results are scattered back. Rows that did not end are returned unchanged.

    ``reset_one`` is traced once: the blocks run under a ``lax.scan`` whose body computes a block
    only while ended rows remain (``lax.cond`` on a scalar, so a skipped block costs nothing), so
    compiling a batched step costs one reset whatever the batch size."""
    _check_positive("block", block)
    n = ended.shape[0]
    block = min(block, n)
    blocks = -(-n // block)
    count = jnp.sum(ended.astype(jnp.int32))
    rows = jnp.nonzero(ended, size=blocks * block, fill_value=n)[0].reshape(blocks, block)
    shapes = jax.eval_shape(jax.vmap(reset_one), jax.tree_util.tree_map(lambda k: k[:block], keys))

    def run(r: Any) -> Any:
        return jax.vmap(reset_one)(jax.tree_util.tree_map(lambda k: k[jnp.minimum(r, n - 1)], keys))

    def skip(r: Any) -> Any:
        return jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)

    def body(i: Any, r: Any) -> tuple[Any, Any]:
        return i + 1, jax.lax.cond(i * block < count, run, skip, r)

    _, fresh = jax.lax.scan(body, jnp.zeros((), jnp.int32), rows)
    flat = rows.reshape(-1)
    return jax.tree_util.tree_map(
        lambda a, b: a.at[flat].set(b.reshape((blocks * block,) + b.shape[2:]).astype(a.dtype), mode="drop"),
        batch,
        fresh,
    )


def autoreset_step(
    step_one: Callable[[Any, Any, Any], tuple[Any, Any, Any, Any, Any]],
    reset_one: Callable[[Any], tuple[Any, Any]],
    keys: Any,
    state: Any,
    actions: Any,
    *,
    force_reset: Any = None,
    reset_args: Any = None,
    finish: Callable[[Any, Any], tuple[Any, Any]] | None = None,
    chunk: int = CHUNK,
    block: int = RESET_BLOCK,
) -> tuple[Any, Any, Any, Any, Any]:
    """One step of N envs with same-step autoreset, the batched form of gymnax's ``step``:
    ``step_one(key, state, action) -> (obs, state, reward, done, info)`` for every env (in chunks
    of ``chunk``), then the envs that are done, or where ``force_reset`` (a bool per env, optional)
    is true, get ``reset_one(key) -> (obs, state)`` (``reset_one(key, arg)`` with ``reset_args``, a
    pytree of one row per env: the env's row as ``arg``) (their new first observation and state; reward,
    done and info stay the step's). ``keys`` has one key per env; each env's reset draws from its own
    key, so the result of an env does not depend on the others (nor on how the batch is split).

    With ``finish``, ``step_one`` and ``reset_one`` return an unfinished reading in place of the
    observation and ``finish(reading, state) -> (obs, state)`` makes the observation once per env,
    after the resets (for the landing task: the estimator stage runs once per env and step, on the
    new episode's first reading where one started, instead of once in the step and once more in
    the reset)."""
    split = jax.vmap(jax.random.split)(keys)
    obs, state, reward, done, info = map_envs(step_one, split[:, 0], state, actions, chunk=chunk)
    ended = done if force_reset is None else done | force_reset
    if reset_args is None:
        obs, state = reset_ended(reset_one, split[:, 1], (obs, state), ended, block=block)
    else:
        obs, state = reset_ended(
            lambda ka: reset_one(*ka), (split[:, 1], reset_args), (obs, state), ended, block=block
        )
    if finish is not None:
        obs, state = map_envs(finish, obs, state, chunk=chunk)
    return obs, state, reward, done, info
