"""The fitted parameters of the detector model for one camera quality (:class:`QualityParams`):
the corner error's mean and log standard deviation on the features of
:func:`~ihrcf_env.core.detector_model.features.corner_basis`, the realistic camera's extra
variance, the temporal correlation and the detection rules (see ``docs/detector_model.md``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.checks import check_real, describe, set_field
from ihrcf_env.core.detector_model.features import N_BASIS

#: The four coefficient tuples of :class:`QualityParams` (each :data:`N_BASIS` numbers).
COEFFICIENT_FIELDS: tuple[str, ...] = ("mean_radial", "log_sd_radial", "mean_tangential", "log_sd_tangential")
#: Bound of every coefficient (the mean in px and the log of the s.d. in px, per unit feature).
COEFFICIENT_LIMIT = 50.0
#: Bounds (inclusive) of the scalar fields of :class:`QualityParams`.
_LIMITS: dict[str, tuple[float, float]] = {
    "noise_gain": (0.0, 1e3),
    "blur_gain": (0.0, 10.0),
    "corr_max": (0.0, 0.999),
    "corr_length_px": (1e-3, 1e3),
    "min_margin_px": (-10.0, 50.0),
    "band_low_px": (-50.0, 50.0),
    "band_high_px": (-50.0, 100.0),
    "band_fail_prob": (0.0, 1.0),
    "size50_px": (0.0, 500.0),
    "size_width_px": (1e-3, 100.0),
    "min_cos_view": (0.0, 1.0),
    "miss_prob": (0.0, 1.0),
}


_PX_FIELDS = ("corr_length_px", "min_margin_px", "band_low_px", "band_high_px", "size50_px", "size_width_px")


@dataclass(frozen=True)
class QualityParams:
    """Fitted detector parameters of one camera quality (see ``docs/detector_model.md``; px unless
    stated). The four coefficient tuples have :data:`N_BASIS` entries, on
    :data:`~ihrcf_env.core.detector_model.features.BASIS_NAMES`, each in
    [-:data:`COEFFICIENT_LIMIT`, :data:`COEFFICIENT_LIMIT`]; the bounds of the other fields are in
    ``_LIMITS`` (e.g. ``corr_max`` in [0, 0.999], probabilities in [0, 1]). TypeError / ValueError
    naming the field otherwise."""

    mean_radial: tuple[float, ...]
    log_sd_radial: tuple[float, ...]
    mean_tangential: tuple[float, ...]
    log_sd_tangential: tuple[float, ...]
    noise_gain: float = 0.0
    blur_gain: float = 0.0
    corr_max: float = 0.0
    corr_length_px: float = 0.15
    min_margin_px: float = 0.0
    band_low_px: float = 0.0
    band_high_px: float = 0.0
    band_fail_prob: float = 0.0
    size50_px: float = 11.0
    size_width_px: float = 1.5
    min_cos_view: float = 0.0
    miss_prob: float = 0.0

    def __post_init__(self) -> None:
        for name in COEFFICIENT_FIELDS:
            value = getattr(self, name)
            if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
                raise TypeError(f"{name} must be a sequence of {N_BASIS} numbers, got {describe(value)}")
            if len(value) != N_BASIS:
                raise ValueError(f"{name} must have {N_BASIS} coefficients, got {len(value)}")
            lim = COEFFICIENT_LIMIT
            set_field(
                self,
                name,
                tuple(check_real(f"{name}[{i}]", v, low=-lim, high=lim) for i, v in enumerate(value)),
            )
        for name, (lo, hi) in _LIMITS.items():
            set_field(
                self,
                name,
                check_real(name, getattr(self, name), "px" if name in _PX_FIELDS else "", low=lo, high=hi),
            )
        if self.band_high_px < self.band_low_px:
            raise ValueError(
                f"band_high_px ({self.band_high_px}) must be >= band_low_px ({self.band_low_px})"
            )
        coef = np.array([getattr(self, name) for name in COEFFICIENT_FIELDS]).T  # (N_BASIS, 4)
        coef.setflags(write=False)
        set_field(self, "_coef", coef)

    def to_dict(self) -> dict[str, Any]:
        return {
            f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> QualityParams:
        if not isinstance(data, Mapping):
            raise TypeError(f"quality parameters must be a mapping, got {describe(data)}")
        names = {f.name for f in fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown parameters {sorted(unknown)}")
        missing = set(COEFFICIENT_FIELDS) - set(data)
        if missing:
            raise ValueError(f"missing parameters {sorted(missing)}")
        kwargs: dict[str, Any] = {
            k: (tuple(v) if k in COEFFICIENT_FIELDS and isinstance(v, list) else v) for k, v in data.items()
        }
        return cls(**kwargs)

    # -- the model's pieces (vectorised over leading dimensions) --------------------------------------
    def error_moments(
        self, basis: ArrayLike, side: ArrayLike, noise_ratio: ArrayLike = 0.0, blur_px: ArrayLike = 0.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean (..., 4, 2) and s.d. (..., 4, 2) of the corner errors along (radial, tangential)
        (px), for features ``basis`` (..., 4, N_BASIS), ``side`` (..., 4) px, ``noise_ratio``
        (broadcast to (..., 4)) and ``blur_px`` (broadcast to (..., 4))."""
        M = np.asarray(basis, dtype=np.float64) @ self._coef  # type: ignore[attr-defined]
        mean = M[..., 0::2]
        var = np.exp(2.0 * M[..., 1::2])
        if self.noise_gain or self.blur_gain:
            extra = (self.noise_gain * np.asarray(noise_ratio)) ** 2 * (100.0 / np.asarray(side)) + (
                self.blur_gain * np.asarray(blur_px)
            ) ** 2
            var = var + np.asarray(extra)[..., None]
        return mean, np.sqrt(var)

    def correlation(self, displacement_px: ArrayLike) -> NDArray[np.float64]:
        """Correlation of a corner's normalised error between two frames of a track in which the
        corner lies ``displacement_px`` (px) apart in the image (whatever the time between them)."""
        d = np.asarray(displacement_px, dtype=np.float64) / self.corr_length_px
        out: NDArray[np.float64] = self.corr_max * np.exp(-d * d)
        return out

    def detection_probability(
        self, quiet_margin: ArrayLike, min_side: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Failure probabilities of the probabilistic rules, each (...): the quiet zone cut by the
        border, the tag too small, the residual miss (broadcast)."""
        q = np.asarray(quiet_margin, dtype=np.float64)
        band = np.where((q >= self.band_low_px) & (q < self.band_high_px), self.band_fail_prob, 0.0)
        x = (np.asarray(min_side, dtype=np.float64) - self.size50_px) / self.size_width_px
        small = 1.0 / (1.0 + np.exp(np.clip(x, -50.0, 50.0)))
        return band, small, np.broadcast_to(self.miss_prob, np.shape(band)).astype(np.float64)


__all__ = [
    "COEFFICIENT_FIELDS",
    "COEFFICIENT_LIMIT",
    "QualityParams",
]
