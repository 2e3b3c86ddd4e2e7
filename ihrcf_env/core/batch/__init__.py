"""Batched (vectorised) versions of the single-frame deck-pose estimators: one call evaluates N
independent frames given as arrays with a leading axis N (pure numpy, no per-frame Python loop).

Each function reproduces its single-frame counterpart in :mod:`ihrcf_env.core.geometry` and
:mod:`ihrcf_env.core.estimators` frame by frame (same validity, same reason text, numbers equal to
floating-point rounding): ``geometry`` (plane, homography, rigid fit, Euler angles), ``tables``
(the range -> pixel table), ``result`` (the batched :class:`~ihrcf_env.core.estimators.base.PoseEstimate`
and its reason table), ``ihrcf`` (IHRCF), ``pnp`` (ATDA's square-tag PnP) and ``fused`` (the
IMU-fused filter of N envs, :class:`~ihrcf_env.core.batch.fused.BatchFused`, with ``imm``,
``fused_frames``, ``fused_measure``, ``fused_blocks`` and ``fused_result``).
"""

from ihrcf_env.core.batch.fused import BatchFused
from ihrcf_env.core.batch.fused_frames import BatchFrames, stack_frames
from ihrcf_env.core.batch.fused_result import BatchFusedOutput
from ihrcf_env.core.batch.ihrcf import IHRCFBatch, ihrcf_batch
from ihrcf_env.core.batch.pnp import atda_batch
from ihrcf_env.core.batch.result import REASONS, BatchPoses
from ihrcf_env.core.batch.tables import BatchTable, batch_table

__all__ = [
    "REASONS",
    "BatchFrames",
    "BatchFused",
    "BatchFusedOutput",
    "BatchPoses",
    "BatchTable",
    "IHRCFBatch",
    "atda_batch",
    "batch_table",
    "ihrcf_batch",
    "stack_frames",
]
