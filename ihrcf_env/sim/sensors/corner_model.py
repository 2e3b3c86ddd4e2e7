"""The detector model's corner errors and failures for N worlds at once (the corner tracks and
detector model of :class:`~ihrcf_env.sim.sensors.closed_form_camera.ClosedFormTagCamera`):
:func:`~ihrcf_env.core.detector_model.tag_features` and :meth:`DetectorModel.corners
<ihrcf_env.core.detector_model.DetectorModel.corners>` on stacks of frames, with each world's
correlated error field (:class:`CornerTracks`) and its own random generator.

Row n of every result is, bit for bit, what the scalar code returns for world n: the same
floating-point operations in the same order (the scalar per-frame path evaluates the corner
features in plain Python complex arithmetic, written out here on real and imaginary parts; the
logarithms and exponentials are Python's ``math`` ones), and each world's generator draws the same
numbers in the same order (8 normals and one uniform per read, then the track's field at its first
use). Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.detector_model import (
    FIELD_FEATURES,
    REASON_BORDER,
    REASON_MISS,
    REASON_OBLIQUE,
    REASON_OUTSIDE,
    REASON_QUIET_ZONE,
    REASON_SMALL,
    CornerTrack,
    QualityParams,
)
from ihrcf_env.sim.sensors.base import tag_status_code

#: ``tag_status`` codes of the model's failures: the probabilistic rules in their order (quiet zone,
#: size, miss), then the image border (all corners outside, some), the view angle.
_RULES = np.array([tag_status_code(r) for r in (REASON_QUIET_ZONE, REASON_SMALL, REASON_MISS)])
_OUTSIDE, _BORDER, _OBLIQUE = (tag_status_code(r) for r in (REASON_OUTSIDE, REASON_BORDER, REASON_OBLIQUE))


class CornerTracks:
    """The :class:`~ihrcf_env.core.detector_model.CornerTrack` of N worlds: ``omega`` (N, 4, 64, 2)
    unit frequencies, ``phase`` (N, 4, 64) rad and ``drawn`` (N,) (False: the world's field is drawn
    from its generator at its first use, as a track reset without a generator)."""

    def __init__(self, n: int) -> None:
        m = 2 * FIELD_FEATURES
        self.omega = np.zeros((n, 4, m, 2))
        self.phase = np.zeros((n, 4, m))
        self.drawn = np.zeros(n, dtype=bool)

    def __len__(self) -> int:
        return len(self.drawn)

    @classmethod
    def of(cls, tracks: Sequence[CornerTrack]) -> CornerTracks:
        """A copy of the scalar tracks' fields."""
        out = cls(len(tracks))
        for i, t in enumerate(tracks):
            if t.omega is not None and t.phase is not None:
                out.omega[i], out.phase[i], out.drawn[i] = t.omega, t.phase, True
        return out

    def reset(self, rngs: Sequence[np.random.Generator | None], rows: Sequence[int] | None = None) -> None:
        """:meth:`CornerTrack.reset <ihrcf_env.core.detector_model.CornerTrack.reset>` of the worlds
        ``rows`` (default all), world ``rows[k]`` from ``rngs[k]`` (None: forget its field)."""
        for i, rng in zip(range(len(self)) if rows is None else rows, rngs, strict=True):
            if rng is None:
                self.drawn[i] = False
            else:
                self._draw(i, rng)

    def _draw(self, i: int, rng: np.random.Generator) -> None:
        m = 2 * FIELD_FEATURES
        self.omega[i] = rng.standard_normal((4, m, 2))
        self.phase[i] = rng.uniform(0.0, 2.0 * math.pi, (4, m))
        self.drawn[i] = True

    def track(self, i: int) -> CornerTrack:
        """A scalar copy of world ``i``'s track."""
        t = CornerTrack()
        if self.drawn[i]:
            t.omega, t.phase = self.omega[i].copy(), self.phase[i].copy()
        return t

    def field(self, corners: NDArray[np.float64], length_px: float) -> NDArray[np.float64]:
        """The fields (N, 4, 2) at the corners (N, 4, 2) px (as ``CornerTrack.field``)."""
        arg = (self.omega @ corners[..., None])[..., 0] * (math.sqrt(2.0) / length_px) + self.phase
        n = len(self)
        out: NDArray[np.float64] = np.cos(arg).reshape(n, 4, 2, FIELD_FEATURES).sum(axis=-1)
        return out * math.sqrt(2.0 / FIELD_FEATURES)


def quad_features(
    corners: NDArray[np.float64], width: int, height: int
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
]:
    """(radial (N, 4, 2), tangential (N, 4, 2), basis (N, 4, N_BASIS), side (N, 4) px, margin (N,) px,
    shortest edge (N,) px) of the quads ``corners`` (N, 4, 2) px, as the scalar per-frame path
    (``features._one_quad``) computes them."""
    x, y = corners[..., 0], corners[..., 1]
    ex_out, ey_out = x[:, [1, 2, 3, 0]] - x, y[:, [1, 2, 3, 0]] - y
    ex_in, ey_in = x - x[:, [3, 0, 1, 2]], y - y[:, [3, 0, 1, 2]]
    l_out = np.maximum(np.hypot(ex_out, ey_out), 1e-9)
    l_in = np.maximum(np.hypot(ex_in, ey_in), 1e-9)
    uxo, uyo, uxi, uyi = ex_out / l_out, ey_out / l_out, ex_in / l_in, ey_in / l_in
    bx, by = uxi - uxo, uyi - uyo
    nb = np.maximum(np.hypot(bx, by), 1e-12)
    rx, ry = bx / nb, by / nb

    def sq(a: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return a * a - b * b, a * b + b * a

    def mul(
        a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64], d: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return a * c - b * d, a * d + b * c

    qo, qi = sq(*sq(uxo, uyo)), sq(*sq(uxi, uyi))  # exp(4 i a) of each edge
    q2o, q2i = sq(*qo), sq(*qi)
    h12o, h12i = mul(*q2o, *qo), mul(*q2i, *qi)
    h16o, h16i = sq(*q2o), sq(*q2i)
    side = np.sqrt(l_out * l_in)
    cos_angle = -(uxo * uxi - uyo * -uyi)
    log_side = np.array(list(map(math.log, (side / 100.0).ravel().tolist()))).reshape(side.shape)
    basis = np.stack(
        [
            np.ones_like(side),
            log_side,
            *(0.5 * (qo[k] + qi[k]) for k in (0, 1)),
            *(0.5 * (q2o[k] + q2i[k]) for k in (0, 1)),
            cos_angle,
            log_side * log_side,
            *(0.5 * (h12o[k] + h12i[k]) for k in (0, 1)),
            *(0.5 * (h16o[k] + h16i[k]) for k in (0, 1)),
        ],
        axis=-1,
    )
    margin = edge_margin(corners, width, height).min(axis=1)
    return (
        np.stack([rx, ry], axis=-1),
        np.stack([-ry, rx], axis=-1),
        basis,
        side,
        margin,
        l_out.min(axis=1),
    )


def edge_margin(points: NDArray[np.float64], width: int, height: int) -> NDArray[np.float64]:
    """Distance (px) of each of ``points`` (..., 2) to the image's outer edge (negative outside)."""
    u, v = points[..., 0], points[..., 1]
    out: NDArray[np.float64] = np.minimum(
        np.minimum(u + 0.5, width - 0.5 - u), np.minimum(v + 0.5, height - 0.5 - v)
    )
    return out


def model_corners(
    prm: QualityParams,
    corners: NDArray[np.float64],
    quiet_zone: NDArray[np.float64],
    cos_view: NDArray[np.float64],
    width: int,
    height: int,
    noise_ratio: NDArray[np.float64] | float,
    blur_px: NDArray[np.float64] | float,
    normals: NDArray[np.float64],
    uniforms: NDArray[np.float64],
    track: CornerTracks,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:meth:`DetectorModel.corners <ihrcf_env.core.detector_model.DetectorModel.corners>` of N
    frames, the true corners (N, 4, 2) and quiet-zone corners (N, 4, 2) px, given each world's draws
    (``normals`` (N, 4, 2), ``uniforms`` (N,)) and ``track`` (every row's field drawn already when
    ``corr_max`` > 0). Returns the corners (N, 4, 2) px (garbage where not detected) and the
    :data:`~ihrcf_env.sim.sensors.base.TAG_STATUS` code of each row (0: detected)."""
    radial, tangential, basis, side, margin, min_side = quad_features(corners, width, height)
    quiet_margin = edge_margin(quiet_zone, width, height).min(axis=1)
    if prm.corr_max > 0.0:
        g = track.field(corners, prm.corr_length_px)
        z = math.sqrt(prm.corr_max) * g + math.sqrt(1.0 - prm.corr_max) * normals
    else:
        z = normals
    band = np.where(
        (prm.band_low_px <= quiet_margin) & (quiet_margin < prm.band_high_px), prm.band_fail_prob, 0.0
    )
    x = (min_side - prm.size50_px) / prm.size_width_px
    small = 1.0 / (1.0 + np.array([math.exp(min(max(v, -50.0), 50.0)) for v in x.tolist()]))
    p_fail = np.stack([band, small, np.full_like(band, prm.miss_prob)], axis=1)
    rule = _RULES[np.argmax(p_fail, axis=1)]
    status = np.where(uniforms >= (1.0 - band) * (1.0 - small) * (1.0 - prm.miss_prob), rule, 0)
    status = np.where(cos_view < prm.min_cos_view, _OBLIQUE, status)
    outside = np.all(edge_margin(corners, width, height) < 0.0, axis=1)
    status = np.where(margin < prm.min_margin_px, np.where(outside, _OUTSIDE, _BORDER), status)
    nr = np.broadcast_to(np.asarray(noise_ratio, dtype=np.float64), side.shape)
    blur = np.broadcast_to(np.asarray(blur_px, dtype=np.float64)[..., None], side.shape)
    mean, sd = prm.error_moments(basis, side, nr, blur)
    e = mean + sd * z
    return corners + e[..., :1] * radial + e[..., 1:] * tangential, status.astype(np.int64)


__all__ = [
    "CornerTracks",
    "edge_margin",
    "model_corners",
    "quad_features",
]
