"""Quiescent periods of a moving deck: windows where the deck is calm enough to land (pure numpy).

A time is **quiescent** when the deck's vertical speed ``|dz/dt|`` stays under
``vertical_speed`` AND its tilt (the angle between the deck normal and the vertical,
``arccos(cos roll cos pitch)``) stays under ``tilt`` for a run of at least ``min_duration``:
the time a helicopter or a drone needs to touch down and settle. The **quiescent fraction** is
the fraction of the record's time inside such runs.

Thresholds are given at full (ship) scale, by default 0.3 m/s, 1 deg and 2 s (a calm-deck
window in the sense of ship-helicopter operating limits, stricter than the limits themselves);
:meth:`QuiescenceThresholds.scaled` converts them to a Froude model scale (speeds and durations
/ sqrt(lambda), angles unchanged).

The **energy index** is a deck-motion indicator in the spirit of the ship-helicopter deck-motion
"energy index" used to designate landing periods (a weighted sum of the deck's kinetic and
potential energies): low values announce a quiescent period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.checks import check_fields, check_positive


@dataclass(frozen=True)
class QuiescenceThresholds:
    """Full-scale thresholds: ``vertical_speed`` (m/s), ``tilt`` (rad), ``min_duration`` (s)."""

    vertical_speed: float = 0.3
    tilt: float = math.radians(1.0)
    min_duration: float = 2.0

    def __post_init__(self) -> None:
        check_fields(
            self,
            lambda n: f"quiescence.{n}",
            {"vertical_speed": (1e-6, 100.0), "tilt": (1e-6, math.pi / 2), "min_duration": (0.0, 1e4)},
            {"vertical_speed": "m/s", "tilt": "rad", "min_duration": "s"},
        )

    def scaled(self, length_scale: float) -> QuiescenceThresholds:
        """The thresholds at the Froude model scale ``length_scale`` (lambda >= 1)."""
        lam = check_positive("length_scale", length_scale, "", high=1e4)
        s = math.sqrt(lam)
        return QuiescenceThresholds(self.vertical_speed / s, self.tilt, self.min_duration / s)


def _check_record(t: ArrayLike, offset: ArrayLike, rpy: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    tt = np.asarray(t, dtype=np.float64)
    off = np.asarray(offset, dtype=np.float64)
    ang = np.asarray(rpy, dtype=np.float64)
    n = tt.shape[0] if tt.ndim == 1 else -1
    if n < 3 or off.shape != (n, 3) or ang.shape != (n, 3):
        raise ValueError(
            f"quiescence needs t (N,), offset (N, 3), rpy (N, 3) with N >= 3, got {tt.shape}, "
            f"{off.shape}, {ang.shape}"
        )
    if not (np.all(np.diff(tt) > 0) and np.isfinite(off).all() and np.isfinite(ang).all()):
        raise ValueError("quiescence needs increasing times and finite poses")
    return tt, off, ang


def tilt(rpy: ArrayLike) -> NDArray[np.float64]:
    """Angle (rad) between the deck normal and the vertical for ZYX roll/pitch/yaw (N, 3)."""
    a = np.asarray(rpy, dtype=np.float64)
    return np.arccos(np.clip(np.cos(a[:, 0]) * np.cos(a[:, 1]), -1.0, 1.0))


def quiescent_mask(
    t: ArrayLike, offset: ArrayLike, rpy: ArrayLike, thresholds: QuiescenceThresholds
) -> NDArray[np.bool_]:
    """(N,) True at the samples inside a quiescent run (see the module docstring) of a deck
    record: times ``t`` (s, increasing), ``offset`` (N, 3) m, ``rpy`` (N, 3) rad, all at the
    thresholds' scale. The vertical speed is the finite difference of the heave."""
    tt, off, ang = _check_record(t, offset, rpy)
    vz = np.gradient(off[:, 2], tt)
    calm = (np.abs(vz) < thresholds.vertical_speed) & (tilt(ang) < thresholds.tilt)
    out = np.zeros_like(calm)
    for start, stop in _runs(calm):
        if tt[stop - 1] - tt[start] >= thresholds.min_duration - 1e-9:
            out[start:stop] = True
    return out


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(start, stop) index ranges of the True runs."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True))


def quiescent_periods(
    t: ArrayLike, offset: ArrayLike, rpy: ArrayLike, thresholds: QuiescenceThresholds
) -> list[tuple[float, float]]:
    """(start, end) times (s) of the quiescent runs of a deck record (see :func:`quiescent_mask`)."""
    tt = np.asarray(t, dtype=np.float64)
    mask = quiescent_mask(t, offset, rpy, thresholds)
    return [(float(tt[a]), float(tt[b - 1])) for a, b in _runs(mask)]


def quiescent_fraction(
    t: ArrayLike, offset: ArrayLike, rpy: ArrayLike, thresholds: QuiescenceThresholds
) -> float:
    """Fraction (0-1) of the samples of a deck record inside quiescent runs."""
    return float(np.mean(quiescent_mask(t, offset, rpy, thresholds)))


def energy_index(
    t: ArrayLike, offset: ArrayLike, rpy: ArrayLike, thresholds: QuiescenceThresholds
) -> NDArray[np.float64]:
    """(N,) dimensionless deck-motion energy: ``(vz / vertical_speed)^2 + (tilt / tilt_max)^2
    + (tilt rate * min_duration / tilt_max)^2`` with the thresholds' scale. At a calm sample the
    first two terms are each below 1; the tilt-rate term looks ahead about ``min_duration``, so
    a low index announces a quiescent run rather than its end."""
    tt, off, ang = _check_record(t, offset, rpy)
    vz = np.gradient(off[:, 2], tt)
    tl = tilt(ang)
    rate = np.gradient(tl, tt)
    th = thresholds
    return (vz / th.vertical_speed) ** 2 + (tl / th.tilt) ** 2 + (rate * th.min_duration / th.tilt) ** 2


def heave_energy_bound(heave: ArrayLike, vz: ArrayLike, omega: float) -> NDArray[np.float64]:
    """Amplitude (m) of the heave oscillation at ``omega`` (rad/s) with the current heave and
    vertical speed: ``sqrt(z^2 + (vz / omega)^2)``; a short-horizon bound of the heave over the
    next half period of a narrow-band deck motion."""
    w = check_positive("omega", omega, "rad/s", high=1e3)
    z = np.asarray(heave, dtype=np.float64)
    v = np.asarray(vz, dtype=np.float64)
    return np.sqrt(z**2 + (v / w) ** 2)


__all__ = [
    "QuiescenceThresholds",
    "energy_index",
    "heave_energy_bound",
    "quiescent_fraction",
    "quiescent_mask",
    "quiescent_periods",
    "tilt",
]
