"""The landing tasks as one Gymnasium vector env: ``gym.make_vec(id, num_envs=N)``.

:class:`DeckLandingVectorEnv` holds N envs of one registered id in this process (each with its own
physics client) and steps them together with Gymnasium 1.x semantics: batched observations,
rewards, ``terminated`` and ``truncated`` arrays, ``info`` as Gymnasium vector envs give it (each
key an array over the envs, with a boolean ``_key`` mask), and next-step autoreset (an env that
ended is reset by the following ``step``, which returns its first observation with reward 0;
``autoreset_mode=AutoresetMode.SAME_STEP`` resets it in the step that ends it instead, with its
last observation and info in ``info["final_obs"]`` / ``info["final_info"]``, as Gymnasium's
``SyncVectorEnv`` does).
From :data:`BATCH_FROM` envs on, their estimators run as one batch
(:mod:`ihrcf_env.wrappers.vector_obs`; ``batch_estimators=True`` / ``False`` forces it either way);
with ``physics="numpy"`` their worlds also advance as one batch. Sub-env ``i`` of
``reset(seed=s)`` is the single env reset with seed ``s + i``, made with ``batch_estimators`` as
the vector env decided it: it reproduces ``gym.make(id, batch_estimators=..., **options)`` step for
step, bit for bit. It is the ids' ``vector_entry_point`` (``gym.make_vec`` uses it unless
``vectorization_mode`` says otherwise).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from ihrcf_env.core.batch.pipeline import batchable_names
from ihrcf_env.core.checks import check_bool, check_int
from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.sim.batched.loop import advance
from ihrcf_env.wrappers.vector_info import stack_infos
from ihrcf_env.wrappers.vector_obs import batched_observations

#: Largest ``num_envs`` (each env holds a physics client).
MAX_ENVS = 1024
#: Fewest envs whose estimators run as one batch by default (below, a batch costs more than it saves).
BATCH_FROM = 8
#: Options the vector env does not take (a GUI is one per process; the vector env does not render).
UNSUPPORTED_OPTIONS = ("render_mode",)


class DeckLandingVectorEnv(VectorEnv):
    """``num_envs`` envs of ``env_id`` with the ``options`` of ``gym.make`` (module docstring)."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        batch_estimators: bool | None = None,
        **options: Any,
    ) -> None:
        self._envs: list[gym.Env] = []
        n = check_int("num_envs", num_envs, low=1, high=MAX_ENVS)
        batch = resolve_batch(n, batch_estimators, options)
        modes = {m.value: m for m in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)}
        mode = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
        if mode not in modes:
            raise ValueError(
                f"autoreset_mode must be one of {sorted(modes)} (AutoresetMode.NEXT_STEP or SAME_STEP), "
                f"got {autoreset_mode!r}"
            )
        self.autoreset_mode = modes[mode]
        self.metadata = {**self.metadata, "autoreset_mode": self.autoreset_mode}
        bad = sorted(set(options) & set(UNSUPPORTED_OPTIONS))
        if bad:
            raise ValueError(f"{bad[0]}: not supported by the vector env (make single envs to render)")
        try:
            for _ in range(n):
                self._envs.append(gym.make(env_id, batch_estimators=batch, **options))
        except BaseException:
            self.close_extras()
            raise
        first = self._envs[0]
        self.env_id = env_id
        self.num_envs = n
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, n)
        self.action_space = batch_space(self.single_action_space, n)
        self.spec = first.spec
        self._autoreset = np.zeros(n, dtype=bool)
        self._closed_envs = False
        #: the task envs under the wrappers (their worlds advance together with numpy physics)
        self._tasks = task_envs(self._envs)
        self._numpy_physics = self._tasks[0].config.world.physics == "numpy"
        #: the batched observation stage (None: each env's own wrapper chain)
        self._batched = batched_observations(self._envs) if batch else None
        if batch and self._batched is None:
            self.close_extras()
            raise ValueError("batch_estimators: these envs' observation cannot be batched (see vector_obs)")
        self._was_reset = False
        #: each env's last observation (the rows a partial reset leaves)
        self._obs: list[Any] = [None] * n

    @property
    def batch_estimators(self) -> bool:
        """True when the envs' estimators run as one batch (False: each env's own)."""
        return self._batched is not None

    @property
    def envs(self) -> tuple[gym.Env, ...]:
        """The sub-envs (read-only: step them through the vector env)."""
        return tuple(self._envs)

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
        self._was_reset = True
        return self._reset_rows(np.arange(self.num_envs), seeds, options)

    def _reset_rows(
        self, rows: NDArray[np.intp], seeds: list[int | None], options: dict[str, Any] | None
    ) -> tuple[NDArray[Any], dict[str, Any]]:
        """Reset the envs of ``rows`` (env ``i`` with ``seeds[i]``); every env's observation."""
        n = self.num_envs
        self._autoreset[rows] = False
        infos: list[dict[str, Any] | None] = [None] * n
        if self._batched is not None:
            done = self._batched.run(None, [], rows, seeds, options)
            for i in rows:
                self._obs[i], infos[i] = done[int(i)].obs, done[int(i)].info
        else:
            for i in rows:
                self._obs[i], infos[i] = self._envs[i].reset(seed=seeds[i], options=options)
        return np.stack(self._obs), stack_infos(infos)

    def step(
        self, actions: Any
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """Step every env with its row of ``actions`` (shape ``(num_envs, *single action shape)``);
        an env that ended at the previous step is reset instead (next-step autoreset)."""
        return self._step(actions, None)

    def step_masked(
        self, actions: Any, mask: Any
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """:meth:`step` of the envs ``mask`` marks only (a numpy bool array over the envs, as
        ``options["reset_mask"]``; ``actions`` still one row per env): the others are neither
        stepped nor autoreset (a pending autoreset waits for their next step), their row of the
        observations is their last one, their reward 0, ``terminated`` and ``truncated`` False and
        ``info`` has no entries for them. A paused env goes on as if it had not been paused, so an
        env with nothing left to fly costs nothing."""
        m = check_env_mask("mask", mask, self.num_envs)
        return self._step(actions, m)

    def _step(
        self, actions: Any, mask: NDArray[np.bool_] | None
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        self._check_open()
        a = check_actions(actions, self.num_envs, self.single_action_space.shape)  # type: ignore[arg-type]
        n = self.num_envs
        live = np.ones(n, dtype=bool) if mask is None else mask
        rewards = np.zeros(n, dtype=np.float64)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        if not self._was_reset:
            raise gym.error.ResetNeeded("step: reset the vector env first")
        if self._numpy_physics:
            self._advance_together(a, live)
        same_step = self.autoreset_mode == AutoresetMode.SAME_STEP
        if self._batched is not None:
            return self._step_batched(a, same_step, live)
        obs = list(self._obs)
        infos: list[dict[str, Any] | None] = [None] * n
        for i in np.flatnonzero(live):
            env = self._envs[i]
            final: dict[str, Any] = {}
            if self._autoreset[i]:
                o, info = env.reset()
            else:
                o, r, terminated[i], truncated[i], info = env.step(a[i])
                rewards[i] = float(r)
                if same_step and (terminated[i] or truncated[i]):
                    final = {"final_obs": o, "final_info": info}
                    o, info = env.reset()
            obs[i] = o
            infos[i] = {**final, **info} if final else info
        self._autoreset[live] = (terminated | truncated)[live] & (not same_step)
        self._obs = obs
        return np.stack(obs), rewards, terminated, truncated, stack_infos(infos)

    def _step_batched(
        self, a: NDArray[Any], same_step: bool, live: NDArray[np.bool_]
    ) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """:meth:`step` through the batched observation stage (one estimator update per phase)."""
        assert self._batched is not None
        n = self.num_envs
        rows = self._batched.run(
            a, np.flatnonzero(live & ~self._autoreset), np.flatnonzero(live & self._autoreset)
        )
        terminated, truncated = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        rewards = np.zeros(n, dtype=np.float64)
        for i, row in rows.items():
            terminated[i], truncated[i], rewards[i] = row.terminated, row.truncated, row.reward
        ended = np.flatnonzero(terminated | truncated)
        final: dict[int, Any] = {}
        if same_step and ended.size:
            final = self._batched.run(None, [], ended)
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

    def _advance_together(self, actions: NDArray[Any], live: NDArray[np.bool_]) -> None:
        """Numpy physics: apply the actions of the envs that step now (``live`` and not autoreset)
        and advance all their worlds in one batched physics step; each env's own ``step`` then
        takes its world's result."""
        rows = np.flatnonzero(live & ~self._autoreset)
        if rows.size == 0:
            return
        tasks = [self._tasks[i] for i in rows]
        for task, i in zip(tasks, rows, strict=True):
            task.apply_action(actions[i])
        worlds = [task.world for task in tasks]
        for world, touchdown in zip(worlds, advance(worlds), strict=True):
            world.mark_advanced(touchdown)

    def close_extras(self, **kwargs: Any) -> None:
        """Close every sub-env (their physics clients)."""
        envs, self._envs = self._envs, []
        for env in envs:
            env.close()
        self._closed_envs = True

    def _check_open(self) -> None:
        if getattr(self, "_closed_envs", True) or not self._envs:
            raise RuntimeError("vector env is closed (close() was called): make a new one with gym.make_vec")


def resolve_batch(n: int, batch_estimators: object, options: dict[str, Any]) -> bool:
    """Whether a vector env of ``n`` envs with these ``options`` runs its estimators as one batch:
    ``batch_estimators`` when given (a bool), else from :data:`BATCH_FROM` envs on when its
    estimators have a batched form (and the envs are not raw)."""
    if batch_estimators is not None:
        return check_bool("batch_estimators", batch_estimators)
    names = options.get("estimators", DEFAULT_ESTIMATORS)
    try:
        names = tuple(names)
    except TypeError:
        return False  # gym.make names the bad option
    return n >= BATCH_FROM and not options.get("raw", False) and batchable_names(names)


def env_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """The seed of each of ``n`` envs from a vector env's ``reset(seed=...)``: an int ``s`` gives
    ``s + i`` to env ``i``; a sequence gives one seed (or None) per env; None leaves all unseeded."""
    if seed is None:
        return [None] * n
    if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
        s = check_int("seed", seed, low=0, high=2**63 - n)
        return [s + i for i in range(n)]
    if isinstance(seed, Sequence) and not isinstance(seed, str):
        if len(seed) != n:
            raise ValueError(f"seed: a sequence of {n} seeds (one per env), got {len(seed)}")
        return [None if s is None else check_int(f"seed[{i}]", s, low=0) for i, s in enumerate(seed)]
    raise TypeError(f"seed must be an int >= 0, a sequence of {n} of them or None, got {seed!r}")


def split_reset_mask(
    options: dict[str, Any] | None, n: int
) -> tuple[NDArray[np.bool_] | None, dict[str, Any] | None]:
    """``options["reset_mask"]`` checked (:func:`check_env_mask`) and the other options (None when
    none are left)."""
    if not options or "reset_mask" not in options:
        return None, options
    rest = {k: v for k, v in options.items() if k != "reset_mask"}
    return check_env_mask("options['reset_mask']", options["reset_mask"], n), rest or None


def check_env_mask(name: str, mask: Any, n: int) -> NDArray[np.bool_]:
    """A copy of ``mask``, checked to be a numpy bool array of shape ``(n,)`` marking at least one
    env (ValueError / TypeError naming ``name`` otherwise)."""
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
        raise TypeError(f"{name}: a numpy array of dtype bool, got {type(mask).__name__}")
    if mask.shape != (n,):
        raise ValueError(f"{name}: shape ({n},) (one flag per env), got {mask.shape}")
    if not mask.any():
        raise ValueError(f"{name}: marks no env (at least one True)")
    return mask.copy()


def check_actions(actions: Any, n: int, shape: tuple[int, ...]) -> NDArray[Any]:
    """``actions`` as an array of shape ``(n, *shape)`` of real numbers (ValueError / TypeError
    naming ``actions`` otherwise)."""
    a = np.asarray(actions)
    want = (n, *shape)
    if a.shape != want:
        raise ValueError(f"actions: shape {want} (num_envs, action), got {a.shape}")
    if a.dtype.kind not in "fiu":
        raise TypeError(f"actions: real numbers, got dtype {a.dtype}")
    return a


def task_envs(envs: Sequence[gym.Env]) -> list[DeckLandingEnv]:
    """The task env under each of ``envs``' wrappers. The vector env uses them for control only
    (the actions applied, the worlds advanced together); what the envs observe still flows
    through each env's own ``step``."""
    out = [env.unwrapped for env in envs]
    for env in out:
        if not isinstance(env, DeckLandingEnv):
            raise TypeError(f"the vector env steps DeckLandingEnv tasks, got {type(env).__name__}")
    return out  # type: ignore[return-value]


def vector_entry_point(env_id: str) -> Callable[..., DeckLandingVectorEnv]:
    """The ``vector_entry_point`` of ``env_id``: ``(num_envs, **options) -> DeckLandingVectorEnv``."""
    return functools.partial(DeckLandingVectorEnv, env_id)
