"""A Gymnasium vector env over a functional JAX env: ``gym.make_vec(id, num_envs=N, backend="jax")``.

:class:`JaxVectorEnv` steps ``num_envs`` episodes of a :class:`FunctionalEnv` (pure ``reset`` /
``step`` functions over a state pytree, one env per call) as one compiled call per step
(``jax.jit`` of ``jax.vmap``). Numpy in and out: actions are checked whole (shape, finite) before
any env steps; observations, rewards, ``terminated`` and ``truncated`` come back as numpy arrays,
``info`` as Gymnasium's vector envs give it (each key an array over the envs with a boolean
``_key`` mask). Gymnasium 1.x autoreset: next-step (default; an env that ended is reset by the
following ``step``, which returns its first observation with reward 0) or same-step (the env that
ends is reset in that step; its last observation and info in ``info["final_obs"]`` /
``info["final_info"]``). The step limit of the id's spec truncates, as ``gym.make``'s TimeLimit.

Every reset draws a new episode (never a cached first state). ``seeding="paired"`` (default) draws
each episode's start, deck motion and wind on the host from the env's own generator exactly as the
PyBullet env does (sub-env ``i`` of ``reset(seed=s)`` gets seed ``s + i``, and its later episodes
continue that generator), so a seed gives the same episode on both backends; ``seeding="jax"``
draws them inside the compiled step from the env's JAX key (the same distributions, no host work,
no pairing). The per-step sensor noise always comes from each env's JAX key (derived from its
episode key: deterministic for a seed, independent of ``num_envs``).

``info`` is the PyBullet vector env's: a functional env with ``reset_from_info`` gives the reset's
info, and its ``host_info`` turns the compiled arrays into the PyBullet env's columns (strings,
float64); an env reset by a step (next-step autoreset) shows its reset's info in that step, as the
PyBullet vector env does. Every reset (the first, a full one, a masked one, an autoreset) runs one
compiled function on blocks of :data:`RESET_ROWS` rows (as many blocks as it takes): one
compilation of the reset whatever ``num_envs`` is.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding as gym_seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int
from ihrcf_env.vector.checks import (
    check_actions,
    check_autoreset_mode,
    env_seeds,
    split_reset_mask,
    time_limit,
)

__all__ = ["MAX_JAX_ENVS", "RESET_ROWS", "SEEDINGS", "FunctionalEnv", "JaxVectorEnv", "reset_size"]

#: Most envs of one JAX vector env.
MAX_JAX_ENVS = 65536
#: Rows of the block a reset of few envs runs on (more: all ``num_envs`` rows).
RESET_ROWS = 16
#: The ways a JAX vector env draws its episodes (module docstring).
SEEDINGS = ("paired", "jax")

StepReturn = tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]


class FunctionalEnv(Protocol):
    """What :class:`JaxVectorEnv` steps: pure functions of one env (no batch axis).

    ``draw_host(rng)`` draws an episode (a pytree of numpy arrays) from a numpy generator as the
    PyBullet env draws it; ``draw(key, params)`` draws one in JAX; ``reset_from(episode, key,
    params) -> (obs, state)``; ``step(key, state, action, params) -> (obs, state, reward,
    terminated, info)`` with ``info`` a dict of arrays. ``episode_key(rng)`` is the integer key of
    the episode ``draw_host`` would draw next (the JAX noise key derives from it). Optional:
    ``reset_from_info(episode, key, params) -> (obs, state, info)`` (the reset's info) and
    ``host_info(info) -> dict`` (the vector info's columns of rows of the compiled info; a
    ``_key`` entry narrows the rows of ``key``)."""

    @property
    def params(self) -> Any: ...

    @property
    def observation_space(self) -> spaces.Space[Any]: ...

    @property
    def action_space(self) -> spaces.Space[Any]: ...

    def draw_host(self, rng: np.random.Generator) -> tuple[int, Any]: ...

    def draw(self, key: Any, params: Any) -> Any: ...

    def reset_from(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any]: ...

    def step(self, key: Any, state: Any, action: Any, params: Any) -> tuple[Any, Any, Any, Any, Any]: ...


def reset_size(rows: int, num_envs: int) -> int:
    """The padded row count of one call of the compiled reset: a block of :data:`RESET_ROWS` rows
    (at most ``num_envs``); a reset of more rows takes several blocks, so one compiled shape serves
    every reset."""
    return min(RESET_ROWS, num_envs)


class JaxVectorEnv(VectorEnv):
    """``num_envs`` episodes of ``fenv`` stepped as one compiled call (module docstring).

    ``env_id`` names the spec (its step limit; ``max_episode_steps`` overrides it as in
    ``gym.make``: -1 for none). ``dtype`` is the computation's float type (``"float64"`` or
    ``"float32"``)."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        env_id: str,
        fenv: FunctionalEnv,
        num_envs: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        seeding: str = "paired",
        dtype: str = "float64",
        devices: int | None = None,
    ) -> None:
        import jax

        from ihrcf_env.fast.cache import enable_compilation_cache
        from ihrcf_env.vector.jax_devices import check_devices, env_mesh, shard_envs

        enable_compilation_cache()
        n = check_int("num_envs", num_envs, low=1, high=MAX_JAX_ENVS)
        if seeding not in SEEDINGS:
            raise ValueError(f"seeding must be one of {SEEDINGS}, got {seeding!r}")
        if dtype not in ("float64", "float32"):
            raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        self.max_episode_steps = time_limit(env_id, max_episode_steps)
        self.env_id = env_id
        self.spec = gym.spec(env_id)
        self.num_envs = n
        self.seeding = seeding
        self.dtype = dtype
        self.fenv = fenv
        self.single_observation_space = fenv.observation_space
        self.single_action_space = fenv.action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self._x64 = dtype == "float64"
        self._rngs: list[np.random.Generator] = [gym_seeding.np_random(None)[0] for _ in range(n)]
        self._autoreset = np.zeros(n, dtype=bool)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._state: Any = None
        self._keys: Any = None
        self._obs: NDArray[Any] | None = None
        self._closed = False
        params = fenv.params
        with jax.enable_x64(self._x64):
            self._params = jax.tree_util.tree_map(jax.numpy.asarray, params)
        #: the devices the envs are spread over (each steps its share of the batch)
        self.devices = check_devices(devices, n)
        mesh = env_mesh(self.devices)
        from jax.sharding import NamedSharding, PartitionSpec

        from ihrcf_env.vector.jax_devices import ENV_AXIS

        #: where the batch's rows live (split over the devices), so that every call sees one placement
        self._rows = NamedSharding(mesh, PartitionSpec(ENV_AXIS))

        def batched(state: Any, keys: Any, actions: Any, stepping: Any) -> Any:
            return self._batched_step(state, keys, actions, stepping, self._params)

        step = shard_envs(batched, mesh)
        self._step_fn = jax.jit(
            lambda state, keys, actions, stepping, params: step(state, keys, actions, stepping)
        )
        self._reset_fn = jax.jit(self._reset_rows_fn)
        #: how often the reset was traced (each trace is a compilation)
        self.reset_traces = 0

    # -- compiled pieces -------------------------------------------------------------------
    def _batched_step(self, state: Any, keys: Any, actions: Any, stepping: Any, params: Any) -> Any:
        """All envs stepped; the rows not ``stepping`` keep their state (their outputs are
        discarded by the host)."""
        import jax
        import jax.numpy as jnp

        from ihrcf_env.vector.jax_batch import map_envs

        split = jax.vmap(jax.random.split)(keys)
        new_keys, step_keys = split[:, 0], split[:, 1]
        obs, new_state, reward, terminated, info = map_envs(
            lambda k, s, a: self.fenv.step(k, s, a, params), step_keys, state, actions
        )

        def keep(new: Any, old: Any) -> Any:
            m = stepping.reshape((-1,) + (1,) * (jnp.ndim(new) - 1))
            return jnp.where(m, new, old)

        state = jax.tree_util.tree_map(keep, new_state, state)
        keys = jnp.where(stepping[:, None], new_keys, keys)
        return obs, state, reward, terminated, info, keys

    def _reset_one(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any, Any]:
        """(obs, state, info) of one env's new episode."""
        with_info = getattr(self.fenv, "reset_from_info", None)
        if with_info is not None:
            return with_info(episode, key, params)
        obs, state = self.fenv.reset_from(episode, key, params)
        return obs, state, {}

    def _reset_rows_fn(
        self, state: Any, keys: Any, obs: Any, rows: Any, episodes: Any, row_keys: Any, params: Any
    ) -> Any:
        """The reset of the rows ``rows`` (episodes given, or drawn in JAX when None) scattered into
        the batch ``state``, ``keys`` and ``obs`` (a row ``num_envs``: padding, dropped); also the
        reset rows' info (unscattered)."""
        import jax

        self.reset_traces += 1  # a Python side effect: runs once per trace
        fenv = self.fenv
        if episodes is None:
            split = jax.vmap(jax.random.split)(row_keys)
            row_keys, draw_keys = split[:, 0], split[:, 1]
            episodes = jax.vmap(fenv.draw, in_axes=(0, None))(draw_keys, params)
        split = jax.vmap(jax.random.split)(row_keys)
        row_keys, reset_keys = split[:, 0], split[:, 1]
        reset_all = jax.vmap(self._reset_one, in_axes=(0, 0, None))
        new_obs, new_state, info = reset_all(episodes, reset_keys, params)

        def put(batch: Any, rows_value: Any) -> Any:
            return batch.at[rows].set(rows_value.astype(batch.dtype), mode="drop")

        state = jax.tree_util.tree_map(put, state, new_state)
        return state, put(keys, row_keys), put(obs, new_obs), info

    def _empty_batch(self, episodes: Any, row_keys: Any) -> tuple[Any, Any, Any]:
        """Zero arrays of the batch state, keys and observations (the rows before their first
        reset), shaped by tracing the reset (nothing is compiled)."""
        import jax
        import jax.numpy as jnp

        def first(episode: Any, key: Any) -> Any:
            obs, state, _ = self._reset_one(episode, key, self._params)
            return obs, state

        one = jax.tree_util.tree_map(lambda a: a[0], (episodes, row_keys)) if episodes is not None else None
        if one is None:
            k = row_keys[0]
            shapes = jax.eval_shape(lambda k: first(self.fenv.draw(k, self._params), k), k)
        else:
            shapes = jax.eval_shape(first, *one)
        n = self.num_envs

        def zeros(s: Any) -> Any:
            return jnp.zeros((n, *s.shape), s.dtype)

        obs, state = jax.tree_util.tree_map(zeros, shapes)
        keys = jnp.zeros((n, *row_keys.shape[1:]), row_keys.dtype)
        return jax.device_put((state, keys, obs), self._rows)

    # -- reset -------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every env (``reset(seed=s)``: env ``i`` with seed ``s + i``) or, with
        ``options["reset_mask"]``, the envs it marks; a new episode for each (module docstring)."""
        self._check_open()
        seeds = env_seeds(seed, self.num_envs)
        mask, rest = split_reset_mask(options, self.num_envs)
        if rest:
            raise ValueError(f"options: the JAX backend takes only 'reset_mask', got {sorted(rest)}")
        if mask is not None and self._state is None:
            raise gym.error.ResetNeeded("options['reset_mask']: reset every env once first")
        rows = np.arange(self.num_envs) if mask is None else np.flatnonzero(mask)
        for i in rows:
            if seeds[i] is not None or self._state is None:
                self._rngs[i] = gym_seeding.np_random(seeds[i])[0]
        info = self._reset_rows(rows)
        assert self._obs is not None
        return self._obs.copy(), _scatter_info(self.num_envs, (rows, info))

    def _reset_rows(self, rows: NDArray[np.intp]) -> dict[str, Any]:
        """New episodes for ``rows`` (their step counters and pending autoresets cleared), a block
        of :func:`reset_size` rows per call of the compiled reset; the reset rows' info columns
        (one row per entry of ``rows``)."""
        size = reset_size(rows.size, self.num_envs)
        parts = [self._reset_block(rows[i : i + size], size) for i in range(0, rows.size, size)]
        return {key: _join([p[key] for p in parts]) for key in parts[0]} if len(parts) > 1 else parts[0]

    def _reset_block(self, rows: NDArray[np.intp], size: int) -> dict[str, Any]:
        """:meth:`_reset_rows` of at most ``size`` rows, padded to ``size``."""
        import jax
        import jax.numpy as jnp

        n = self.num_envs
        padded = np.full(size, n, dtype=np.int32)
        padded[: rows.size] = rows
        episode_keys = np.zeros(size, dtype=np.uint64)
        episodes: Any = None
        with jax.enable_x64(self._x64):
            if self.seeding == "paired":
                drawn = [self.fenv.draw_host(self._rngs[i]) for i in rows]
                episode_keys[: rows.size] = [k for k, _ in drawn]
                eps = [e for _, e in drawn]
                eps += [eps[0]] * (size - rows.size)
                episodes = jax.tree_util.tree_map(lambda *xs: jnp.asarray(np.stack(xs)), *eps)
            else:
                episode_keys[: rows.size] = [int(self._rngs[i].integers(0, 2**63)) for i in rows]
            row_keys = jax.vmap(_key_of)(
                jnp.asarray((episode_keys >> np.uint64(32)).astype(np.uint32)),
                jnp.asarray((episode_keys & np.uint64(0xFFFFFFFF)).astype(np.uint32)),
            )
            if self._state is None:
                self._state, self._keys, obs = self._empty_batch(episodes, row_keys)
            else:
                obs = jax.device_put(jnp.asarray(self._obs), self._rows)
                # one placement for every call (a 1-device mesh may label outputs replicated)
                self._state, self._keys = jax.device_put((self._state, self._keys), self._rows)
            self._state, self._keys, obs, info = self._reset_fn(
                self._state, self._keys, obs, jnp.asarray(padded), episodes, row_keys, self._params
            )
        self._obs = np.asarray(obs)
        self._elapsed[rows] = 0
        self._autoreset[rows] = False
        return self._host_info(jax.tree_util.tree_map(lambda a: np.asarray(a)[: rows.size], info))

    def _host_info(self, info: dict[str, Any]) -> dict[str, Any]:
        """The functional env's ``host_info`` of rows of compiled info (numpy arrays)."""
        host = getattr(self.fenv, "host_info", None)
        return host(info) if host is not None else info

    # -- step ---------------------------------------------------------------------------------
    def step(self, actions: Any) -> StepReturn:
        """Step every env with its row of ``actions`` (shape ``(num_envs, *action shape)``); an env
        that ended at the previous step is reset instead (next-step autoreset)."""
        import jax
        import jax.numpy as jnp

        self._check_open()
        a = check_actions(actions, self.num_envs, self.single_action_space.shape)  # type: ignore[arg-type]
        if self._state is None:
            raise gym.error.ResetNeeded("step: reset the vector env first")
        n = self.num_envs
        reset_rows = np.flatnonzero(self._autoreset)
        reset_info = self._reset_rows(reset_rows) if reset_rows.size else {}
        stepping = ~np.isin(np.arange(n), reset_rows)
        with jax.enable_x64(self._x64):
            dt = jnp.float64 if self._x64 else jnp.float32
            obs, self._state, reward, terminated, info, self._keys = self._step_fn(
                self._state, self._keys, jnp.asarray(a, dt), jnp.asarray(stepping), self._params
            )
        obs_np = np.asarray(obs)
        rewards = np.where(stepping, np.asarray(reward, np.float64), 0.0)
        term = np.asarray(terminated, bool) & stepping
        self._elapsed[stepping] += 1
        limit = self.max_episode_steps
        trunc = stepping & ~term & (limit is not None) & (self._elapsed >= (limit or 0))
        assert self._obs is not None
        out_obs = np.where(stepping.reshape((-1,) + (1,) * (obs_np.ndim - 1)), obs_np, self._obs)
        ended = np.flatnonzero(term | trunc)
        self._obs = out_obs
        info_np = _to_numpy(info)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended.size:
            final_obs = out_obs[ended].copy()
            done = np.zeros(n, dtype=bool)
            done[ended] = True
            going = np.flatnonzero(stepping & ~done)
            final_info = _scatter_info(n, (ended, self._host_info(_take(info_np, ended))))
            new_info = self._reset_rows(ended)
            out_obs = self._obs.copy()
            fo = np.full(n, None, dtype=object)
            for j, i in enumerate(ended):
                fo[i] = final_obs[j]
            infos = _scatter_info(
                n,
                (going, self._host_info(_take(info_np, going))),
                (reset_rows, reset_info),
                (ended, new_info),
            )
            infos.update(final_obs=fo, _final_obs=done, final_info=final_info, _final_info=done.copy())
        else:
            rows = np.flatnonzero(stepping)
            infos = _scatter_info(n, (rows, self._host_info(_take(info_np, rows))), (reset_rows, reset_info))
            self._autoreset = term | trunc
        return out_obs.copy(), rewards, term, trunc, infos

    # -- closing ------------------------------------------------------------------------------
    def close_extras(self, **kwargs: Any) -> None:
        """Drop the batch state (no other resources are held)."""
        self._closed = True
        self._state = None

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("vector env is closed (close() was called): make a new one with gym.make_vec")


def _join(parts: list[Any]) -> Any:
    """Info columns of consecutive row blocks joined (nested dicts key by key)."""
    if isinstance(parts[0], dict):
        return {key: _join([p[key] for p in parts]) for key in parts[0]}
    return np.concatenate([np.asarray(p) for p in parts])


def _to_numpy(info: Any) -> Any:
    """``info`` (a dict of arrays or NamedTuples of arrays, possibly nested) with numpy arrays."""
    import jax

    return jax.tree_util.tree_map(np.asarray, info)


def _take(info: Any, rows: NDArray[Any]) -> Any:
    """The rows ``rows`` (indices or a bool mask) of every array of ``info``."""
    import jax

    return jax.tree_util.tree_map(lambda a: np.asarray(a)[rows], info)


def _scatter_info(n: int, *parts: tuple[NDArray[np.intp], dict[str, Any]]) -> dict[str, Any]:
    """The vector ``info`` of ``n`` envs from ``parts``, each (rows, columns): ``columns[key]`` holds
    one entry per row of ``rows`` (a nested dict: a nested info), ``columns["_" + key]`` (optional,
    a bool per row) the rows that have ``key``. As Gymnasium's vector envs give it (and
    :func:`~ihrcf_env.vector.info.stack_infos`): each key an array over the envs (zeros, or None in
    an object array, where absent) and its ``_key`` mask."""
    order: list[str] = []
    for _, cols in parts:
        order += [k for k in cols if not k.startswith("_") and k not in order]
    out: dict[str, Any] = {}
    for key in order:
        pieces = []
        for rows, cols in parts:
            if key not in cols:
                continue
            value, have = cols[key], cols.get(f"_{key}")
            if have is not None:
                rows, value = rows[have], _take(value, have)
            pieces.append((rows, value))
        mask = np.zeros(n, dtype=bool)
        for rows, _ in pieces:
            mask[rows] = True
        first = pieces[0][1]
        if isinstance(first, dict):
            out[key] = _scatter_info(n, *pieces)
        else:
            first = np.asarray(first)
            if first.dtype == object:
                column = np.full(n, None, dtype=object)
            else:
                column = np.zeros((n, *first.shape[1:]), dtype=first.dtype)
            for rows, value in pieces:
                column[rows] = value
            out[key] = column
        out[f"_{key}"] = mask
    return out


def _key_of(hi: Any, lo: Any) -> Any:
    """A JAX PRNG key of a 64-bit episode key given as two uint32 halves."""
    import jax

    return jax.random.fold_in(jax.random.PRNGKey(hi), lo)
