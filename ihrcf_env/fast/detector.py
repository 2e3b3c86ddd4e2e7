"""The fitted detector model for one frame: the corners the rendered detector would report from the
true projected tag, or the status code of its failure; the port of
:meth:`ihrcf_env.core.detector_model.DetectorModel.corners` (and of the closed-form camera's
``sim.sensors.corner_model.model_corners``), with the episode's correlated error field of
:class:`~ihrcf_env.core.detector_model.CornerTrack`.

The draws (eight standard normals and one uniform per frame, the track's frequencies and phases per
episode) are inputs. Pixels in the OpenCV pixel-centre convention; status codes are the indices of
the tag-corner reading's status table (0: detected), :data:`STATUS_NAMES`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.detector_model import FIELD_FEATURES, QualityParams

__all__ = [
    "STATUS_BORDER",
    "STATUS_DEPTH",
    "STATUS_FRAME_LOST",
    "STATUS_MISS",
    "STATUS_NAMES",
    "STATUS_OBLIQUE",
    "STATUS_OUTSIDE",
    "STATUS_QUIET_ZONE",
    "STATUS_SMALL",
    "DetectorParams",
    "corner_field",
    "detect",
    "detector_params",
    "edge_margin",
    "quad_features",
]

#: The tag-corner reading's status names, indexed by status code (0: detected).
STATUS_NAMES: tuple[str, ...] = (
    "",
    "tag not detected",
    "tag outside the image",
    "tag partly outside the image",
    "tag partly outside the image (too close to its border)",
    "tag seen too obliquely",
    "tag's quiet zone cut by the image border",
    "tag too small in the image",
    "detector missed the tag",
    "tag outside the camera's depth range",
    "tag occluded",
    "camera frame lost",
)
STATUS_OUTSIDE = 2
STATUS_BORDER = 4
STATUS_OBLIQUE = 5
STATUS_QUIET_ZONE = 6
STATUS_SMALL = 7
STATUS_MISS = 8
STATUS_DEPTH = 9
STATUS_FRAME_LOST = 11


class DetectorParams(NamedTuple):
    """One camera quality's fitted parameters as arrays and constants (host-side,
    :func:`detector_params`): ``coef`` (N_BASIS, 4) on (mean radial, log s.d. radial, mean
    tangential, log s.d. tangential), the scalars of :class:`QualityParams` (px unless stated)."""

    coef: Array
    noise_gain: float
    blur_gain: float
    corr_max: float
    corr_length_px: float
    min_margin_px: float
    band_low_px: float
    band_high_px: float
    band_fail_prob: float
    size50_px: float
    size_width_px: float
    min_cos_view: float
    miss_prob: float


def detector_params(prm: QualityParams) -> DetectorParams:
    """The :class:`DetectorParams` of a fitted quality."""
    coef = np.array(
        [prm.mean_radial, prm.log_sd_radial, prm.mean_tangential, prm.log_sd_tangential], dtype=np.float64
    ).T
    return DetectorParams(
        jnp.asarray(coef),
        *(
            float(getattr(prm, f))
            for f in (
                "noise_gain",
                "blur_gain",
                "corr_max",
                "corr_length_px",
                "min_margin_px",
                "band_low_px",
                "band_high_px",
                "band_fail_prob",
                "size50_px",
                "size_width_px",
                "min_cos_view",
                "miss_prob",
            )
        ),
    )


def edge_margin(points: Array, width: int, height: int) -> Array:
    """Distance (px) of each of ``points`` (..., 2) to the image's outer edge (negative outside)."""
    u, v = points[..., 0], points[..., 1]
    return jnp.minimum(jnp.minimum(u + 0.5, width - 0.5 - u), jnp.minimum(v + 0.5, height - 0.5 - v))


def quad_features(corners: Array) -> tuple[Array, Array, Array, Array, Array]:
    """(radial (4, 2), tangential (4, 2), basis (4, N_BASIS), side (4,) px, shortest edge px) of the
    quad ``corners`` (4, 2) px: the outward bisector of each corner, it turned by +90 deg, the
    features of :data:`~ihrcf_env.core.detector_model.BASIS_NAMES`, the geometric mean of the two
    edges at each corner."""
    x, y = corners[:, 0], corners[:, 1]
    nxt, prv = jnp.array([1, 2, 3, 0]), jnp.array([3, 0, 1, 2])
    ex_out, ey_out = x[nxt] - x, y[nxt] - y
    ex_in, ey_in = x - x[prv], y - y[prv]
    l_out = jnp.maximum(jnp.hypot(ex_out, ey_out), 1e-9)
    l_in = jnp.maximum(jnp.hypot(ex_in, ey_in), 1e-9)
    uxo, uyo, uxi, uyi = ex_out / l_out, ey_out / l_out, ex_in / l_in, ey_in / l_in
    bx, by = uxi - uxo, uyi - uyo
    nb = jnp.maximum(jnp.hypot(bx, by), 1e-12)
    rx, ry = bx / nb, by / nb

    def sq(a: Array, b: Array) -> tuple[Array, Array]:
        return a * a - b * b, a * b + b * a

    def mul(a: Array, b: Array, c: Array, d: Array) -> tuple[Array, Array]:
        return a * c - b * d, a * d + b * c

    qo, qi = sq(*sq(uxo, uyo)), sq(*sq(uxi, uyi))  # exp(4 i a) of each edge
    q2o, q2i = sq(*qo), sq(*qi)
    h12o, h12i = mul(*q2o, *qo), mul(*q2i, *qi)
    h16o, h16i = sq(*q2o), sq(*q2i)
    side = jnp.sqrt(l_out * l_in)
    cos_angle = -(uxo * uxi + uyo * uyi)
    log_side = jnp.log(side / 100.0)
    basis = jnp.stack(
        [
            jnp.ones_like(side),
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
    return jnp.stack([rx, ry], axis=-1), jnp.stack([-ry, rx], axis=-1), basis, side, jnp.min(l_out)


def corner_field(omega: Array, phase: Array, corners: Array, length_px: float) -> Array:
    """The episode's correlated error field (4, 2) (unit variance) at ``corners`` (4, 2) px:
    ``omega`` (4, 2 * FIELD_FEATURES, 2) unit frequencies and ``phase`` (4, 2 * FIELD_FEATURES)
    rad drawn at the episode's start (:meth:`CornerTrack.reset
    <ihrcf_env.core.detector_model.CornerTrack.reset>`)."""
    arg = (omega[..., 0] * corners[:, None, 0] + omega[..., 1] * corners[:, None, 1]) * (
        math.sqrt(2.0) / length_px
    ) + phase
    out = jnp.cos(arg).reshape(4, 2, FIELD_FEATURES).sum(axis=-1)
    return out * math.sqrt(2.0 / FIELD_FEATURES)


def detect(
    prm: DetectorParams,
    corners: Array,
    quiet_zone: Array,
    cos_view: Array,
    width: int,
    height: int,
    noise_ratio: Array,
    blur_px: Array,
    normals: Array,
    uniform: Array,
    omega: Array,
    phase: Array,
) -> tuple[Array, Array]:
    """What the rendered detector reports for a frame with the true ``corners`` (4, 2) px and
    ``quiet_zone`` corners (4, 2) px, the viewing cosine, the realistic camera's ``noise_ratio``
    (scalar or (4,)) and motion blur ``blur_px``, given the frame's draws (``normals`` (4, 2),
    ``uniform``) and the episode's field (``omega``, ``phase``; unused when ``corr_max`` is 0).
    Returns the corners (4, 2) px (finite; meaningful only when detected) and the status code (0:
    detected; the failures of the border, the view angle and the probabilistic rules)."""
    radial, tangential, basis, side, min_side = quad_features(corners)
    margins = edge_margin(corners, width, height)
    margin = jnp.min(margins)
    quiet_margin = jnp.min(edge_margin(quiet_zone, width, height))
    if prm.corr_max > 0.0:
        g = corner_field(omega, phase, corners, prm.corr_length_px)
        z = math.sqrt(prm.corr_max) * g + math.sqrt(1.0 - prm.corr_max) * normals
    else:
        z = normals
    band = jnp.where(
        (prm.band_low_px <= quiet_margin) & (quiet_margin < prm.band_high_px), prm.band_fail_prob, 0.0
    )
    x = (min_side - prm.size50_px) / prm.size_width_px
    small = 1.0 / (1.0 + jnp.exp(jnp.clip(x, -50.0, 50.0)))
    miss = jnp.full_like(band, prm.miss_prob)
    rule = jnp.where(
        (band >= small) & (band >= miss),
        STATUS_QUIET_ZONE,
        jnp.where(small >= miss, STATUS_SMALL, STATUS_MISS),
    )
    status = jnp.where(uniform >= (1.0 - band) * (1.0 - small) * (1.0 - prm.miss_prob), rule, 0)
    status = jnp.where(cos_view < prm.min_cos_view, STATUS_OBLIQUE, status)
    outside = jnp.all(margins < 0.0)
    status = jnp.where(margin < prm.min_margin_px, jnp.where(outside, STATUS_OUTSIDE, STATUS_BORDER), status)
    M = basis @ prm.coef
    mean = M[:, 0::2]
    var = jnp.exp(2.0 * M[:, 1::2])
    if prm.noise_gain or prm.blur_gain:
        nr = jnp.broadcast_to(noise_ratio, side.shape)
        extra = (prm.noise_gain * nr) ** 2 * (100.0 / side) + (prm.blur_gain * blur_px) ** 2
        var = var + extra[:, None]
    e = mean + jnp.sqrt(var) * z
    out = corners + e[:, :1] * radial + e[:, 1:] * tangential
    out = jnp.where(jnp.isfinite(out), out, 0.0)
    return out, status.astype(jnp.int32)
