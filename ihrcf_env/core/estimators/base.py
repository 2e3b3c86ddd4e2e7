"""The pose-estimate record shared by every deck-pose estimator.

Both estimators report the pose of the **deck** frame in the drone **body** frame (see
:mod:`ihrcf_env.core.frames`): ``position`` (m), ``rotation`` ``R_body_deck`` and ``euler``
(roll, pitch, yaw) in radians, intrinsic Z-Y-X.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import as_array, euler_from_matrix

#: Collinearity tolerance (see geometry.collinear) for the touch-pixel, sensor and corner quadrilaterals.
DEGENERATE_REL_TOL: float = 1e-2


def _frozen(a: ArrayLike, shape: tuple[int, ...], name: str) -> NDArray[np.float64]:
    a = np.array(as_array(a, shape, name), dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """Deck pose in the drone body frame.

    Attributes:
        position: (3,) deck origin (tag centre) in the body frame, m.
        euler: (3,) (roll, pitch, yaw) of ``rotation``, rad (intrinsic Z-Y-X, see frames).
        rotation: (3, 3) ``R_body_deck`` (deck axes expressed in the body frame).
        valid: False when the estimator could not produce a pose; then all numbers are zeros /
            identity (never NaN), see :meth:`invalid`.
        residual: fit quality. IHRCF: RMS of the rigid-fit residuals of the four 3-D corners, m.
            ATDA: RMS reprojection error of the four corners, px. 0 when invalid.
        reason: why the estimate is invalid; '' when valid.
    """

    position: NDArray[np.float64]
    euler: NDArray[np.float64]
    rotation: NDArray[np.float64]
    valid: bool
    residual: float
    reason: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _frozen(self.position, (3,), "position"))
        object.__setattr__(self, "euler", _frozen(self.euler, (3,), "euler"))
        object.__setattr__(self, "rotation", _frozen(self.rotation, (3, 3), "rotation"))
        object.__setattr__(self, "valid", bool(self.valid))
        object.__setattr__(self, "residual", float(self.residual))

    @classmethod
    def invalid(cls, reason: str) -> PoseEstimate:
        """An invalid estimate: zero position and euler, identity rotation, residual 0, ``reason`` set."""
        return cls(np.zeros(3), np.zeros(3), np.eye(3), False, 0.0, reason)

    @classmethod
    def from_body_pose(cls, R_body_deck: ArrayLike, p_body_deck: ArrayLike, residual: float) -> PoseEstimate:
        """A valid estimate from a body-frame rotation (3, 3) and position (3,) (m)."""
        R = as_array(R_body_deck, (3, 3), "R_body_deck")
        return cls(p_body_deck, euler_from_matrix(R), R, True, residual, "")


def _shape_checked(x: ArrayLike, shape: tuple[int, ...], name: str, dtype: type = np.float64) -> NDArray:
    """Shape check only (NaN allowed: a bad measurement, not a programmer error)."""
    a = np.asarray(x, dtype=dtype)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return a
