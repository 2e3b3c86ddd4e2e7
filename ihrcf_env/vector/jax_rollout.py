"""The batched step that trainers and benchmarks run: N episodes of a functional env as one
function, with the step limit, same-step autoreset and the batch spread over devices.

:func:`batch_step` returns ``step(keys, state, actions, force_reset) -> (obs, state, reward, done,
success)`` over N envs (every argument and result batched along its leading axis): one control step
of every env, an episode that ends (terminated, or at the step limit ``max_steps``) replaced in the
same step by a new one (its first observation returned; reward, ``done`` and ``success`` stay the
ended step's), and every env where ``force_reset`` is true reset as well. The first reset of a
batch is this same function with ``force_reset`` all true over any state of the right shapes
(:func:`placeholder_state`), so the reset and the step compile as one function.

A functional env with the staged form (``step_stage``, ``reset_stage``, ``finish``: the landing
task's :class:`~ihrcf_env.vector.jax_landing.LandingFunctional`) runs its estimator stage once per
env and step, after the resets; ``privileged(reading)`` (optional) appends the critic's privileged
inputs to each observation row (an asymmetric actor-critic's). With a mesh of several devices
(:mod:`ihrcf_env.vector.jax_devices`) each device steps its own share of the envs; every env's
result is computed from its own key alone, so it does not depend on how the batch is split.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from ihrcf_env.vector.jax_batch import CHUNK, RESET_BLOCK, autoreset_step
from ihrcf_env.vector.jax_devices import shard_envs

__all__ = ["batch_step", "has_stages", "placeholder_state"]


def has_stages(fenv: Any) -> bool:
    """Whether ``fenv`` has the staged form (``step_stage``, ``reset_stage``, ``finish``)."""
    return all(callable(getattr(fenv, name, None)) for name in ("step_stage", "reset_stage", "finish"))


def batch_step(
    fenv: Any,
    max_steps: int,
    *,
    mesh: Any = None,
    privileged: Callable[[Any], Any] | None = None,
    curriculum: bool = False,
    chunk: int = CHUNK,
    block: int = RESET_BLOCK,
) -> Callable[..., Any]:
    """The batched step of ``fenv`` (module docstring); its state is ``(env state, steps)``.
    ``privileged(reading) -> (P,)`` needs the staged form. ``curriculum``: the step takes a fifth
    argument, ``start_scale`` (N,), passed to the staged ``reset_stage`` of each env that starts an
    episode (a start curriculum)."""
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise ValueError(f"max_steps must be a positive int, got {max_steps!r}")
    params = fenv.params
    staged = has_stages(fenv)
    if (privileged is not None or curriculum) and not staged:
        raise ValueError(
            "privileged inputs and a start curriculum need a functional env with the staged form "
            "(step_stage, reset_stage, finish)"
        )

    if staged:

        def step_one(key: Any, state: Any, action: Any) -> Any:
            inner, t = state
            reading, inner, reward, done, info = fenv.step_stage(key, inner, action, params)
            return reading, (inner, t + 1), reward, done | (t + 1 >= max_steps), info["is_success"]

        def reset_one(key: Any, start_scale: Any = None) -> Any:
            if start_scale is None:
                reading, inner = fenv.reset_stage(key, params)
            else:
                reading, inner = fenv.reset_stage(key, params, start_scale=start_scale)
            return reading, (inner, jnp.zeros((), jnp.int32))

        def finish(reading: Any, state: Any) -> Any:
            inner, t = state
            obs, inner = fenv.finish(reading, inner)
            if privileged is not None:
                obs = jnp.concatenate([obs, privileged(reading).astype(obs.dtype)])
            return obs, (inner, t)

    else:

        def step_one(key: Any, state: Any, action: Any) -> Any:
            inner, t = state
            obs, inner, reward, done, info = fenv.step(key, inner, action, params)
            success = info.get("is_success", jnp.zeros((), bool))
            return obs, (inner, t + 1), reward, done | (t + 1 >= max_steps), success

        def reset_one(key: Any, start_scale: Any = None) -> Any:
            k1, k2 = jax.random.split(key)
            obs, inner = fenv.reset_from(fenv.draw(k1, params), k2, params)
            return obs, (inner, jnp.zeros((), jnp.int32))

        finish = None  # type: ignore[assignment]

    def local(keys: Any, state: Any, actions: Any, force_reset: Any, start_scale: Any = None) -> Any:
        obs, state, reward, done, success = autoreset_step(
            step_one, reset_one, keys, state, actions, force_reset=force_reset, reset_args=start_scale,
            finish=finish, chunk=chunk, block=block,
        )  # fmt: skip
        return obs, state, reward, done, success

    return local if mesh is None else shard_envs(local, mesh)


def placeholder_state(fenv: Any, num_envs: int) -> Any:
    """A batch state of ``num_envs`` envs of the right shapes and dtypes (zeros): what
    :func:`batch_step` resets with ``force_reset`` all true."""
    params = fenv.params
    if has_stages(fenv):
        shapes = jax.eval_shape(lambda k: fenv.reset_stage(k, params)[1], jax.random.PRNGKey(0))
    else:
        shapes = jax.eval_shape(
            lambda k: fenv.reset_from(fenv.draw(k, params), k, params)[1], jax.random.PRNGKey(0)
        )
    inner = jax.tree_util.tree_map(lambda s: jnp.zeros((num_envs,) + s.shape, s.dtype), shapes)
    return inner, jnp.zeros((num_envs,), jnp.int32)
