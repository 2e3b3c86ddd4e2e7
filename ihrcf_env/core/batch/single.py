"""ATDA on one frame through the batched square-tag PnP (:mod:`ihrcf_env.core.batch.pnp` with
N = 1): the single-frame API of :mod:`ihrcf_env.core.estimators.atda` with the arithmetic of the
batched estimator, so a single environment and row i of a vector environment give the same numbers.

:func:`atda_candidates_batched` has the signature and result of
:func:`~ihrcf_env.core.estimators.atda.atda_candidates` (``dist``: at most the five coefficients
(k1, k2, p1, p2, k3); ValueError otherwise); :func:`atda_single` that of
:func:`~ihrcf_env.core.estimators.atda.atda_estimate`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch.pnp import pnp_candidates, pnp_choose
from ihrcf_env.core.batch.result import REASONS
from ihrcf_env.core.estimators.base import PoseEstimate, _shape_checked
from ihrcf_env.core.frames import as_array
from ihrcf_env.core.rig import SensorRig

#: One solution: (RMS reprojection error px, ``R_body_deck`` (3, 3), ``p_body_deck`` (3,) m), as
#: :data:`ihrcf_env.core.estimators.atda.Candidate`.
Candidate = tuple[float, NDArray[np.float64], NDArray[np.float64]]

_DETECTED = np.ones(1, dtype=bool)
_DETECTED.setflags(write=False)


def atda_candidates_batched(
    corners_px: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    refine: bool = True,
) -> list[Candidate] | str:
    """The polished IPPE solutions of one frame's corners (4, 2) px in front of the camera, lowest
    reprojection error first, or the reason (str) there are none."""
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    c = pnp_candidates(corners[None], _DETECTED, K, dist, tag_size, rig, refine)
    code = int(c.code[0])
    if code:
        return REASONS[code]
    return [(float(c.error[0, s]), c.rotation[0, s], c.position[0, s]) for s in (0, 1) if c.usable[0, s]]


def atda_single(
    corners_px: ArrayLike,
    K: ArrayLike,
    dist: ArrayLike | None,
    tag_size: float,
    rig: SensorRig,
    prior_rotation: ArrayLike | None = None,
    refine: bool = True,
) -> PoseEstimate:
    """ATDA deck pose of one frame (arguments and result as
    :func:`~ihrcf_env.core.estimators.atda.atda_estimate`): row 0 of
    :func:`~ihrcf_env.core.batch.pnp.atda_batch` on this frame alone."""
    corners = _shape_checked(corners_px, (4, 2), "corners_px")
    prior = None if prior_rotation is None else as_array(prior_rotation, (3, 3), "prior_rotation")[None]
    c = pnp_candidates(corners[None], _DETECTED, K, dist, tag_size, rig, refine)
    return pnp_choose(c, prior).estimate(0)


__all__ = [
    "Candidate",
    "atda_candidates_batched",
    "atda_single",
]
