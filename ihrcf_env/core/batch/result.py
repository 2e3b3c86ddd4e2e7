"""The batched :class:`~ihrcf_env.core.estimators.base.PoseEstimate`: N estimates as arrays, and the
table of the single estimators' reason strings their codes index."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.batch.geometry import (
    HOMOGRAPHY_ERRORS,
    PLANE_ERRORS,
    PLANE_Z_ERROR,
    RIGID_ERROR,
    euler_batch,
)
from ihrcf_env.core.estimators.base import TAG_NOT_FOUND, PoseEstimate

#: Reason codes (indices into :data:`REASONS`) of the batched IHRCF and ATDA.
OK = 0
NOT_DETECTED = 1
NONFINITE_CORNERS = 2
FEW_RANGES = 3
PLANE_COINCIDENT = 4
PLANE_COLLINEAR = 5
PLANE_PARALLEL = 6
PREDICTED_RANGE = 7
OUTSIDE_TABLE = 8
NONFINITE_TOUCH = 9
DEGENERATE_LAYOUT = 10
DEGENERATE_TOUCH = 11
HOMOGRAPHY_NOT_UNIQUE = 12
HOMOGRAPHY_H22 = 13
CORNER_AT_INFINITY = 14
CORNER_BEHIND = 15
FIT_NONFINITE = 16
FIT_COLLINEAR = 17
FIT_RESIDUAL = 18
DEGENERATE_TAG = 19
PNP_NO_SOLUTION = 20
TAG_BEHIND = 21

#: Reason text of each code, as the single estimators write it (:data:`FIT_RESIDUAL` is a template
#: filled with the residual and the threshold, m; :data:`NOT_DETECTED` is replaced by the frame's own
#: reason when one is given to :meth:`BatchPoses.reasons`).
REASONS: tuple[str, ...] = (
    "",
    TAG_NOT_FOUND,
    "non-finite tag corners",
    "fewer than 3 valid ranges",
    f"deck plane undefined: {PLANE_ERRORS[1]}",
    f"deck plane undefined: {PLANE_ERRORS[2]}",
    f"deck plane undefined: {PLANE_Z_ERROR}",
    "predicted range not positive",
    "range outside calibration table",
    "non-finite touch pixels",
    "degenerate sensor layout",
    "degenerate touch pixels",
    f"homography failed: {HOMOGRAPHY_ERRORS[1]}",
    f"homography failed: {HOMOGRAPHY_ERRORS[2]}",
    "tag corner maps to infinity",
    "tag corner behind the camera",
    "rigid fit failed: non-finite corners",
    f"rigid fit failed: {RIGID_ERROR}",
    "fit residual {rms:.4g} m > {max_residual:.4g} m",
    "degenerate tag corners",
    "solvePnP found no solution",
    "tag behind the camera",
)


def first_failure(code: NDArray[np.int8], failed: ArrayLike, reason: int) -> None:
    """Set ``code`` to ``reason`` in place where ``failed`` and no earlier check failed."""
    code[(code == OK) & np.asarray(failed, dtype=bool)] = reason


@dataclass(frozen=True, eq=False)
class BatchPoses:
    """N deck-pose estimates (body frame), row i equal to one :class:`PoseEstimate`.

    Attributes:
        position: (N, 3) deck origin in the body frame, m (zeros where invalid).
        euler: (N, 3) (roll, pitch, yaw), rad (zeros where invalid).
        rotation: (N, 3, 3) ``R_body_deck`` (identity where invalid).
        valid: (N,) bool.
        residual: (N,) fit quality as in :class:`PoseEstimate` (0 where invalid).
        code: (N,) int8 reason codes, indices into :data:`REASONS` (0 where valid).
        fit_rms: (N,) the rigid-fit RMS (m) behind a :data:`FIT_RESIDUAL` code (else 0).
        max_residual: the threshold (m) of :data:`FIT_RESIDUAL` (NaN when not applicable).
    """

    position: NDArray[np.float64]
    euler: NDArray[np.float64]
    rotation: NDArray[np.float64]
    valid: NDArray[np.bool_]
    residual: NDArray[np.float64]
    code: NDArray[np.int8]
    fit_rms: NDArray[np.float64]
    max_residual: float = float("nan")

    def __len__(self) -> int:
        return len(self.valid)

    def reason(self, i: int, not_detected: str = TAG_NOT_FOUND) -> str:
        """Reason text of row ``i`` ('' when valid); ``not_detected`` for an undetected tag."""
        c = int(self.code[i])
        if c == FIT_RESIDUAL:
            return REASONS[c].format(rms=float(self.fit_rms[i]), max_residual=self.max_residual)
        return not_detected if c == NOT_DETECTED else REASONS[c]

    def reasons(self, not_detected: Sequence[str] | None = None) -> list[str]:
        """Reason text of every row; ``not_detected[i]`` (e.g. the frame's ``corners_reason``)
        replaces :data:`TAG_NOT_FOUND` for an undetected tag."""
        nd = [TAG_NOT_FOUND] * len(self) if not_detected is None else list(not_detected)
        return [self.reason(i, nd[i]) for i in range(len(self))]

    def estimate(self, i: int, not_detected: str = TAG_NOT_FOUND) -> PoseEstimate:
        """Row ``i`` as a :class:`PoseEstimate`."""
        if not self.valid[i]:
            return PoseEstimate.invalid(self.reason(i, not_detected))
        return PoseEstimate(self.position[i], self.euler[i], self.rotation[i], True, float(self.residual[i]))


def assemble(
    R: NDArray[np.float64],
    p: NDArray[np.float64],
    residual: NDArray[np.float64],
    code: NDArray[np.int8],
    fit_rms: NDArray[np.float64] | None = None,
    max_residual: float = float("nan"),
) -> BatchPoses:
    """A :class:`BatchPoses` of body-frame rotations (N, 3, 3) and positions (N, 3), with the invalid
    rows (``code != 0``) reset to zeros / identity as :meth:`PoseEstimate.invalid` does."""
    ok = code == OK
    R = np.where(ok[:, None, None], R, np.eye(3))
    p = np.where(ok[:, None], p, 0.0)
    euler = np.where(ok[:, None], euler_batch(R), 0.0)
    rms = np.zeros(len(code)) if fit_rms is None else np.where(code == FIT_RESIDUAL, fit_rms, 0.0)
    return BatchPoses(p, euler, R, ok, np.where(ok, residual, 0.0), code, rms, max_residual)


__all__ = [
    "CORNER_AT_INFINITY",
    "CORNER_BEHIND",
    "DEGENERATE_LAYOUT",
    "DEGENERATE_TAG",
    "DEGENERATE_TOUCH",
    "FEW_RANGES",
    "FIT_COLLINEAR",
    "FIT_NONFINITE",
    "FIT_RESIDUAL",
    "HOMOGRAPHY_H22",
    "HOMOGRAPHY_NOT_UNIQUE",
    "NONFINITE_CORNERS",
    "NONFINITE_TOUCH",
    "NOT_DETECTED",
    "OK",
    "OUTSIDE_TABLE",
    "PLANE_COINCIDENT",
    "PLANE_COLLINEAR",
    "PLANE_PARALLEL",
    "PNP_NO_SOLUTION",
    "PREDICTED_RANGE",
    "REASONS",
    "TAG_BEHIND",
    "BatchPoses",
    "assemble",
    "first_failure",
]
