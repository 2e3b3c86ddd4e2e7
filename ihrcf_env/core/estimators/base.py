"""What every deck-pose estimator shares: its input (:class:`SensorFrame`), its output
(:class:`PoseEstimate`) and its interface (:class:`DeckPoseSource`).

Every estimator reports the pose of the **deck** frame in the drone **body** frame (see
:mod:`ihrcf_env.core.frames`): ``position`` (m), ``rotation`` ``R_body_deck`` and ``euler``
(roll, pitch, yaw) in radians, intrinsic Z-Y-X.

The interface follows dm_control's observables: a source has a ``name`` (its observation key), is
``reset()`` at the start of an episode and ``update(frame)``-d once per sensor frame, in time order,
returning its current estimate. Tag detection is done once per frame, outside the estimators (see
:class:`~ihrcf_env.core.estimators.pipeline.DeckPoseEstimator`), and its corners are shared through
the frame; a frame without corners (tag not found) still reaches every estimator, so that a
temporal filter can propagate on the IMU and the ranges.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import _euler, as_array

_T = TypeVar("_T")

#: Collinearity tolerance (see geometry.collinear) for the touch-pixel, sensor and corner quadrilaterals.
DEGENERATE_REL_TOL: float = 1e-2


def _frozen(a: ArrayLike, shape: tuple[int, ...], name: str) -> NDArray[np.float64]:
    """A read-only float64 copy of ``a``, checked like :func:`~ihrcf_env.core.frames.as_array`."""
    out = np.array(a, dtype=np.float64)
    as_array(out, shape, name)
    out.setflags(write=False)
    return out


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
        R = np.array(as_array(R_body_deck, (3, 3), "R_body_deck"))
        p = np.array(as_array(p_body_deck, (3,), "position"))
        euler = _euler(R)  # finite for a finite R
        for a in (R, p, euler):
            a.setflags(write=False)
        est = object.__new__(cls)  # checked above: no second pass through __post_init__
        for name, value in (("position", p), ("euler", euler), ("rotation", R), ("valid", True)):
            object.__setattr__(est, name, value)
        object.__setattr__(est, "residual", float(residual))
        object.__setattr__(est, "reason", "")
        return est


def _shape_checked(x: ArrayLike, shape: tuple[int, ...], name: str, dtype: type = np.float64) -> NDArray:
    """Shape check only (NaN allowed: a bad measurement, not a programmer error)."""
    a: NDArray = np.asarray(x, dtype=dtype)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    return a


def _readonly(x: ArrayLike, shape: tuple[int, ...], name: str, dtype: type = np.float64) -> NDArray:
    """A read-only copy of ``x`` with exactly ``shape`` (NaN allowed: a bad measurement)."""
    a: NDArray = np.array(x, dtype=dtype)  # always a copy
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class ImuSample:
    """One IMU sample (body frame).

    Attributes:
        quaternion: (4,) attitude ``x, y, z, w``, world from body.
        angular_velocity: (3,) body rates, rad/s, body frame.
        specific_force: (3,) accelerometer reading (specific force), m/s^2, body frame
            (+9.81 on z at hover).
    """

    quaternion: NDArray[np.float64]
    angular_velocity: NDArray[np.float64]
    specific_force: NDArray[np.float64]

    def __post_init__(self) -> None:
        object.__setattr__(self, "quaternion", _readonly(self.quaternion, (4,), "quaternion"))
        object.__setattr__(
            self, "angular_velocity", _readonly(self.angular_velocity, (3,), "angular_velocity")
        )
        object.__setattr__(self, "specific_force", _readonly(self.specific_force, (3,), "specific_force"))


#: ``SensorFrame.corners_reason`` when no corners were given and no reason either.
TAG_NOT_FOUND: str = "tag not found"


@dataclass(frozen=True, eq=False)
class SensorFrame:
    """Everything the estimators see at one instant (read-only arrays).

    Attributes:
        time: sample time, s (simulation time in the env; NaN when unknown): the camera's exposure
            time, the instant the corners describe.
        corners: (4, 2) tag corners in OpenCV pixels (pixel centres at integers), OpenCV's aruco
            order, or None when the tag was not detected.
        corners_reason: why ``corners`` is None (default :data:`TAG_NOT_FOUND`); '' when detected.
        ranges: (4,) ToF ranges of ps1..ps4 along the optical axis, m (NaN allowed).
        ranges_valid: (4,) bool, which ranges are usable.
        imu: the IMU sample of this instant, or None.
        image: the camera image the corners came from (uint8), or None (e.g. a projected camera
            model, or a log without images). Estimators must not rely on it being present.
        ranges_time: when the ranges were measured, s (NaN: at ``time``).
        arrival_time: when the frame reached the estimators, s (NaN: at ``time``, no latency); an
            estimator that can predicts its output to this time.
        arrival_imu: the IMU sample at ``arrival_time`` (None: ``imu``).
    """

    time: float
    corners: NDArray[np.float64] | None
    ranges: NDArray[np.float64]
    ranges_valid: NDArray[np.bool_]
    corners_reason: str = ""
    imu: ImuSample | None = None
    image: NDArray[np.uint8] | None = None
    ranges_time: float = math.nan
    arrival_time: float = math.nan
    arrival_imu: ImuSample | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", float(self.time))
        for name in ("ranges_time", "arrival_time"):
            value = float(getattr(self, name))
            if math.isinf(value):
                raise ValueError(f"{name} must be finite (s) or NaN (unknown), got {value!r}")
            object.__setattr__(self, name, value)
        if self.arrival_imu is not None and not isinstance(self.arrival_imu, ImuSample):
            kind = type(self.arrival_imu).__name__
            raise TypeError(f"arrival_imu must be an ImuSample or None, got {kind}")
        if self.corners is None:
            object.__setattr__(self, "corners_reason", str(self.corners_reason) or TAG_NOT_FOUND)
        else:
            object.__setattr__(self, "corners", _readonly(self.corners, (4, 2), "corners"))
            object.__setattr__(self, "corners_reason", "")
        object.__setattr__(self, "ranges", _readonly(self.ranges, (4,), "ranges"))
        object.__setattr__(self, "ranges_valid", _readonly(self.ranges_valid, (4,), "ranges_valid", bool))
        if self.imu is not None and not isinstance(self.imu, ImuSample):
            raise TypeError(f"imu must be an ImuSample or None, got {type(self.imu).__name__}")
        if math.isinf(self.time):
            raise ValueError(f"time must be finite (s) or NaN (unknown), got {self.time!r}")
        object.__setattr__(self, "_memo", {})

    def memo(self, key: Hashable, compute: Callable[[], _T]) -> _T:
        """``compute()``, once per ``key`` for this frame: a product derived from the frame that
        several estimators need (IHRCF's 3-D corners, ATDA's candidate poses) is computed once.
        ``key`` must capture every input of ``compute`` besides the frame's own (read-only)
        arrays; the result is shared, so callers must not modify it."""
        memo: dict[Hashable, Any] = self._memo  # type: ignore[attr-defined]
        if key not in memo:
            memo[key] = compute()
        return memo[key]


@runtime_checkable
class DeckPoseSource(Protocol):
    """A deck-pose estimator fed one :class:`SensorFrame` at a time.

    ``name`` is its observation key (``obs[name]``, ``info[f"{name}_reason"]``). ``reset()`` forgets
    any state (priors, filters) at the start of an episode. ``update(frame)`` takes the next frame
    (time non-decreasing between resets) and returns the current estimate, invalid with a reason
    when there is none; it raises only for programmer errors (wrong shapes), never for bad
    measurements.
    """

    @property
    def name(self) -> str: ...

    def reset(self) -> None: ...

    def update(self, frame: SensorFrame) -> PoseEstimate: ...


__all__ = [
    "DEGENERATE_REL_TOL",
    "TAG_NOT_FOUND",
    "DeckPoseSource",
    "ImuSample",
    "PoseEstimate",
    "SensorFrame",
]
