"""The observation stage of the vector env with the estimators of its N envs evaluated together.

:class:`BatchedObservations` takes the results of N landing tasks' steps (the vector env steps the
tasks, :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`, itself) and their
:class:`~ihrcf_env.wrappers.landing_obs.LandingObservation` s in two halves: each wrapper takes its
env's raw step (:meth:`LandingObservation.take_step`), then one
:class:`~ihrcf_env.core.batch.pipeline.BatchDeckPoseEstimator` update for the frames of all of
them, then each env's flat observation (:meth:`LandingObservation.complete`). Row i equals the
single env ``gym.make(id, **options)`` to floating-point rounding (the batched IHRCF and fused
filter; ATDA is cv2's per frame). :func:`batched_observations` returns None where this does not
apply (raw envs, estimators without a batched form): the vector env then completes each env's
observation with its own wrapper.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch.pipeline import BatchDeckPoseEstimator, batchable
from ihrcf_env.core.estimators.base import SensorFrame
from ihrcf_env.wrappers.landing_obs import LandingObservation

__all__ = ["BatchedObservations", "Row", "StepResult", "batched_observations"]

#: A task env's step results: raw observation, reward, terminated, truncated, info.
StepResult = tuple[dict[str, Any], float, bool, bool, dict[str, Any]]


class Row(NamedTuple):
    """One env's results of a vector step (a reset: reward 0, not ended)."""

    obs: NDArray[np.float32]
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]


def batched_observations(wrappers: Sequence[LandingObservation | None]) -> BatchedObservations | None:
    """The batched observation stage of the envs whose observation wrappers are ``wrappers`` (all
    made by one id with the same options; None: a raw env), or None when it does not apply
    (module docstring)."""
    if not wrappers or any(w is None for w in wrappers):
        return None
    chains = [w for w in wrappers if w is not None]
    if not all(batchable(w.stage.sources) for w in chains):
        return None
    return BatchedObservations(chains)


class BatchedObservations:
    """N observation wrappers whose estimators run as one batch (module docstring).

    Args:
        wrappers: the envs' :class:`LandingObservation` s (same estimators and calibration).
    """

    def __init__(self, wrappers: Sequence[LandingObservation]) -> None:
        self.wrappers = list(wrappers)
        self.n = len(self.wrappers)
        stage = self.wrappers[0].stage
        self.estimators = BatchDeckPoseEstimator(self.n, stage.estimator.config, stage.estimator.names)
        self._motion = self.wrappers[0].deck_motion

    def run(
        self,
        stepped: Mapping[int, StepResult],
        reset_rows: Iterable[int],
        seeds: Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> dict[int, Row]:
        """The observations of the envs whose tasks stepped (``stepped``: row -> the task's step
        results) and of those of ``reset_rows``, reset here (with ``seeds[i]`` and ``options``);
        one estimator update for all of them. Returns row -> :class:`Row`."""
        raws: dict[int, StepResult] = {}
        reset_rows = [int(i) for i in reset_rows]
        for i, result in stepped.items():
            raws[int(i)] = self.wrappers[int(i)].take_step(*result)
        if reset_rows:
            mask = np.zeros(self.n, dtype=bool)
            mask[reset_rows] = True
            self.estimators.reset(mask)
        for i in reset_rows:
            seed = None if seeds is None else seeds[i]
            raw, info = self.wrappers[i].reset_raw(seed=seed, options=options)
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
