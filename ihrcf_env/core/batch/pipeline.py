"""The built-in estimators of N :class:`~ihrcf_env.core.estimators.pipeline.DeckPoseEstimator` s
evaluated together: :class:`BatchDeckPoseEstimator`.

One call of :meth:`BatchDeckPoseEstimator.update` takes one :class:`SensorFrame` (or None: the
row is not stepped) per row and returns, per stepped row, what that row's own
:class:`DeckPoseEstimator` would: name -> :class:`PoseEstimate`. IHRCF and the fused filter run
on arrays (:func:`~ihrcf_env.core.batch.ihrcf.ihrcf_batch`,
:class:`~ihrcf_env.core.batch.fused.BatchFused`); ATDA's candidate poses come from the single
frame's cv2 path (:func:`~ihrcf_env.core.estimators.atda.atda_candidates`, one call per frame with
a tag, shared by ATDA and the fused filter as :meth:`SensorFrame.memo` shares them), so each row
equals the single estimator to floating-point rounding. Only the built-in ``ihrcf``, ``atda``
and ``fused`` are batched: :func:`batchable` says whether a set of estimators is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch.fused import BatchFused
from ihrcf_env.core.batch.fused_frames import BatchFrames, stack_atda_candidates, stack_frames
from ihrcf_env.core.batch.ihrcf import ihrcf_batch
from ihrcf_env.core.batch.pnp import PnPCandidates, pnp_choose
from ihrcf_env.core.batch.tables import BatchTable
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.estimators.atda import ATDAEstimator, Candidate, atda_candidates
from ihrcf_env.core.estimators.base import DeckPoseSource, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.fused import FusedEstimator
from ihrcf_env.core.estimators.ihrcf import IHRCFEstimator
from ihrcf_env.core.estimators.registry import BUILTIN_ESTIMATORS, ESTIMATORS, EstimatorConfig

#: The estimator classes evaluated on arrays, by observation key.
BATCHED: dict[str, type] = {"ihrcf": IHRCFEstimator, "atda": ATDAEstimator, "fused": FusedEstimator}

#: A row's estimates (name -> estimate), as :meth:`DeckPoseEstimator.update` returns them.
Estimates = dict[str, PoseEstimate]


def batchable_names(names: Sequence[str]) -> bool:
    """True when every estimator ``names`` registers is a built-in one of :data:`BATCHED` (not
    re-registered by user code)."""
    return bool(names) and all(n in BATCHED and ESTIMATORS.get(n) is BUILTIN_ESTIMATORS.get(n) for n in names)


def batchable(sources: Mapping[str, DeckPoseSource]) -> bool:
    """True when every estimator of ``sources`` (name -> estimator, as
    :attr:`DeckPoseEstimator.sources`) is a built-in one of :data:`BATCHED` under its own key."""
    return bool(sources) and all(type(s) is BATCHED.get(n) for n, s in sources.items())


class BatchDeckPoseEstimator:
    """The estimators ``names`` (a subset of :data:`BATCHED`, in the observation's order) of ``n``
    rows built from one :class:`EstimatorConfig` (as :func:`build_estimators` builds them).

    Attributes: ``n``, ``names``, ``config``; ``fused`` (the :class:`BatchFused`, or None).
    """

    def __init__(self, n: int, config: EstimatorConfig, names: Sequence[str]) -> None:
        unknown = [k for k in names if k not in BATCHED]
        if unknown:
            raise ValueError(f"estimators: {unknown} have no batched form (batched: {sorted(BATCHED)})")
        self.n = int(n)
        self.names = tuple(names)
        self.config = c = config
        table = c.touch_pixels
        self._table = BatchTable(table) if isinstance(table, RangePixelTable) else table
        self.fused = (
            BatchFused(self.n, self._table, c.rig, c.tag_size, c.K, c.dist, c.max_residual, params=c.fused)
            if "fused" in self.names
            else None
        )
        self._prior = np.tile(np.eye(3), (self.n, 1, 1))  # ATDA's flip prior per row
        self._has_prior = np.zeros(self.n, dtype=bool)

    def reset(self, mask: ArrayLike | None = None) -> None:
        """Reset the estimators of the rows in ``mask`` (N,) bool (default all), as
        :meth:`DeckPoseEstimator.reset`."""
        m = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        self._has_prior[m] = False
        self._prior[m] = np.eye(3)
        if self.fused is not None:
            self.fused.reset(m)

    def update(self, frames: Sequence[SensorFrame | None]) -> list[Estimates | None]:
        """Feed row i's frame to row i's estimators (None: the row is not stepped and keeps its
        state); per row, name -> estimate (None for rows not stepped)."""
        if len(frames) != self.n:
            raise ValueError(f"frames: one per row ({self.n}), got {len(frames)}")
        active = np.array([f is not None for f in frames], dtype=bool)
        out: list[Estimates | None] = [None] * self.n
        if not active.any():
            return out
        bf = stack_frames(frames)
        cands = self._candidates(frames) if ("atda" in self.names or self._fused_uses_atda()) else None
        per_name: dict[str, list[PoseEstimate]] = {}
        rows = np.flatnonzero(active)
        for name in self.names:
            if name == "ihrcf":
                per_name[name] = self._ihrcf(bf, rows)
            elif name == "atda":
                assert cands is not None
                per_name[name] = self._atda(bf, cands, active, rows)
            else:
                assert self.fused is not None
                res = self.fused.update(bf, active, cands)
                per_name[name] = [res.estimate(int(i)) for i in rows]
        for k, i in enumerate(rows):
            out[int(i)] = {name: per_name[name][k] for name in self.names}
        return out

    def motion(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """The fused filter's deck motion per row (:meth:`BatchFused.motion`): velocity (N, 3) m/s,
        normal rate (N, 3) 1/s, and the rows where it is defined. RuntimeError without ``fused``."""
        if self.fused is None:
            raise RuntimeError("motion() needs the fused estimator")
        return self.fused.motion()

    # -- the estimators ------------------------------------------------------------------------
    def _fused_uses_atda(self) -> bool:
        p = self.fused.params if self.fused is not None else None
        return p is not None and self.config.K is not None and (p.use_atda_attitude or p.use_atda_position)

    def _candidates(self, frames: Sequence[SensorFrame | None]) -> PnPCandidates:
        """ATDA's candidates of each frame with a tag (cv2's path, refined), placeholders elsewhere."""
        c = self.config
        res: list[list[Candidate] | str] = []
        for f in frames:
            if f is None or f.corners is None:
                res.append("tag not found")  # not read: the row is inactive or has no tag
            else:
                res.append(atda_candidates(f.corners, c.K, c.dist, c.tag_size, c.rig, True))
        return stack_atda_candidates(res)

    def _ihrcf(self, bf: BatchFrames, rows: NDArray[np.intp]) -> list[PoseEstimate]:
        c = self.config
        poses = ihrcf_batch(
            bf.corners,
            bf.ranges,
            bf.ranges_valid,
            bf.detected,
            self._table,
            c.rig,
            c.tag_size,
            c.max_residual,
        )
        return [poses.estimate(int(i), bf.corners_reason[i]) for i in rows]

    def _atda(
        self, bf: BatchFrames, cands: PnPCandidates, active: NDArray[np.bool_], rows: NDArray[np.intp]
    ) -> list[PoseEstimate]:
        poses = pnp_choose(cands, self._prior, self._has_prior)
        took = active & bf.detected & poses.valid
        self._prior[took] = poses.rotation[took]
        self._has_prior |= took
        return [
            poses.estimate(int(i)) if bf.detected[i] else PoseEstimate.invalid(bf.corners_reason[i])
            for i in rows
        ]


__all__ = [
    "BATCHED",
    "BatchDeckPoseEstimator",
    "Estimates",
    "batchable",
    "batchable_names",
]
