"""The observation stage of the vector env with the estimators of its N envs evaluated together.

:class:`BatchedObservations` steps N landing envs made by ``gym.make`` (``TimeLimit`` >
``OrderEnforcing`` > ``PassiveEnvChecker`` > :class:`~ihrcf_env.wrappers.landing_obs.LandingObservation`
> task env) in two halves: each env's raw step (:meth:`LandingObservation.step_raw`, the time
limit counted here as ``TimeLimit`` counts it), then one
:class:`~ihrcf_env.core.batch.pipeline.BatchDeckPoseEstimator` update for the frames of all of
them, then each env's flat observation (:meth:`LandingObservation.complete`). Row i equals the
single env ``gym.make(id, **options)`` to floating-point rounding (the batched IHRCF and fused
filter; ATDA is cv2's per frame). :func:`batched_observations` returns None where this does not
apply (raw envs, estimators without a batched form, other wrappers): the vector env then steps
each env's own wrapper chain.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker, TimeLimit
from numpy.typing import NDArray

from ihrcf_env.core.batch.pipeline import BatchDeckPoseEstimator, batchable
from ihrcf_env.core.estimators.base import SensorFrame
from ihrcf_env.wrappers.landing_obs import LandingObservation

#: Wrappers ``gym.make`` puts above the observation wrapper that the batched stage stands in for.
_OUTER = (TimeLimit, OrderEnforcing, PassiveEnvChecker)


class Row(NamedTuple):
    """One env's results of a vector step (a reset: reward 0, not ended)."""

    obs: NDArray[np.float32]
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]


def _chain(env: gym.Env) -> tuple[LandingObservation, int | None] | None:
    """The observation wrapper under ``env``'s outer wrappers and the time limit (steps, None:
    none), or None when the chain holds anything else."""
    limit: int | None = None
    while isinstance(env, _OUTER):
        if isinstance(env, TimeLimit):
            limit = env._max_episode_steps
        env = env.env
    return (env, limit) if isinstance(env, LandingObservation) else None


def batched_observations(envs: Sequence[gym.Env]) -> BatchedObservations | None:
    """The batched observation stage of ``envs`` (all made by ``gym.make`` of one id with the
    same options), or None when it does not apply (module docstring)."""
    chains = [_chain(e) for e in envs]
    if not chains or any(c is None for c in chains):
        return None
    wrappers = [c[0] for c in chains if c is not None]
    if not all(batchable(w.stage.sources) for w in wrappers):
        return None
    limits = {c[1] for c in chains if c is not None}
    return BatchedObservations(wrappers, limits.pop() if len(limits) == 1 else None)


class BatchedObservations:
    """N observation wrappers whose estimators run as one batch (module docstring).

    Args:
        wrappers: the envs' :class:`LandingObservation` s (same estimators and calibration).
        max_episode_steps: the time limit of every env (None: none).
    """

    def __init__(self, wrappers: Sequence[LandingObservation], max_episode_steps: int | None) -> None:
        self.wrappers = list(wrappers)
        self.n = len(self.wrappers)
        stage = self.wrappers[0].stage
        self.estimators = BatchDeckPoseEstimator(self.n, stage.estimator.config, stage.estimator.names)
        self.max_episode_steps = max_episode_steps
        self.elapsed = np.zeros(self.n, dtype=np.int64)
        self._motion = self.wrappers[0].deck_motion

    def run(
        self,
        actions: NDArray[Any] | None,
        step_rows: Iterable[int],
        reset_rows: Iterable[int],
        seeds: Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> dict[int, Row]:
        """Step the envs of ``step_rows`` (row i with ``actions[i]``) and reset those of
        ``reset_rows`` (with ``seeds[i]`` and ``options``); one estimator update for all of them.
        Returns row -> :class:`Row`."""
        raws: dict[int, tuple[dict[str, Any], float, bool, bool, dict[str, Any]]] = {}
        reset_rows = [int(i) for i in reset_rows]
        for i in (int(i) for i in step_rows):
            assert actions is not None
            raw, reward, terminated, truncated, info = self.wrappers[i].step_raw(actions[i])
            self.elapsed[i] += 1
            if self.max_episode_steps is not None and self.elapsed[i] >= self.max_episode_steps:
                truncated = True
            raws[i] = (raw, reward, bool(terminated), bool(truncated), info)
        if reset_rows:
            mask = np.zeros(self.n, dtype=bool)
            mask[reset_rows] = True
            self.estimators.reset(mask)
        for i in reset_rows:
            seed = None if seeds is None else seeds[i]
            raw, info = self.wrappers[i].reset_raw(seed=seed, options=options)
            self.elapsed[i] = 0
            raws[i] = (raw, 0.0, False, False, info)
        frames: list[SensorFrame | None] = [None] * self.n
        for i, (raw, *_rest) in raws.items():
            frames[i] = self.wrappers[i].stage.prepare(raw)
        estimates = self.estimators.update(frames)
        velocity, rate, defined = self.estimators.motion() if self._motion else (None, None, None)
        out: dict[int, Row] = {}
        for i in sorted(raws):
            raw, reward, terminated, truncated, info = raws[i]
            motion = None
            if defined is not None and defined[i]:
                assert velocity is not None and rate is not None
                motion = (velocity[i].copy(), rate[i].copy())
            obs = self.wrappers[i].complete(raw, info, estimates[i], motion)
            out[i] = Row(obs, reward, terminated, truncated, info)
        return out
