"""The landing tasks' vector env over several processes: ``gym.make_vec(id, num_envs=N, workers=K)``.

:class:`WorkerVectorEnv` splits its N envs over K worker processes, each holding one
:class:`~ihrcf_env.wrappers.vector.DeckLandingVectorEnv` of its share (the first ``N mod K``
workers take one env more). A step sends each worker its rows of the actions and receives its
batched results: one message per worker and step, whatever N, so the processes' cores add up
(Gymnasium's ``AsyncVectorEnv`` exchanges one message per env). Sub-env ``i`` of ``reset(seed=s)``
is still the single env of seed ``s + i``; observations, rewards, ``terminated``, ``truncated``
and ``info`` (each key an array over the N envs with its ``_key`` mask) are those of one
``DeckLandingVectorEnv`` of N envs. Workers are started with the ``spawn`` method (a physics
client does not survive a fork); an error in a worker is raised in the parent with its traceback.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int
from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.wrappers.vector import (
    check_actions,
    check_env_mask,
    env_seeds,
    resolve_batch,
    split_reset_mask,
)

#: Largest number of worker processes.
MAX_WORKERS = 64
#: Seconds to wait for a worker to start, answer or stop.
WORKER_TIMEOUT_S = 600.0


def _serve(conn: Connection, env_id: str, num_envs: int, options: dict[str, Any]) -> None:
    """A worker: one vector env of ``num_envs``, driven by ``(command, argument)`` messages."""
    from ihrcf_env.wrappers.vector import DeckLandingVectorEnv

    env = None
    try:
        env = DeckLandingVectorEnv(env_id, num_envs, **options)
        conn.send(("ok", (env.single_observation_space, env.single_action_space, env.metadata)))
        while True:
            command, arg = conn.recv()
            if command == "close":
                break
            try:
                if command == "step":
                    conn.send(("ok", env.step(arg)))
                elif command == "step_masked":
                    conn.send(("ok", env.step_masked(*arg)))
                elif command == "reset":
                    conn.send(("ok", env.reset(seed=arg[0], options=arg[1])))
                else:
                    conn.send(("error", f"unknown command {command!r}"))
            except Exception:
                conn.send(("error", traceback.format_exc()))
    except Exception:
        conn.send(("error", traceback.format_exc()))
    finally:
        if env is not None:
            env.close()
        conn.close()


def merge_infos(parts: Sequence[dict[str, Any]], sizes: Sequence[int]) -> dict[str, Any]:
    """The ``info`` of the concatenated envs from each part's vector ``info`` (part ``k`` over
    ``sizes[k]`` envs): every key an array over all the envs; where a part lacks a key, its envs
    hold the array's zero (``None`` for objects; arrays per env, such as ``final_obs``, keep their
    shape) with the ``_key`` mask False."""
    keys: list[str] = []
    for part in parts:
        keys.extend(k for k in part if k not in keys)
    out: dict[str, Any] = {}
    for key in keys:
        values = [part.get(key) for part in parts]
        if any(isinstance(v, dict) for v in values):
            out[key] = merge_infos([v if isinstance(v, dict) else {} for v in values], sizes)
            continue
        present = [np.asarray(v) for v in values if v is not None]
        dtype = np.result_type(*present) if present else np.dtype(object)
        per_env = present[0].shape[1:] if present else ()  # the shape of one env's value
        filled = []
        for v, n in zip(values, sizes, strict=True):
            if v is not None:
                filled.append(np.asarray(v))
            elif key.startswith("_"):
                filled.append(np.zeros(n, dtype=bool))
            else:
                filled.append(
                    np.full((n, *per_env), None, dtype=object)
                    if dtype.kind == "O"
                    else np.zeros((n, *per_env), dtype=dtype)
                )
        out[key] = np.concatenate(filled)
    return out


class WorkerVectorEnv(VectorEnv):
    """``num_envs`` envs of ``env_id`` over ``workers`` processes (module docstring); ``options``
    as for ``gym.make`` (and ``autoreset_mode``)."""

    def __init__(self, env_id: str, num_envs: int, workers: int, **options: Any) -> None:
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        self._closed_workers = True
        n = check_int("num_envs", num_envs, low=1)
        k = check_int("workers", workers, low=1, high=min(n, MAX_WORKERS))
        self.sizes = [n // k + (1 if i < n % k else 0) for i in range(k)]
        # as one vector env of N envs decides it
        options = {**options, "batch_estimators": resolve_batch(n, options.get("batch_estimators"), options)}
        self.offsets = np.cumsum([0, *self.sizes])
        ctx = mp.get_context("spawn")
        try:
            for size in self.sizes:
                parent, child = ctx.Pipe()
                proc = ctx.Process(target=_serve, args=(child, env_id, size, dict(options)), daemon=True)
                with one_blas_thread():
                    proc.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(proc)
            self._closed_workers = False
            first = [self._receive(i) for i in range(k)][0]
        except BaseException:
            self.close_extras()
            raise
        obs_space, act_space, metadata = first
        self.env_id = env_id
        self.num_envs = n
        self.workers = k
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = batch_space(obs_space, n)
        self.action_space = batch_space(act_space, n)
        self.metadata = metadata
        self.autoreset_mode: AutoresetMode = metadata["autoreset_mode"]
        self.spec = gym.spec(env_id)
        #: every env's last observation (the rows a partial reset leaves)
        self._obs: NDArray[Any] | None = None

    def _receive(self, i: int) -> Any:
        conn = self._conns[i]
        if not conn.poll(WORKER_TIMEOUT_S):
            raise RuntimeError(f"vector env worker {i} did not answer within {WORKER_TIMEOUT_S:g} s")
        status, payload = conn.recv()
        if status != "ok":
            raise RuntimeError(f"vector env worker {i} failed:\n{payload}")
        return payload

    def _check_open(self) -> None:
        if self._closed_workers:
            raise RuntimeError("vector env is closed (close() was called): make a new one with gym.make_vec")

    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every env (``reset(seed=s)``: env ``i`` with seed ``s + i``), or with
        ``options["reset_mask"]`` the envs it marks only (as
        :meth:`~ihrcf_env.wrappers.vector.DeckLandingVectorEnv.reset`)."""
        self._check_open()
        off = self.offsets
        each = env_seeds(seed, self.num_envs)
        mask, rest = split_reset_mask(options, self.num_envs)
        if mask is not None and self._obs is None:
            raise gym.error.ResetNeeded("options['reset_mask']: reset every env once first")
        asked = []
        for i, conn in enumerate(self._conns):
            part = each[off[i] : off[i + 1]]
            seeds = None if all(x is None for x in part) else part
            if mask is None:
                conn.send(("reset", (seeds, options)))
            elif mask[off[i] : off[i + 1]].any():
                conn.send(("reset", (seeds, {**(rest or {}), "reset_mask": mask[off[i] : off[i + 1]]})))
            else:
                continue
            asked.append(i)
        parts: list[Any] = [None] * self.workers
        for i in asked:
            parts[i] = self._receive(i)
        if mask is None:
            obs = np.concatenate([p[0] for p in parts])
        else:
            assert self._obs is not None
            obs = self._obs.copy()
            for i in asked:
                obs[off[i] : off[i + 1]] = parts[i][0]
        self._obs = obs
        return obs.copy(), merge_infos([{} if p is None else p[1] for p in parts], self.sizes)

    def step(
        self, actions: Any
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """Step every env with its row of ``actions`` (shape ``(num_envs, *single action shape)``)."""
        return self._step(actions, None)

    def step_masked(
        self, actions: Any, mask: Any
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """Step the envs ``mask`` marks only (as
        :meth:`~ihrcf_env.wrappers.vector.DeckLandingVectorEnv.step_masked`); a worker none of whose
        envs is marked is not asked."""
        return self._step(actions, check_env_mask("mask", mask, self.num_envs))

    def _step(
        self, actions: Any, mask: NDArray[np.bool_] | None
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        self._check_open()
        a = check_actions(actions, self.num_envs, self.single_action_space.shape)  # type: ignore[arg-type]
        if self._obs is None:
            raise gym.error.ResetNeeded("step: reset the vector env first")
        off = self.offsets
        asked = []
        for i, conn in enumerate(self._conns):
            rows = slice(off[i], off[i + 1])
            if mask is None:
                conn.send(("step", a[rows]))
            elif mask[rows].any():
                conn.send(("step_masked", (a[rows], mask[rows])))
            else:
                continue
            asked.append(i)
        n = self.num_envs
        obs = self._obs.copy()
        rewards = np.zeros(n, dtype=np.float64)
        terminated, truncated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.workers)]
        for i in asked:
            rows = slice(off[i], off[i + 1])
            obs[rows], rewards[rows], terminated[rows], truncated[rows], infos[i] = self._receive(i)
        self._obs = obs
        return obs.copy(), rewards, terminated, truncated, merge_infos(infos, self.sizes)

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the workers (each closes its envs' physics clients)."""
        self._closed_workers = True
        conns, procs = self._conns, self._procs
        self._conns, self._procs = [], []
        for conn in conns:
            try:
                conn.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for proc in procs:
            proc.join(timeout=30)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=5)
        for conn in conns:
            conn.close()
