"""Labelled landing episodes for DAgger, flown by single envs in processes or by one vector env.

An :class:`Episode` is one episode from a chosen seed: its observations, the scripted landing's
label at every step (the expert running alongside on the same observations) and its outcome. The
pilot is the expert itself or a :class:`~ihrcf_env.control.gru_policy.GruPolicy` plus Gaussian
action noise drawn from a generator seeded by the episode's seed. Two flyers give the same list
for the same seeds:

* :class:`Pool`: ``workers`` processes, each with one single env and one expert (:func:`fly`);
* :class:`VectorFlyer`: one native vector env of ``num_envs`` envs (over ``workers`` processes),
  an expert per env; an env whose episode ends starts the next seed at once (a partial reset,
  ``options["reset_mask"]``), so no env idles while seeds are left.

Both fly several :class:`Flight` s (seeds with their pilot) as one queue
(:meth:`Pool.fly_all`): DAgger flies a round's validation and the next round's episodes, which
share a policy, together, so the flyers wait for the slowest episode once instead of twice.

Each episode of a :class:`VectorFlyer` is the one :func:`fly` gives in a single env made with the
vector env's options (its ``batch_estimators`` included), bit for bit. Neither needs PyTorch.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import multiprocessing as mp
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.control.gru_policy import GruPolicy
from ihrcf_env.control.policies import LANDING_CONFIGS, V1_LANDING_CONFIG, ScriptedLanding
from ihrcf_env.rl.envs import make_env
from ihrcf_env.wrappers.vector_info import unbatch_info


@dataclass
class Episode:
    """One flown episode: its observations (T, obs_size), the expert's labels (T, 4) in [-1, 1],
    whether it landed and its outcome."""

    seed: int
    obs: np.ndarray
    labels: np.ndarray
    success: bool
    outcome: str


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

    def jobs(self) -> list[tuple[int, GruPolicy | None, float, bool]]:
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


class Pool:
    """``workers`` processes flying episodes with :func:`fly` (``spawn``: no state shared)."""

    def __init__(self, env_id: str, env_kw: dict[str, Any], workers: int, commit_below: float) -> None:
        ctx = mp.get_context("spawn")
        self._ex = cf.ProcessPoolExecutor(
            workers, mp_context=ctx, initializer=init_worker, initargs=(env_id, env_kw, commit_below)
        )

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
class VectorFlyer:
    """Episodes flown in one vector env: ``gym.make_vec(env_id, num_envs, camera_model="projected",
    **env_kw)`` (over ``workers`` processes when > 1), one expert per env (module docstring)."""

    def __init__(
        self, env_id: str, env_kw: dict[str, Any], num_envs: int, workers: int, commit_below: float
    ) -> None:
        options = {"camera_model": "projected", **env_kw}
        if workers > 1:
            options["workers"] = workers
        probe = make_env(env_id, "projected", **env_kw)
        try:
            self._experts = [make_expert(probe, commit_below) for _ in range(num_envs)]
            self._size = int(probe.observation_space.shape[0])  # type: ignore[index]
        finally:
            probe.close()
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*is out of date", category=DeprecationWarning)
            self._vec: Any = gym.make_vec(env_id, num_envs=num_envs, **options)  # seeds as a list
        self.num_envs = num_envs

    def fly(
        self, seeds: Sequence[int], policy: GruPolicy | None, noise: float, label: bool = True
    ) -> list[Episode]:
        """Episodes from ``seeds`` (in order), as many at a time as the vector env has envs."""
        return self.fly_all([Flight.of(seeds, policy, noise, label)])[0]

    def fly_all(self, flights: Sequence[Flight]) -> list[list[Episode]]:
        """Every flight's episodes (one list per flight, in order), flown as one queue."""
        n, queue = self.num_envs, [job for f in flights for job in f.jobs()]
        if not queue:
            return [[] for _ in flights]
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
            obs, _, terminated, truncated, info = self._vec.step(actions)
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
        return _split(flights, [done[k] for k in range(len(queue))])

    def close(self) -> None:
        self._vec.close()
