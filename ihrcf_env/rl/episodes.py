"""Labelled landing episodes for DAgger, flown by single envs in processes or by one vector env.

An :class:`Episode` is one episode from a chosen seed: its observations, the scripted landing's
label at every step (the expert running alongside on the same observations) and its outcome. The
pilot is the expert itself or a :class:`~ihrcf_env.control.gru_policy.GruPolicy` plus Gaussian
action noise drawn from a generator seeded by the episode's seed. Two flyers give the same list
for the same seeds:

* :class:`Pool`: ``workers`` processes, each with one single env and one expert (:func:`fly`);
* :class:`VectorFlyer`: a native vector env of ``num_envs`` envs, or one of ``num_envs // workers``
  envs in each of ``workers`` processes, with an expert and a pilot per env in the same process;
  an env whose episode ends starts its process's next seed at once (a partial reset,
  ``options["reset_mask"]``), and one with no seed left pauses (``step_masked``) instead of
  stepping with the others.

Both fly several :class:`Flight` s (seeds with their pilot) as one queue
(:meth:`Pool.fly_all`): DAgger flies a round's validation and the next round's episodes, which
share a policy, together, so the flyers wait for the slowest episode once instead of twice.

Each episode of a :class:`VectorFlyer` is the one :func:`fly` gives in a single env made with the
vector env's options, bit for bit. Neither needs PyTorch.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import multiprocessing as mp
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env._warnings import older_version_allowed
from ihrcf_env.control.gru_policy import GruPolicy
from ihrcf_env.control.policies import LANDING_CONFIGS, V1_LANDING_CONFIG, ScriptedLanding
from ihrcf_env.core.checks import check_int
from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.rl.envs import make_env
from ihrcf_env.vector.checks import MAX_ENVS
from ihrcf_env.vector.info import unbatch_info


@dataclass
class Episode:
    """One flown episode: its observations (T, obs_size), the expert's labels (T, 4) in [-1, 1],
    whether it landed and its outcome."""

    seed: int
    obs: np.ndarray
    labels: np.ndarray
    success: bool
    outcome: str


#: One episode to fly: (seed, policy or None for the expert, noise, label).
Job = tuple[int, GruPolicy | None, float, bool]


@dataclass(frozen=True)
class Flight:
    """Episodes to fly: ``seeds``, each piloted by ``policy`` (None: the expert) plus Gaussian
    ``noise`` (action units), labelled by the expert when ``label``."""

    seeds: tuple[int, ...]
    policy: GruPolicy | None
    noise: float = 0.0
    label: bool = True

    @classmethod
    def of(cls, seeds: Sequence[int], policy: GruPolicy | None, noise: float, label: bool = True) -> Flight:
        return cls(tuple(int(s) for s in seeds), policy, float(noise), bool(label))

    def jobs(self) -> list[Job]:
        """One (seed, policy, noise, label) per episode."""
        return [(s, self.policy, self.noise, self.label) for s in self.seeds]


def _split(flights: Sequence[Flight], episodes: list[Episode]) -> list[list[Episode]]:
    """``episodes`` (every flight's, in order) cut back into one list per flight."""
    out, k = [], 0
    for f in flights:
        out.append(episodes[k : k + len(f.seeds)])
        k += len(f.seeds)
    return out


def make_expert(env: Any, commit_below: float) -> ScriptedLanding:
    """The scripted landing for ``env`` (its task's tunables) committing below ``commit_below`` m."""
    task = str(getattr(env.unwrapped, "task_name", ""))
    config = dataclasses.replace(LANDING_CONFIGS.get(task, V1_LANDING_CONFIG), commit_below=commit_below)
    return ScriptedLanding.from_env(env, config=config)


def _pilot_action(
    obs: np.ndarray,
    target: np.ndarray | None,
    policy: GruPolicy | None,
    hidden: np.ndarray | None,
    noise: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray | None]:
    """The action flown at one step (float32, in [-1, 1]): the expert's ``target`` without a
    ``policy``, else the policy's (state ``hidden``) plus noise; and the policy's next state."""
    if policy is None or hidden is None:
        assert target is not None
        return target.astype(np.float32), hidden
    a, h = policy.step(np.asarray(obs, dtype=np.float64)[None], hidden[None])
    action = a[0].astype(np.float32)
    if noise > 0:
        action = action + noise * rng.standard_normal(action.shape)
    return np.clip(action, -1.0, 1.0).astype(np.float32), h[0]


def _episode(seed: int, obs: list[np.ndarray], labels: list[np.ndarray], size: int, info: Any) -> Episode:
    n = len(obs)
    return Episode(
        seed,
        np.stack(obs) if n else np.zeros((0, size), np.float32),
        np.stack(labels) if n else np.zeros((0, 4), np.float32),
        bool(info.get("is_success", False)),
        str(info.get("outcome", "")),
    )


# --- single envs in worker processes ------------------------------------------------------------
_WORKER: dict[str, Any] = {}


def init_worker(env_id: str, env_kw: dict[str, Any], commit_below: float) -> None:
    """This process's env (``make_env(env_id, "projected", **env_kw)``) and expert for :func:`fly`."""
    env = make_env(env_id, "projected", **env_kw)
    _WORKER["env"] = env
    _WORKER["expert"] = make_expert(env, commit_below)


def fly(seed: int, policy: GruPolicy | None, noise: float, label: bool = True) -> Episode:
    """Fly one episode from ``reset(seed=seed)`` in this process's env (:func:`init_worker`): the
    expert when ``policy`` is None, else ``policy`` plus Gaussian ``noise`` (action units; seeded by
    ``seed``). With ``label`` every step is labelled by the expert running alongside."""
    env, expert = _WORKER["env"], _WORKER["expert"]
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    expert.reset()
    hidden = None if policy is None else np.zeros(policy.hidden_size)
    observations, labels = [], []
    while True:
        target = None
        if label or policy is None:
            target = np.clip(expert.act(obs), -1.0, 1.0)
            if label:
                observations.append(np.asarray(obs, dtype=np.float32))
                labels.append(np.asarray(target, dtype=np.float32))
        action, hidden = _pilot_action(obs, target, policy, hidden, noise, rng)
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            return _episode(seed, observations, labels, env.observation_space.shape[0], info)


def _ready() -> None:
    """A task that does nothing: :func:`start_processes` waits for one per process."""


def start_processes(workers: int, initializer: Any, initargs: tuple[Any, ...]) -> cf.ProcessPoolExecutor:
    """``workers`` spawned processes (``initializer(*initargs)`` in each), all started now and with
    one BLAS thread each (:func:`~ihrcf_env.core.threads.one_blas_thread`)."""
    with one_blas_thread():
        ex = cf.ProcessPoolExecutor(
            workers, mp_context=mp.get_context("spawn"), initializer=initializer, initargs=initargs
        )
        try:
            for f in [ex.submit(_ready) for _ in range(workers)]:  # one process per task, started now
                f.result()
        except BaseException:
            ex.shutdown(cancel_futures=True)
            raise
    return ex


class Pool:
    """``workers`` processes flying episodes with :func:`fly` (``spawn``: no state shared)."""

    def __init__(self, env_id: str, env_kw: dict[str, Any], workers: int, commit_below: float) -> None:
        self._ex = start_processes(workers, init_worker, (env_id, env_kw, commit_below))

    def fly(
        self, seeds: Sequence[int], policy: GruPolicy | None, noise: float, label: bool = True
    ) -> list[Episode]:
        """Episodes from ``seeds`` (in order), flown in parallel."""
        return self.fly_all([Flight.of(seeds, policy, noise, label)])[0]

    def fly_all(self, flights: Sequence[Flight]) -> list[list[Episode]]:
        """Every flight's episodes (one list per flight, in order), flown as one queue."""
        futures = [self._ex.submit(fly, *job) for f in flights for job in f.jobs()]
        return _split(flights, [f.result() for f in futures])

    def close(self) -> None:
        self._ex.shutdown(cancel_futures=True)


# --- one vector env -----------------------------------------------------------------------------
class _VectorQueue:
    """A native vector env of ``num_envs`` envs in this process with an expert per env, flying
    queues of jobs."""

    def __init__(self, env_id: str, env_kw: dict[str, Any], num_envs: int, commit_below: float) -> None:
        probe = make_env(env_id, "projected", **env_kw)
        try:
            self._experts = [make_expert(probe, commit_below) for _ in range(num_envs)]
            self._size = int(probe.observation_space.shape[0])  # type: ignore[index]
        finally:
            probe.close()
        options = {"camera_model": "projected", **env_kw}
        with older_version_allowed():
            self._vec: Any = gym.make_vec(env_id, num_envs=num_envs, **options)  # seeds as a list
        self.num_envs = num_envs

    def fly_jobs(self, queue: Sequence[Job]) -> list[Episode]:
        """The episodes of ``queue``'s jobs, in order."""
        n = self.num_envs
        if not queue:
            return []
        done: dict[int, Episode] = {}
        slot: list[int | None] = [None] * n  # the index in ``queue`` each env flies
        rngs: list[np.random.Generator | None] = [None] * n
        hidden: list[np.ndarray | None] = [None] * n
        record: list[tuple[list[np.ndarray], list[np.ndarray]]] = [([], []) for _ in range(n)]
        nxt = 0

        def start(envs: Sequence[int]) -> list[int | None]:
            """Give ``envs`` the next jobs; their seeds for the reset (None: no job left)."""
            nonlocal nxt
            out: list[int | None] = [None] * n
            for i in envs:
                if nxt < len(queue):
                    seed, policy = queue[nxt][:2]
                    slot[i], out[i] = nxt, seed
                    rngs[i] = np.random.default_rng(seed)
                    hidden[i] = None if policy is None else np.zeros(policy.hidden_size)
                    record[i] = ([], [])
                    self._experts[i].reset()
                    nxt += 1
                else:
                    slot[i] = None
            return out

        obs, _ = self._vec.reset(seed=start(range(n)))
        while any(s is not None for s in slot):
            actions = np.zeros((n, 4), np.float32)  # envs without a job left fly zeros
            for i, k in enumerate(slot):
                if k is None:
                    continue
                _, policy, noise, label = queue[k]
                target = None
                if label or policy is None:
                    target = np.clip(self._experts[i].act(obs[i]), -1.0, 1.0)
                    if label:
                        record[i][0].append(np.asarray(obs[i], dtype=np.float32))
                        record[i][1].append(np.asarray(target, dtype=np.float32))
                rng = rngs[i]
                assert rng is not None
                actions[i], hidden[i] = _pilot_action(obs[i], target, policy, hidden[i], noise, rng)
            live = np.array([k is not None for k in slot])  # envs with nothing left to fly pause
            obs, _, terminated, truncated, info = self._vec.step_masked(actions, live)
            ended = [i for i in range(n) if slot[i] is not None and (terminated[i] or truncated[i])]
            for i in ended:
                k = slot[i]
                assert k is not None
                done[k] = _episode(queue[k][0], *record[i], self._size, unbatch_info(info, i))
            if ended:
                seeds_now = start(ended)
                again = np.array([i in ended and seeds_now[i] is not None for i in range(n)])
                if again.any():
                    obs, _ = self._vec.reset(seed=seeds_now, options={"reset_mask": again})
        return [done[k] for k in range(len(queue))]

    def close(self) -> None:
        self._vec.close()


def init_vector_worker(env_id: str, env_kw: dict[str, Any], num_envs: int, commit_below: float) -> None:
    """This process's vector env and experts for :func:`fly_share`."""
    _WORKER["queue"] = _VectorQueue(env_id, env_kw, num_envs, commit_below)


def fly_share(queue: Sequence[Job]) -> list[Episode]:
    """The episodes of ``queue`` flown by this process's vector env (:func:`init_vector_worker`)."""
    flyer: _VectorQueue = _WORKER["queue"]
    return flyer.fly_jobs(queue)


class VectorFlyer:
    """Episodes flown by native vector envs, an expert per env: one vector env of ``num_envs``
    envs in this process, or with ``workers`` > 1 one of ``num_envs // workers`` envs in each of
    ``workers`` processes, which fly every ``workers``-th job of a queue with their own experts and
    pilots (module docstring)."""

    def __init__(
        self, env_id: str, env_kw: dict[str, Any], num_envs: int, workers: int, commit_below: float
    ) -> None:
        n = check_int("num_envs", num_envs, low=1, high=MAX_ENVS)
        w = check_int("workers", workers, low=1, high=n)
        self.num_envs, self.workers = n, w
        self._local: _VectorQueue | None = None
        self._ex: cf.ProcessPoolExecutor | None = None
        if w == 1:
            self._local = _VectorQueue(env_id, env_kw, n, commit_below)
        else:
            self._ex = start_processes(w, init_vector_worker, (env_id, env_kw, n // w, commit_below))

    def fly(
        self, seeds: Sequence[int], policy: GruPolicy | None, noise: float, label: bool = True
    ) -> list[Episode]:
        """Episodes from ``seeds`` (in order), as many at a time as the vector envs have envs."""
        return self.fly_all([Flight.of(seeds, policy, noise, label)])[0]

    def fly_all(self, flights: Sequence[Flight]) -> list[list[Episode]]:
        """Every flight's episodes (one list per flight, in order), flown as one queue."""
        queue = [job for f in flights for job in f.jobs()]
        if self._local is not None:
            return _split(flights, self._local.fly_jobs(queue))
        assert self._ex is not None
        w = self.workers
        futures = [self._ex.submit(fly_share, queue[k::w]) for k in range(w)]
        shares = [f.result() for f in futures]
        return _split(flights, [shares[j % w][j // w] for j in range(len(queue))])

    def close(self) -> None:
        if self._local is not None:
            self._local.close()
        if self._ex is not None:
            self._ex.shutdown(cancel_futures=True)


__all__ = [
    "Episode",
    "Flight",
    "Job",
    "Pool",
    "VectorFlyer",
    "fly",
    "fly_share",
    "init_vector_worker",
    "init_worker",
    "make_expert",
    "start_processes",
]
