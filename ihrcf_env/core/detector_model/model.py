"""The detector model at run time: :class:`DetectorModel` turns a frame's
:class:`~ihrcf_env.core.detector_model.features.TagFeatures` into the corners the rendered
detector would report, or the reason it would fail; :class:`CornerTrack` carries an episode's
correlated error field. The model is described in ``docs/detector_model.md``. Pure numpy.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import describe
from ihrcf_env.core.detector_model.features import TagFeatures, image_margin
from ihrcf_env.core.detector_model.params import QualityParams

#: Camera qualities the model covers (:data:`ihrcf_env.config.sensors.CAMERA_QUALITIES`).
QUALITIES: tuple[str, ...] = ("ideal", "realistic")

#: Failure reasons (``reason`` of :meth:`DetectorModel.corners`).
REASON_OUTSIDE = "tag outside the image"
REASON_BORDER = "tag partly outside the image (too close to its border)"
REASON_OBLIQUE = "tag seen too obliquely"
REASON_QUIET_ZONE = "tag's quiet zone cut by the image border"
REASON_SMALL = "tag too small in the image"
REASON_MISS = "detector missed the tag"


#: Random features of a track's error field (:class:`CornerTrack`).
FIELD_FEATURES = 32


class CornerTrack:
    """Per-episode state of the correlated corner error: a smooth random field over the image.

    The rendered detector's error is a function of where a corner falls on the pixel grid: the same
    pose gives the same error, a corner that moved ``D`` px between two frames (whatever their time
    apart) has errors correlated by ``exp(-(D / corr_length_px)^2)``. The track draws such a field
    per corner and component (random Fourier features: :data:`FIELD_FEATURES` cosines with
    Gaussian frequencies, unit variance); :meth:`DetectorModel.corners` evaluates it at the true
    corners. :meth:`reset` at the start of every episode, with the episode's generator (without
    one, the field is drawn from the generator of the first :meth:`DetectorModel.corners` call).
    """

    def __init__(self, rng: np.random.Generator | None = None) -> None:
        self.omega: NDArray[np.float64] | None = None  # (4, 2 * FIELD_FEATURES, 2) unit frequencies
        self.phase: NDArray[np.float64] | None = None  # (4, 2 * FIELD_FEATURES)
        self.reset(rng)

    def reset(self, rng: np.random.Generator | None = None) -> None:
        """Draw a new field from ``rng`` (``4 * 2 * FIELD_FEATURES * 3`` numbers), or forget it."""
        if rng is None:
            self.omega = self.phase = None
            return
        m = 2 * FIELD_FEATURES
        self.omega = rng.standard_normal((4, m, 2))
        self.phase = rng.uniform(0.0, 2.0 * math.pi, (4, m))

    def field(
        self, corners: NDArray[np.float64], length_px: float, rng: np.random.Generator
    ) -> NDArray[np.float64]:
        """The field (4, 2) (unit variance, Gaussian covariance of length ``length_px``) at the
        corners (4, 2) px; drawn from ``rng`` first if the track has none."""
        if self.omega is None or self.phase is None:
            self.reset(rng)
        assert self.omega is not None and self.phase is not None
        arg = (self.omega @ corners[:, :, None])[..., 0] * (math.sqrt(2.0) / length_px) + self.phase
        out: NDArray[np.float64] = np.cos(arg).reshape(4, 2, FIELD_FEATURES).sum(axis=-1)
        return out * math.sqrt(2.0 / FIELD_FEATURES)


@dataclass(frozen=True, eq=False)
class DetectorModel:
    """The fitted detector model: :class:`QualityParams` per camera quality (``"ideal"``,
    ``"realistic"``) and the fit's record (``fit``: command, seed, frames, camera, statistics).

    :meth:`corners` turns a frame's :class:`TagFeatures` into detected corners or a failure reason;
    :meth:`load` / :meth:`save` read and write the JSON file (:func:`default_detector_model_path`).
    """

    qualities: Mapping[str, QualityParams]
    fit: Mapping[str, Any] = field(default_factory=dict)
    source: str | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.qualities, Mapping):
            raise TypeError(
                f"qualities must be a mapping of quality -> QualityParams, got {self.qualities!r}"
            )
        missing = [q for q in QUALITIES if q not in self.qualities]
        if missing:
            raise ValueError(f"qualities must include {QUALITIES}; missing {missing}")
        for q, prm in self.qualities.items():
            if not isinstance(prm, QualityParams):
                raise TypeError(f"qualities[{q!r}] must be a QualityParams, got {describe(prm)}")
        if not isinstance(self.fit, Mapping):
            raise TypeError(f"fit must be a mapping, got {describe(self.fit)}")

    def params(self, quality: str) -> QualityParams:
        """The parameters of camera ``quality``; ValueError naming it if unknown."""
        try:
            return self.qualities[quality]
        except (KeyError, TypeError):
            raise ValueError(f"quality must be one of {tuple(self.qualities)}, got {quality!r}") from None

    def corners(
        self,
        features: TagFeatures,
        rng: np.random.Generator,
        quality: str = "ideal",
        track: CornerTrack | None = None,
    ) -> tuple[NDArray[np.float64] | None, str]:
        """What the rendered detector would report for ``features``: ``(corners (4, 2) px, "")`` or
        ``(None, reason)``.

        Always draws 8 standard normals and one uniform from ``rng`` (whatever the outcome), so a
        seeded run is reproducible and the stream does not depend on detections (plus the track's
        field at its first use if it was reset without a generator). ``track`` carries the
        episode's correlated error field (None: independent frames).
        """
        prm = self.params(quality)
        n = rng.standard_normal((4, 2))
        u = float(rng.random())
        c = features.corners
        if track is not None and prm.corr_max > 0.0:
            g = track.field(c, prm.corr_length_px, rng)
            z = math.sqrt(prm.corr_max) * g + math.sqrt(1.0 - prm.corr_max) * n
        else:
            z = n
        if features.margin < prm.min_margin_px:
            outside = image_margin(c[:, None, :], features.width, features.height)
            return None, (REASON_OUTSIDE if np.all(outside < 0.0) else REASON_BORDER)
        if features.cos_view < prm.min_cos_view:
            return None, REASON_OBLIQUE
        q = features.quiet_margin
        band = prm.band_fail_prob if prm.band_low_px <= q < prm.band_high_px else 0.0
        x = (features.min_side - prm.size50_px) / prm.size_width_px
        small = 1.0 / (1.0 + math.exp(min(max(x, -50.0), 50.0)))
        p_fail = (band, small, prm.miss_prob)
        if u >= (1.0 - p_fail[0]) * (1.0 - p_fail[1]) * (1.0 - p_fail[2]):
            return None, (REASON_QUIET_ZONE, REASON_SMALL, REASON_MISS)[int(np.argmax(p_fail))]
        mean, sd = prm.error_moments(features.basis, features.side, features.noise_ratio, features.blur_px)
        e = mean + sd * z
        return c + e[:, :1] * features.radial + e[:, 1:] * features.tangential, ""

    def __eq__(self, other: object) -> bool:
        """Equal contents (the parameters of every quality and the fit's record): a model loaded
        twice from one file equals itself."""
        if not isinstance(other, DetectorModel):
            return NotImplemented
        return self is other or self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]  # compared by contents

    # -- file (ihrcf_env.core.detector_model.file) ----------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The JSON object of the model file (:func:`~ihrcf_env.core.detector_model.file.model_to_dict`)."""
        from ihrcf_env.core.detector_model.file import model_to_dict

        return model_to_dict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str | None = None) -> DetectorModel:
        """The model of a :meth:`to_dict` mapping; ValueError / TypeError naming what is wrong
        (:func:`~ihrcf_env.core.detector_model.file.model_from_dict`)."""
        from ihrcf_env.core.detector_model.file import model_from_dict

        return model_from_dict(data, source)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model file to ``path``; returns the path
        (:func:`~ihrcf_env.core.detector_model.file.save_model`)."""
        from ihrcf_env.core.detector_model.file import save_model

        return save_model(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str] | None = None) -> DetectorModel:
        """Read a model file (default: the shipped one);
        :class:`~ihrcf_env.core.detector_model.file.DetectorModelError` naming the file and the fit
        command when it is missing, unreadable or malformed
        (:func:`~ihrcf_env.core.detector_model.file.load_model`)."""
        from ihrcf_env.core.detector_model.file import load_model

        return load_model(path)


__all__ = [
    "FIELD_FEATURES",
    "QUALITIES",
    "REASON_BORDER",
    "REASON_MISS",
    "REASON_OBLIQUE",
    "REASON_OUTSIDE",
    "REASON_QUIET_ZONE",
    "REASON_SMALL",
    "CornerTrack",
    "DetectorModel",
]
