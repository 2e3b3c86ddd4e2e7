"""The landing tasks as one Gymnasium vector env: ``gym.make_vec(id, num_envs=N)``.

:class:`DeckLandingVectorEnv` holds N envs of one registered id in this process (each with its own
physics client) and steps them together with Gymnasium 1.x semantics: batched observations,
rewards, ``terminated`` and ``truncated`` arrays, ``info`` as Gymnasium vector envs give it (each
key an array over the envs, with a boolean ``_key`` mask), and next-step autoreset (an env that
ended is reset by the following ``step``, which returns its first observation with reward 0;
``autoreset_mode=AutoresetMode.SAME_STEP`` resets it in the step that ends it instead, with its
last observation and info in ``info["final_obs"]`` / ``info["final_info"]``, as Gymnasium's
``SyncVectorEnv`` does).

Each env is built by the id's entry point (the task env under its observation wrapper, or the
raw task); the vector env does what ``gym.make``'s wrappers would do itself: the time limit of
the id's spec (``max_episode_steps`` overrides it as in ``gym.make``: -1 for none), the order of
calls, the checks of its inputs (whole, before any env steps). A step runs in three phases: every
task's :meth:`~ihrcf_env.envs.deck_landing.DeckLandingEnv.begin_step` (the action handed over),
the worlds advanced one at a time (each its own PyBullet step), every task's
:meth:`~ihrcf_env.envs.deck_landing.DeckLandingEnv.end_step` (sensing, task rules, info); then the
observations, each env's through its own observation wrapper and estimators. Sub-env ``i`` of
``reset(seed=s)`` is the single env reset with seed ``s + i``: it reproduces
``gym.make(id, **options)`` step for step, bit for bit. (The batched path of the physics and the
estimators is the JAX backend, ``gym.make_vec(id, num_envs, backend="jax")``.)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import load_env_creator
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int
from ihrcf_env.envs.deck_landing import DeckLandingEnv
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
from ihrcf_env.vector.info import stack_infos
from ihrcf_env.wrappers.landing_obs import LandingObservation

__all__ = ["DeckLandingVectorEnv", "Row", "StepResult", "SubEnv", "build_env"]

StepReturn = tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]
#: One task's step results (the raw observation, reward, terminated, truncated, info), as
#: :meth:`~ihrcf_env.envs.deck_landing.DeckLandingEnv.end_step` returns them.
StepResult = tuple[dict[str, Any], float, bool, bool, dict[str, Any]]


class Row(NamedTuple):
    """One env's results of a vector step (a reset: reward 0, not ended)."""

    obs: NDArray[np.float32]
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]


class SubEnv(NamedTuple):
    """One env of a vector env: what the id's entry point returned (``env``), the task env it
    holds and its observation wrapper (None: a raw env, ``env`` is the task)."""

    env: gym.Env
    task: DeckLandingEnv
    wrapper: LandingObservation | None


def build_env(env_id: str, options: dict[str, Any]) -> SubEnv:
    """One env of ``env_id`` made by the id's entry point with the spec's kwargs and ``options``
    (as ``gym.make`` calls it, without its outer wrappers), split into its pieces."""
    spec = gym.spec(env_id)
    entry = spec.entry_point
    if entry is None:
        raise ValueError(f"{env_id}: registered without an entry point")
    creator = entry if callable(entry) else load_env_creator(entry)
    env = creator(**{**spec.kwargs, **options})
    if isinstance(env, LandingObservation) and isinstance(env.env, DeckLandingEnv):
        env.env.spec = spec  # as gym.make records it (the vector env keeps the step limit itself)
        return SubEnv(env, env.env, env)
    if isinstance(env, DeckLandingEnv):
        env.spec = spec
        return SubEnv(env, env, None)
    env.close()
    raise TypeError(
        f"{env_id}: the vector env steps DeckLandingEnv tasks (raw or under LandingObservation), got {env!r}"
    )


class DeckLandingVectorEnv(VectorEnv):
    """``num_envs`` envs of ``env_id`` with the ``options`` of ``gym.make`` (module docstring);
    ``max_episode_steps`` as ``gym.make`` takes it (None: the spec's; -1: no limit);
    ``disable_env_checker`` is taken and has no effect (the vector env checks its inputs itself)."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        max_episode_steps: int | None = None,
        disable_env_checker: bool | None = None,
        **options: Any,
    ) -> None:
        self._subs: list[SubEnv] = []
        self._closed_envs = True
        n = check_int("num_envs", num_envs, low=1, high=MAX_ENVS)
        self.autoreset_mode = check_autoreset_mode(autoreset_mode)
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        #: the episodes' step limit (None: none)
        self.max_episode_steps = time_limit(env_id, max_episode_steps)
        check_options(options)
        self._closed_envs = False
        try:
            self._subs.append(build_env(env_id, options))
            # the others share the first one's resolved config: validated and loaded once
            shared = {"config": self._subs[0].task.config}
            if "calibration" in options:
                shared["calibration"] = options["calibration"]
            for _ in range(n - 1):
                self._subs.append(build_env(env_id, shared))
        except BaseException:
            self.close_extras()
            raise
        first = self._subs[0].env
        self.env_id = env_id
        self.num_envs = n
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.spec = gym.spec(env_id)
        self._autoreset = np.zeros(n, dtype=bool)
        self._elapsed = np.zeros(n, dtype=np.int64)  # steps of each env's episode
        self._was_reset = False
        #: each env's last observation (the rows a partial reset leaves)
        self._obs: list[Any] = [None] * n

    @property
    def envs(self) -> tuple[gym.Env, ...]:
        """The sub-envs as the id's entry point made them (read-only: step them through the
        vector env)."""
        return tuple(s.env for s in self._subs)

    # -- reset --------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset every env (``reset(seed=s)``: env ``i`` with seed ``s + i``; ``options`` to each).

        ``options["reset_mask"]`` (a bool array over the envs, Gymnasium 1.1+'s partial reset)
        resets only the envs it marks, each with its seed as above; the others keep their episode
        and their row of the returned observations is their last one; ``info`` has the reset
        envs' entries only. The other options go to the envs reset."""
        self._check_open()
        seeds = env_seeds(seed, self.num_envs)
        mask, options = split_reset_mask(options, self.num_envs)
        if mask is not None:
            if not self._was_reset:
                raise gym.error.ResetNeeded("options['reset_mask']: reset every env once first")
            return self._reset_rows(np.flatnonzero(mask), seeds, options)
        obs, info = self._reset_rows(np.arange(self.num_envs), seeds, options)
        self._was_reset = True
        return obs, info

    def _reset_rows(
        self, rows: NDArray[np.intp], seeds: list[int | None], options: dict[str, Any] | None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset the envs of ``rows`` (env ``i`` with ``seeds[i]``); every env's observation."""
        done = self._observe({}, rows, seeds, options)
        infos: list[dict[str, Any] | None] = [None] * self.num_envs
        for i, row in done.items():
            self._obs[i], infos[i] = row.obs, row.info
        return np.stack(self._obs), stack_infos(infos)

    # -- step ---------------------------------------------------------------------------------
    def step(self, actions: Any) -> StepReturn:
        """Step every env with its row of ``actions`` (shape ``(num_envs, *single action shape)``);
        an env that ended at the previous step is reset instead (next-step autoreset)."""
        return self._step(actions, None)

    def step_masked(self, actions: Any, mask: Any) -> StepReturn:
        """:meth:`step` of the envs ``mask`` marks only (a numpy bool array over the envs, as
        ``options["reset_mask"]``; ``actions`` still one row per env, all checked): the others are
        neither stepped nor autoreset (a pending autoreset waits for their next step), their row of
        the observations is their last one, their reward 0, ``terminated`` and ``truncated`` False
        and ``info`` has no entries for them. A paused env goes on as if it had not been paused, so
        an env with nothing left to fly costs nothing."""
        self._check_open()
        m = check_env_mask("mask", mask, self.num_envs)
        return self._step(actions, m)

    def _step(self, actions: Any, mask: NDArray[np.bool_] | None) -> StepReturn:
        self._check_open()
        a = check_actions(actions, self.num_envs, self.single_action_space.shape)  # type: ignore[arg-type]
        if not self._was_reset:
            raise gym.error.ResetNeeded("step: reset the vector env first")
        n = self.num_envs
        live = np.ones(n, dtype=bool) if mask is None else mask
        stepping = np.flatnonzero(live & ~self._autoreset)
        rows = self._observe(self._advance(a, stepping), np.flatnonzero(live & self._autoreset))
        rewards = np.zeros(n, dtype=np.float64)
        terminated, truncated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        limit = self.max_episode_steps
        for i, row in rows.items():
            terminated[i], truncated[i], rewards[i] = row.terminated, row.truncated, row.reward
            if limit is not None and self._elapsed[i] >= limit:
                truncated[i] = True  # as gym.make's TimeLimit
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        ended = np.flatnonzero(terminated | truncated)
        final = self._observe({}, ended) if same_step and ended.size else {}
        obs = list(self._obs)
        infos: list[dict[str, Any] | None] = [None] * n
        for i, row in rows.items():
            if i in final:
                obs[i] = final[i].obs
                infos[i] = {"final_obs": row.obs, "final_info": row.info, **final[i].info}
            else:
                obs[i], infos[i] = row.obs, row.info
        self._autoreset[live] = (terminated | truncated)[live] & (not same_step)
        self._obs = obs
        return np.stack(obs), rewards, terminated, truncated, stack_infos(infos)

    def _advance(self, actions: NDArray[Any], rows: NDArray[np.intp]) -> dict[int, StepResult]:
        """Step the tasks of ``rows`` (row ``i`` with ``actions[i]``) in three phases: each task's
        ``begin_step``, the worlds advanced (``World.step``, one after the other), each task's
        ``end_step``. Returns row -> the task's step results."""
        if rows.size == 0:
            return {}
        tasks = [self._subs[i].task for i in rows]
        taken = [task.begin_step(actions[i]) for task, i in zip(tasks, rows, strict=True)]
        touchdowns = [task.world.step() for task in tasks]
        out: dict[int, StepResult] = {}
        for task, i, a, touchdown in zip(tasks, rows, taken, touchdowns, strict=True):
            out[int(i)] = task.end_step(a, touchdown)
            self._elapsed[i] += 1
        return out

    def _observe(
        self,
        stepped: dict[int, StepResult],
        reset_rows: NDArray[np.intp],
        seeds: Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> dict[int, Row]:
        """The observations of the envs whose tasks stepped (``stepped``) and of those of
        ``reset_rows``, reset here (env ``i`` with ``seeds[i]``, ``options``); row -> :class:`Row`."""
        self._elapsed[reset_rows] = 0
        self._autoreset[reset_rows] = False
        out: dict[int, Row] = {}
        for i, result in stepped.items():
            wrapper = self._subs[i].wrapper
            out[i] = Row(*(result if wrapper is None else wrapper.observe_step(*result)))
        for i in (int(i) for i in reset_rows):
            seed = None if seeds is None else seeds[i]
            obs, info = self._subs[i].env.reset(seed=seed, options=options)
            out[i] = Row(obs, 0.0, False, False, info)
        return out

    # -- closing ------------------------------------------------------------------------------
    def close_extras(self, **kwargs: Any) -> None:
        """Close every sub-env (their physics clients)."""
        subs, self._subs = self._subs, []
        self._closed_envs = True
        for sub in subs:
            sub.env.close()

    def _check_open(self) -> None:
        if self._closed_envs or not self._subs:
            raise RuntimeError("vector env is closed (close() was called): make a new one with gym.make_vec")
