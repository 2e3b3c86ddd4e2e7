"""The landing tasks' vector env over several processes: ``gym.make_vec(id, num_envs=N, workers=K)``.

:class:`WorkerVectorEnv` splits its N envs over K worker processes, each holding one
:class:`~ihrcf_env.vector.env.DeckLandingVectorEnv` of its share (the first ``N mod K`` workers
take one env more). A step sends each worker its rows of the actions and receives its batched
results: one message per worker and step, whatever N, so the processes' cores add up
(Gymnasium's ``AsyncVectorEnv`` exchanges one message per env). Sub-env ``i`` of ``reset(seed=s)``
is still the single env of seed ``s + i``; observations, rewards, ``terminated``, ``truncated``
and ``info`` (each key an array over the N envs with its ``_key`` mask) are those of one
``DeckLandingVectorEnv`` of N envs.

Everything given is checked in this process first, with the in-process env's own checks (the
options by ``make_config``, each step's actions whole), so a bad argument raises the error the
in-process env raises, before any worker starts or steps. Workers are started with the ``spawn``
method (a physics client does not survive a fork): they import the main script as
``__mp_main__``, so a component registered under ``if __name__ == "__main__":`` is unknown there
(register it at the top level of a module; the error says which). Every reply is read before an
error is raised: a worker that fails (:class:`WorkerError`, naming the worker and its env rows,
with its traceback) leaves the vector env usable after a full ``reset()``; a worker that stops,
dies or does not answer closes the vector env (the error says so).
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import traceback
from collections.abc import Sequence
from multiprocessing.connection import Connection
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

import ihrcf_env
from ihrcf_env.core.checks import check_int, describe
from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.vector.checks import (
    MAX_ENVS,
    check_actions,
    check_autoreset_mode,
    check_env_mask,
    check_options,
    env_seeds,
    split_reset_mask,
    time_limit,
)

__all__ = ["MAX_WORKERS", "WORKER_TIMEOUT_S", "WorkerError", "WorkerVectorEnv", "merge_infos"]

#: Largest number of worker processes.
MAX_WORKERS = 64
#: Seconds to wait for a worker to start or answer.
WORKER_TIMEOUT_S = 600.0
#: Seconds to wait for a worker to stop once asked.
_STOP_TIMEOUT_S = 30.0
#: The task of each id with a native vector env (its options are checked as ``make_config`` does).
_TASKS = {ihrcf_env.LANDING_V1_ID: "landing-v1", ihrcf_env.LANDING_V2_ID: "landing-v2"}

StepReturn = tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]


class WorkerError(RuntimeError):
    """A worker process of a :class:`WorkerVectorEnv` failed or stopped; the message names the
    worker (its index and env rows) and says whether the vector env is still usable. The worker's
    own exception, when it could be sent back, is the ``__cause__``."""


def registered_components() -> dict[str, tuple[str, ...]]:
    """The names of the registered user components, by kind (estimator, sensor, noise model, fault)."""
    from ihrcf_env.core.estimators.registry import ESTIMATORS
    from ihrcf_env.sim.registry import FAULTS, NOISE_MODELS, SENSORS

    return {
        "estimator": tuple(sorted(ESTIMATORS)),
        "sensor": tuple(sorted(SENSORS)),
        "noise model": tuple(sorted(NOISE_MODELS)),
        "fault": tuple(sorted(FAULTS)),
    }


def unregistered_note(parent: dict[str, tuple[str, ...]]) -> str:
    """What this process lacks of the components registered in the parent (``parent``: by kind),
    as a sentence with the fix; "" when it lacks none."""
    own = registered_components()
    missing = [
        f"{kind} {name!r}" for kind, names in parent.items() for name in names if name not in own[kind]
    ]
    if not missing:
        return ""
    return (
        f"{', '.join(missing)} registered in the main process but unknown in the worker processes: "
        "workers are started with 'spawn' and import the main script as '__mp_main__', so a "
        'registration under `if __name__ == "__main__":` does not run in them. Register it at '
        "import time of a module (the script's top level, or a module the script imports)."
    )


def _failure(exc: BaseException, note: str = "") -> tuple[str, str, bytes | None]:
    """A worker's error reply: a one-line summary, the traceback (with ``note`` first) and the
    exception pickled (None if it does not pickle)."""
    try:
        blob: bytes | None = pickle.dumps(exc)
    except Exception:
        blob = None
    summary = f"{type(exc).__name__}: {exc}"
    text = traceback.format_exc()
    return (f"{note}\n{summary}" if note else summary), text, blob


def _serve(
    conn: Connection,
    env_id: str,
    num_envs: int,
    options: dict[str, Any],
    parent_components: dict[str, tuple[str, ...]],
) -> None:
    """A worker: one vector env of ``num_envs``, driven by ``(command, argument)`` messages; each
    answered by ``("ok", result)`` or ``("error", (summary, traceback, pickled exception))``."""
    from ihrcf_env.vector.env import DeckLandingVectorEnv

    env = None
    try:
        try:
            env = DeckLandingVectorEnv(env_id, num_envs, **options)
        except Exception as e:
            conn.send(("error", _failure(e, unregistered_note(parent_components))))
            return
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
                    raise ValueError(f"unknown command {command!r}")
            except Exception as e:
                conn.send(("error", _failure(e)))
    except (EOFError, OSError, KeyboardInterrupt):
        pass  # the parent has gone (or stopped us): nothing left to answer
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


def check_shares(num_envs: object, workers: object) -> list[int]:
    """The envs of each worker (the first ``N mod K`` take one more), ``num_envs`` and ``workers``
    checked first (TypeError / ValueError naming them; each worker holds at most
    :data:`~ihrcf_env.vector.checks.MAX_ENVS`)."""
    n = check_int("num_envs", num_envs, low=1)
    k = check_int("workers", workers, low=1, high=MAX_WORKERS)
    if n > MAX_ENVS * k:
        raise ValueError(
            f"num_envs must be an integer in [1, {MAX_ENVS * k}] ({MAX_ENVS} envs per worker process, "
            f"{k} workers), got {describe(num_envs)}"
        )
    if k > n:
        raise ValueError(f"workers must be an integer in [1, num_envs = {n}], got {describe(workers)}")
    return [n // k + (1 if i < n % k else 0) for i in range(k)]


def check_env_options(env_id: str, options: dict[str, Any]) -> None:
    """The options checked as the in-process env checks them (``make_config`` of the id's task:
    the same error class and message), without building an env."""
    task = _TASKS.get(env_id)
    if task is not None:
        ihrcf_env.make_config(task=task, **options)


class WorkerVectorEnv(VectorEnv):
    """``num_envs`` envs of ``env_id`` over ``workers`` processes (module docstring); ``options``
    as for ``gym.make`` (and ``autoreset_mode``, ``max_episode_steps``)."""

    def __init__(
        self,
        env_id: str,
        num_envs: int,
        workers: int,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        disable_env_checker: bool | None = None,
        **options: Any,
    ) -> None:
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        self._closed_workers = True
        self._closed_because = "close() was called"
        self.sizes = check_shares(num_envs, workers)
        n, k = sum(self.sizes), len(self.sizes)
        # the in-process env's checks, here, before any worker starts
        mode = check_autoreset_mode(autoreset_mode)
        #: the episodes' step limit (None: none)
        self.max_episode_steps = time_limit(env_id, max_episode_steps)
        check_options(options)
        check_env_options(env_id, options)
        worker_options = {
            **options,
            "autoreset_mode": mode,
            "max_episode_steps": -1 if self.max_episode_steps is None else self.max_episode_steps,
        }
        self.offsets = np.cumsum([0, *self.sizes])
        self.env_id = env_id
        self.num_envs = n
        self.workers = k
        components = registered_components()
        ctx = mp.get_context("spawn")
        self._closed_workers = False
        try:
            for size in self.sizes:
                parent, child = ctx.Pipe()
                proc = ctx.Process(
                    target=_serve, args=(child, env_id, size, dict(worker_options), components), daemon=True
                )
                with one_blas_thread():
                    proc.start()
                child.close()
                self._conns.append(parent)
                self._procs.append(proc)
            first = self._gather(range(k), starting=True)[0]
        except BaseException:
            self.close_extras()
            raise
        obs_space, act_space, metadata = first
        self.single_observation_space = obs_space
        self.single_action_space = act_space
        self.observation_space = batch_space(obs_space, n)
        self.action_space = batch_space(act_space, n)
        self.metadata = metadata
        self.autoreset_mode: AutoresetMode = metadata["autoreset_mode"]
        self.spec = gym.spec(env_id)
        #: every env's last observation (the rows a partial reset leaves; None: a reset is needed)
        self._obs: NDArray[Any] | None = None

    @property
    def pids(self) -> tuple[int, ...]:
        """The worker processes' ids, worker by worker (empty once closed)."""
        return tuple(int(p.pid) for p in self._procs)

    # -- messages -----------------------------------------------------------------------------
    def _who(self, i: int) -> str:
        a, b = int(self.offsets[i]), int(self.offsets[i + 1]) - 1
        rows = f"env {a}" if a == b else f"envs {a}-{b}"
        return f"worker {i} (pid {self._procs[i].pid}, {rows})"

    def _send(self, messages: dict[int, tuple[str, Any]]) -> dict[int, Any]:
        """Send each worker of ``messages`` its message; every reply (see :meth:`_gather`)."""
        sent, lost = [], []
        for i, message in messages.items():
            try:
                self._conns[i].send(message)
                sent.append(i)
            except (OSError, EOFError, ValueError):
                lost.append(i)
        return self._gather(sent, lost=lost)

    def _gather(
        self, asked: Sequence[int], lost: Sequence[int] = (), starting: bool = False
    ) -> dict[int, Any]:
        """Every reply of the workers ``asked`` (worker -> result), all read before an error is
        raised: a worker that stopped or did not answer (or is in ``lost``) closes the vector env
        (:class:`WorkerError` saying so); a worker's error is raised as a :class:`WorkerError`
        naming every worker that failed, and a full reset is needed before the next step."""
        replies: dict[int, Any] = {}
        errors: dict[int, tuple[str, str, bytes | None]] = {}
        gone: dict[int, str] = {i: "stopped (its pipe is closed)" for i in lost}
        for i in asked:
            conn = self._conns[i]
            try:
                if not conn.poll(WORKER_TIMEOUT_S):
                    gone[i] = f"did not answer within {WORKER_TIMEOUT_S:g} s"
                    continue
                status, payload = conn.recv()
            except (OSError, EOFError):
                gone[i] = "stopped"
                continue
            if status == "ok":
                replies[i] = payload
            else:
                errors[i] = payload
        if gone:
            whom = "; ".join(f"{self._who(i)} {why}{self._exit_text(i)}" for i, why in sorted(gone.items()))
            self._closed_because = f"a worker process stopped ({whom})"
            self.close_extras()
            raise WorkerError(
                f"vector env {whom}: the vector env is closed, make a new one with gym.make_vec"
            )
        if errors:
            error = self._error(errors, starting)
            if starting:
                self._closed_because = "a worker process failed to start"
                self.close_extras()
            self._obs = None
            raise error
        return replies

    def _exit_text(self, i: int) -> str:
        proc = self._procs[i]
        proc.join(timeout=1.0)
        return "" if proc.exitcode is None else f" (exit code {proc.exitcode})"

    def _error(self, errors: dict[int, tuple[str, str, bytes | None]], starting: bool) -> WorkerError:
        after = (
            "the vector env is closed"
            if starting
            else "the vector env needs a full reset() before its next step"
        )
        parts = [f"{self._who(i)} failed: {summary}" for i, (summary, _, _) in sorted(errors.items())]
        first = min(errors)
        text = f"vector env {'; '.join(parts)} ({after})\n\nthe worker's traceback:\n{errors[first][1]}"
        error = WorkerError(text)
        blob = errors[first][2]
        if blob is not None:
            try:
                error.__cause__ = pickle.loads(blob)
            except Exception:
                pass
        return error

    def _check_open(self) -> None:
        if self._closed_workers:
            raise RuntimeError(
                f"vector env is closed ({self._closed_because}): make a new one with gym.make_vec"
            )

    # -- the vector env API -------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every env (``reset(seed=s)``: env ``i`` with seed ``s + i``), or with
        ``options["reset_mask"]`` the envs it marks only (as
        :meth:`~ihrcf_env.vector.env.DeckLandingVectorEnv.reset`)."""
        self._check_open()
        off = self.offsets
        each = env_seeds(seed, self.num_envs)
        mask, rest = split_reset_mask(options, self.num_envs)
        if mask is not None and self._obs is None:
            raise gym.error.ResetNeeded("options['reset_mask']: reset every env once first")
        messages: dict[int, tuple[str, Any]] = {}
        for i in range(self.workers):
            part = each[off[i] : off[i + 1]]
            seeds = None if all(x is None for x in part) else part
            if mask is None:
                messages[i] = ("reset", (seeds, options))
            elif mask[off[i] : off[i + 1]].any():
                messages[i] = ("reset", (seeds, {**(rest or {}), "reset_mask": mask[off[i] : off[i + 1]]}))
        parts = self._send(messages)
        if mask is None:
            obs = np.concatenate([parts[i][0] for i in range(self.workers)])
        else:
            assert self._obs is not None
            obs = self._obs.copy()
            for i in parts:
                obs[off[i] : off[i + 1]] = parts[i][0]
        self._obs = obs
        return obs.copy(), merge_infos(
            [parts[i][1] if i in parts else {} for i in range(self.workers)], self.sizes
        )

    def step(self, actions: Any) -> StepReturn:
        """Step every env with its row of ``actions`` (shape ``(num_envs, *single action shape)``)."""
        return self._step(actions, None)

    def step_masked(self, actions: Any, mask: Any) -> StepReturn:
        """Step the envs ``mask`` marks only (as
        :meth:`~ihrcf_env.vector.env.DeckLandingVectorEnv.step_masked`); a worker none of whose
        envs is marked is not asked."""
        self._check_open()
        return self._step(actions, check_env_mask("mask", mask, self.num_envs))

    def _step(self, actions: Any, mask: NDArray[np.bool_] | None) -> StepReturn:
        self._check_open()
        a = check_actions(actions, self.num_envs, self.single_action_space.shape)  # type: ignore[arg-type]
        if self._obs is None:
            raise gym.error.ResetNeeded("step: reset the vector env first")
        off = self.offsets
        messages: dict[int, tuple[str, Any]] = {}
        for i in range(self.workers):
            rows = slice(off[i], off[i + 1])
            if mask is None:
                messages[i] = ("step", a[rows])
            elif mask[rows].any():
                messages[i] = ("step_masked", (a[rows], mask[rows]))
        replies = self._send(messages)
        n = self.num_envs
        obs = self._obs.copy()
        rewards = np.zeros(n, dtype=np.float64)
        terminated, truncated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.workers)]
        for i, reply in replies.items():
            rows = slice(off[i], off[i + 1])
            obs[rows], rewards[rows], terminated[rows], truncated[rows], infos[i] = reply
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
            except (OSError, EOFError, ValueError):
                pass
        for proc in procs:
            proc.join(timeout=_STOP_TIMEOUT_S)
            if proc.is_alive():
                proc.terminate()
                proc.join(timeout=5)
            if proc.is_alive():
                proc.kill()
                proc.join(timeout=5)
        for conn in conns:
            conn.close()
        for proc in procs:
            if not proc.is_alive():
                proc.close()
