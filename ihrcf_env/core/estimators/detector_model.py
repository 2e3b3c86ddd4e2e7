"""A statistical model of the tag detector: what :class:`~ihrcf_env.core.estimators.TagDetector`
(``refine="subpix"``) reports on a rendered frame, from the exact projection of the tag's corners.

Rendering a 512x512 frame costs ~45 ms; a learner needing 1e6 steps cannot afford it. The
"projected" camera (:class:`ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera`) renders nothing:
it projects the tag's corners through the true camera and asks this model for the corners the
rendered pipeline would have produced, or for the reason it would have failed. Pure numpy (no
simulator): the same model can corrupt corners projected from logged poses.

**Corner error** (measured on rendered frames, see ``python -m ihrcf_env.fit_detector``). Each
corner's error is expressed in its local frame: ``r`` the outward bisector of the corner's angle,
``t`` = ``r`` turned by +90 deg (image axes). In that frame the error is Gaussian and independent
between corners and components, with mean and log standard deviation linear in the corner's
features (:func:`corner_basis`): 1, ``log(L / 100 px)`` and its square (``L`` the geometric mean
of the two adjacent edge lengths, px), the first four harmonics of the edges' angle to the pixel
grid (``cos 4ka, sin 4ka``, k = 1..4, averaged over the two edges) and the cosine of the corner's
interior angle (perspective: 0 for a right angle). The renderer's edges are
staircases whose bias depends on that angle: the corners come out ~0.2 px inside the tag (a
radial bias that grows with ``L``, which shrinks the tag and biases depth), and shifted along
``t`` by up to ~0.2 px depending on the sign of the edges' tilt to the pixel grid. The realistic
camera adds variance ``(noise_gain * noise_ratio)^2 * 100 / L + (blur_gain * blur_px)^2``
(``noise_ratio``: temporal noise at mid-grey over the white level of the tag, from the episode's
exposure, gain and light; ``blur_px``: the image motion during the exposure), both fitted: the
IMX296's 2-4 DN add only ~0.05 px (sub-pixel refinement averages them out), the blur ~0.05 px per
px of motion. The error is fitted on the frames of both qualities together (the renderer's
aliasing is the same) and on the operating range (corner angles 60-120 deg, edges >= 20 px); the
small-tag and oblique frames only set the detection limits. Shipped fit (seed 0, 2 x 1200
frames): radial bias -0.19 px and s.d. 0.21 (radial) / 0.27 px (tangential) at L = 100 px.

**Temporal correlation**. The rendered error is a function of where the corners fall on the pixel
grid: the same pose gives the same error, and errors of a corner ``D`` px apart in two frames of
a track (however far apart in time) are correlated by ``corr_max * exp(-(D / corr_length_px)^2)``
(measured: ~0.7 at 0.05 px, ~0.4 at 0.15 px, ~0.07 at 0.3 px, ~0 beyond; the same at 0.3 px
accumulated over several slow frames, so a Markov chain of per-frame steps would keep a hovering
drone's error for far too long; shipped fit ``corr_max`` 0.88, ``corr_length_px`` 0.16). The
pose-dependent mean is correlated by construction. The normalised remainder is
``sqrt(corr_max)`` times a smooth random field over the image position (:class:`CornerTrack`:
random Fourier features with that Gaussian covariance, drawn per episode) plus
``sqrt(1 - corr_max)`` white noise. A drone hovering over a slowly moving deck therefore sees
slowly varying errors that a filter cannot average away, as with the renderer.

**Detection failures** (rules fitted per camera quality): the tag's black square closer than
``min_margin_px`` to the image border (or outside it); the outer edge of the white quiet zone
inside the image by ``band_low_px``..``band_high_px`` (the detector then loses the tag to its nested
quads: fails with probability ``band_fail_prob``); the tag too small (logistic in the shortest
side, ``size50_px``, ``size_width_px``); seen too obliquely (``cos_view < min_cos_view``); and a
residual ``miss_prob``. Occlusion and the camera's depth range are the simulator's job (ray casts).

The fitted parameters live in ``assets/detector_model.json`` (:func:`default_detector_model_path`),
re-made with ``python -m ihrcf_env.fit_detector``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.paths import assets_dir

#: The command that (re)makes the detector model file.
FIT_COMMAND = "python -m ihrcf_env.fit_detector"
#: File format tag and version of :meth:`DetectorModel.save`.
FORMAT_NAME = "ihrcf_env detector model"
FORMAT_VERSION = 1
#: Camera qualities the model covers (:data:`ihrcf_env.sim.sensors.camera.CAMERA_QUALITIES`).
QUALITIES: tuple[str, ...] = ("ideal", "realistic")
#: Outer edge of the tag's white quiet zone, in units of the tag size (one cell of eight each side).
QUIET_ZONE_SCALE = 1.25
#: Names of the per-corner features (columns of :func:`corner_basis`).
BASIS_NAMES: tuple[str, ...] = (
    "1",
    "log(L/100px)",
    "cos4a",
    "sin4a",
    "cos8a",
    "sin8a",
    "cos(angle)",
    "log(L/100px)^2",
    "cos12a",
    "sin12a",
    "cos16a",
    "sin16a",
)
N_BASIS = len(BASIS_NAMES)

#: Failure reasons (``reason`` of :meth:`DetectorModel.corners`).
REASON_OUTSIDE = "tag outside the image"
REASON_BORDER = "tag partly outside the image (too close to its border)"
REASON_OBLIQUE = "tag seen too obliquely"
REASON_QUIET_ZONE = "tag's quiet zone cut by the image border"
REASON_SMALL = "tag too small in the image"
REASON_MISS = "detector missed the tag"


class DetectorModelError(ValueError):
    """A detector model file is missing, unreadable or malformed (the message names the file and
    the command that re-makes it)."""


def default_detector_model_path() -> Path:
    """The detector model shipped with the package (``assets/detector_model.json``)."""
    return assets_dir() / "detector_model.json"


# -- geometry ---------------------------------------------------------------------------------------
def project_points(
    points_cam: ArrayLike, K: ArrayLike, distortion: tuple[float, float] = (0.0, 0.0)
) -> NDArray[np.float64]:
    """Pixels (N, 2) (OpenCV pixel-centre convention) of camera-frame points (N, 3) (m, OpenCV
    camera frame, z > 0) through ``K`` (3, 3) and radial distortion ``(k1, k2)``:
    ``x_d = x (1 + k1 r^2 + k2 r^4)`` (OpenCV's model, as the simulated lens)."""
    P = np.asarray(points_cam, dtype=np.float64)
    Km = np.asarray(K, dtype=np.float64)
    x = P[:, 0] / P[:, 2]
    y = P[:, 1] / P[:, 2]
    k1, k2 = distortion
    if k1 or k2:
        r2 = x * x + y * y
        s = 1.0 + k1 * r2 + k2 * r2 * r2
        x, y = x * s, y * s
    return np.column_stack([Km[0, 0] * x + Km[0, 1] * y + Km[0, 2], Km[1, 1] * y + Km[1, 2]])


def image_margin(points: ArrayLike, width: int, height: int) -> NDArray[np.float64]:
    """Distance (px) of the nearest of ``points`` (..., N, 2) to the image's outer edge (pixel
    centres at integers, the image spans [-0.5, W - 0.5] x [-0.5, H - 0.5]); negative outside."""
    p = np.asarray(points, dtype=np.float64)
    u, v = p[..., 0], p[..., 1]
    m = np.minimum(np.minimum(u + 0.5, width - 0.5 - u), np.minimum(v + 0.5, height - 0.5 - v))
    out: NDArray[np.float64] = m.min(axis=-1)
    return out


def corner_basis(
    corners: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Local frames and features of the corners (..., 4, 2) of a convex quad (px).

    Returns ``(radial, tangential, basis, side)``: the outward bisector of each corner's angle and
    that turned by +90 deg (..., 4, 2) (unit vectors, image axes); the features (..., 4,
    :data:`N_BASIS`) named by :data:`BASIS_NAMES`; the geometric mean ``L`` of the two edges at each
    corner (..., 4) px.
    """
    c = np.asarray(corners, dtype=np.float64)
    z = c[..., 0] + 1j * c[..., 1]  # corners as complex numbers
    e_out = z[..., [1, 2, 3, 0]] - z
    e_in = z - z[..., [3, 0, 1, 2]]
    l_out = np.maximum(np.abs(e_out), 1e-9)
    l_in = np.maximum(np.abs(e_in), 1e-9)
    u_out, u_in = e_out / l_out, e_in / l_in
    s = u_in - u_out  # outward bisector (unnormalised)
    r = s / np.maximum(np.abs(s), 1e-12)
    radial = np.stack([r.real, r.imag], axis=-1)
    tangential = np.stack([-r.imag, r.real], axis=-1)
    side = np.sqrt(l_out * l_in)
    q_out, q_in = u_out**4, u_in**4  # exp(4 i a) of each edge
    h4 = 0.5 * (q_out + q_in)
    h8 = 0.5 * (q_out**2 + q_in**2)
    h12 = 0.5 * (q_out**3 + q_in**3)
    h16 = 0.5 * (q_out**4 + q_in**4)
    cos_angle = -(u_out * np.conj(u_in)).real  # interior angle of the corner
    log_side = np.log(side / 100.0)
    basis = np.stack(
        [
            np.ones_like(side),
            log_side,
            h4.real,
            h4.imag,
            h8.real,
            h8.imag,
            cos_angle,
            log_side * log_side,
            h12.real,
            h12.imag,
            h16.real,
            h16.imag,
        ],
        axis=-1,
    )
    return radial, tangential, basis, side


def noise_to_contrast(
    white_dn: ArrayLike, electrons_per_dn: float, read_noise_e: float
) -> NDArray[np.float64]:
    """Temporal noise s.d. at half the white level over the white level (tag black is 0 DN):
    ``sqrt((read / g)^2 + (W / 2) / g) / W`` for white level ``W`` (DN, floored at 1) and ``g``
    electrons per DN."""
    w = np.maximum(np.asarray(white_dn, dtype=np.float64), 1.0)
    g = float(electrons_per_dn)
    out: NDArray[np.float64] = np.sqrt((read_noise_e / g) ** 2 + 0.5 * w / g) / w
    return out


@dataclass(frozen=True, eq=False)
class TagFeatures:
    """What drives the detector on one frame, from the true projected tag (see
    :func:`tag_features`). Pixels in the (distorted) image, OpenCV pixel-centre convention."""

    corners: NDArray[np.float64]  # (4, 2) true corners, TagDetector's order
    quiet_zone: NDArray[np.float64]  # (4, 2) outer corners of the white quiet zone
    cos_view: float  # |cos| of the angle between the tag normal and the line of sight to its centre
    width: int
    height: int
    noise_ratio: NDArray[np.float64]  # (4,) noise s.d. at mid-grey / white level (0: ideal camera)
    blur_px: float  # image motion during the exposure (px; 0: none)
    radial: NDArray[np.float64]  # (4, 2) see corner_basis
    tangential: NDArray[np.float64]  # (4, 2)
    basis: NDArray[np.float64]  # (4, N_BASIS)
    side: NDArray[np.float64]  # (4,) px
    margin: float  # image_margin of the corners, px
    quiet_margin: float  # image_margin of the quiet zone's corners, px
    min_side: float  # shortest edge, px


def _one_quad(
    corners: NDArray[np.float64], width: int, height: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    """:func:`corner_basis` of one quad (4, 2) in plain Python (the per-frame path: ~10x faster than
    numpy on four points), plus its :func:`image_margin` and shortest edge."""
    z = [complex(x, y) for x, y in corners.tolist()]
    radial: list[list[float]] = []
    tangential: list[list[float]] = []
    basis: list[list[float]] = []
    side: list[float] = []
    lengths: list[float] = []
    for i in range(4):
        e_out, e_in = z[(i + 1) % 4] - z[i], z[i] - z[i - 1]
        l_out, l_in = max(abs(e_out), 1e-9), max(abs(e_in), 1e-9)
        u_out, u_in = e_out / l_out, e_in / l_in
        b = u_in - u_out
        r = b / max(abs(b), 1e-12)
        radial.append([r.real, r.imag])
        tangential.append([-r.imag, r.real])
        q_out, q_in = (u_out * u_out) ** 2, (u_in * u_in) ** 2
        q2_out, q2_in = q_out * q_out, q_in * q_in
        h4, h8 = 0.5 * (q_out + q_in), 0.5 * (q2_out + q2_in)
        h12, h16 = 0.5 * (q2_out * q_out + q2_in * q_in), 0.5 * (q2_out * q2_out + q2_in * q2_in)
        L = math.sqrt(l_out * l_in)
        side.append(L)
        lengths.append(l_out)
        cos_angle = -(u_out * u_in.conjugate()).real
        log_side = math.log(L / 100.0)
        basis.append(
            [
                *(1.0, log_side, h4.real, h4.imag, h8.real, h8.imag, cos_angle, log_side * log_side),
                *(h12.real, h12.imag, h16.real, h16.imag),
            ]
        )
    margin = min(min(p.real + 0.5, width - 0.5 - p.real, p.imag + 0.5, height - 0.5 - p.imag) for p in z)
    return np.array(radial), np.array(tangential), np.array(basis), np.array(side), margin, min(lengths)


def tag_features(
    corners: ArrayLike,
    quiet_zone: ArrayLike,
    cos_view: float,
    width: int,
    height: int,
    noise_ratio: ArrayLike = 0.0,
    blur_px: float = 0.0,
) -> TagFeatures:
    """:class:`TagFeatures` of a frame: the tag's true corners (4, 2) px and its quiet zone's outer
    corners (4, 2) px in the image of ``width`` x ``height`` px, the viewing cosine, the realistic
    camera's ``noise_ratio`` (scalar or (4,), :func:`noise_to_contrast`) and motion blur (px)."""
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    q = np.asarray(quiet_zone, dtype=np.float64).reshape(4, 2)
    w, h = int(width), int(height)
    radial, tangential, basis, side, margin, min_side = _one_quad(c, w, h)
    qu, qv = q[:, 0].tolist(), q[:, 1].tolist()
    quiet_margin = min(min(u + 0.5, w - 0.5 - u, v + 0.5, h - 0.5 - v) for u, v in zip(qu, qv, strict=True))
    nr = np.asarray(noise_ratio, dtype=np.float64)
    return TagFeatures(
        corners=c,
        quiet_zone=q,
        cos_view=float(cos_view),
        width=w,
        height=h,
        noise_ratio=nr if nr.shape == (4,) else np.full(4, float(nr)),
        blur_px=float(blur_px),
        radial=radial,
        tangential=tangential,
        basis=basis,
        side=side,
        margin=margin,
        quiet_margin=quiet_margin,
        min_side=min_side,
    )


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


# -- parameters -------------------------------------------------------------------------------------
def _check_number(name: str, value: object, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{name} must be finite and in [{lo}, {hi}], got {value!r}")
    return v


_COEFFICIENTS = ("mean_radial", "log_sd_radial", "mean_tangential", "log_sd_tangential")
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


@dataclass(frozen=True)
class QualityParams:
    """Fitted detector parameters of one camera quality (see the module docstring; px unless
    stated). The four coefficient tuples have :data:`N_BASIS` entries, on :data:`BASIS_NAMES`."""

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
        for name in _COEFFICIENTS:
            value = getattr(self, name)
            if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
                raise TypeError(f"{name} must be a sequence of {N_BASIS} numbers, got {value!r}")
            if len(value) != N_BASIS:
                raise ValueError(f"{name} must have {N_BASIS} coefficients, got {len(value)}")
            object.__setattr__(
                self, name, tuple(_check_number(f"{name}[{i}]", v, -50.0, 50.0) for i, v in enumerate(value))
            )
        for name, (lo, hi) in _LIMITS.items():
            object.__setattr__(self, name, _check_number(name, getattr(self, name), lo, hi))
        if self.band_high_px < self.band_low_px:
            raise ValueError(
                f"band_high_px ({self.band_high_px}) must be >= band_low_px ({self.band_low_px})"
            )
        coef = np.array([getattr(self, name) for name in _COEFFICIENTS]).T  # (N_BASIS, 4)
        coef.setflags(write=False)
        object.__setattr__(self, "_coef", coef)

    def to_dict(self) -> dict[str, Any]:
        return {
            f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> QualityParams:
        if not isinstance(data, Mapping):
            raise TypeError(f"quality parameters must be a mapping, got {type(data).__name__}")
        names = {f.name for f in fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown parameters {sorted(unknown)}")
        missing = set(_COEFFICIENTS) - set(data)
        if missing:
            raise ValueError(f"missing parameters {sorted(missing)}")
        kwargs: dict[str, Any] = {
            k: (tuple(v) if k in _COEFFICIENTS and isinstance(v, list) else v) for k, v in data.items()
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
                raise TypeError(f"qualities[{q!r}] must be a QualityParams, got {type(prm).__name__}")
        if not isinstance(self.fit, Mapping):
            raise TypeError(f"fit must be a mapping, got {type(self.fit).__name__}")

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

    # -- file ----------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "fit_command": FIT_COMMAND,
            "qualities": {q: p.to_dict() for q, p in self.qualities.items()},
            "fit": dict(self.fit),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str | None = None) -> DetectorModel:
        """The model of a :meth:`to_dict` mapping; ValueError/TypeError naming what is wrong."""
        if not isinstance(data, Mapping):
            raise TypeError(f"a detector model must be a JSON object, got {type(data).__name__}")
        if data.get("format") != FORMAT_NAME:
            raise ValueError(f"'format' must be {FORMAT_NAME!r}, got {data.get('format')!r}")
        if data.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"'format_version' must be {FORMAT_VERSION}, got {data.get('format_version')!r}")
        qualities = data.get("qualities")
        if not isinstance(qualities, Mapping):
            raise TypeError(f"'qualities' must be an object, got {type(qualities).__name__}")
        params = {}
        for q, p in qualities.items():
            try:
                params[str(q)] = QualityParams.from_dict(p)
            except (TypeError, ValueError) as e:
                raise type(e)(f"qualities[{q!r}]: {e}") from None
        fit = data.get("fit", {})
        return cls(qualities=params, fit=fit if isinstance(fit, Mapping) else {}, source=source)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model as JSON (small: a few kB) to ``path``; returns the path."""
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n", encoding="utf-8")
        return out

    @classmethod
    def load(cls, path: str | os.PathLike[str] | None = None) -> DetectorModel:
        """Read a model file (default: the shipped one). :class:`DetectorModelError` naming the
        file and the fit command when it is missing, unreadable or malformed."""
        p = Path(path) if path is not None else default_detector_model_path()
        try:
            text = p.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise DetectorModelError(
                f"{p}: detector model file not found; create it with {FIT_COMMAND} --out {p}"
            ) from None
        except (OSError, UnicodeDecodeError) as e:
            raise DetectorModelError(
                f"{p}: cannot read the detector model file ({e}); re-create it with {FIT_COMMAND} --out {p}"
            ) from e
        try:
            data = json.loads(text, parse_constant=_reject_constant)
            return cls.from_dict(data, source=str(p))
        except (ValueError, TypeError) as e:
            raise DetectorModelError(
                f"{p}: not a valid detector model file ({e}); re-create it with {FIT_COMMAND} --out {p}"
            ) from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} in JSON")


# -- fitting ----------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class DetectorSamples:
    """Rendered frames of one camera quality paired with their projected features, for
    :func:`fit_quality`. Frames of one track are consecutive control steps and consecutive in the
    arrays (the fit of the temporal correlation uses neighbours with the same ``track``).

    Attributes:
        corners, quiet_zone: (N, 4, 2) true projected corners of the tag and of its quiet zone, px.
        cos_view: (N,) viewing cosine. noise_ratio: (N, 4). blur_px: (N,).
        detected: (N, 4, 2) TagDetector's corners, NaN where it found nothing.
        track: (N,) int track id. width, height: image size (px).
    """

    corners: NDArray[np.float64]
    quiet_zone: NDArray[np.float64]
    cos_view: NDArray[np.float64]
    noise_ratio: NDArray[np.float64]
    blur_px: NDArray[np.float64]
    detected: NDArray[np.float64]
    track: NDArray[np.int64]
    width: int
    height: int

    def __post_init__(self) -> None:
        n = np.asarray(self.corners).shape[0]
        shapes = {
            "corners": (n, 4, 2),
            "quiet_zone": (n, 4, 2),
            "cos_view": (n,),
            "noise_ratio": (n, 4),
            "blur_px": (n,),
            "detected": (n, 4, 2),
            "track": (n,),
        }
        for name, shape in shapes.items():
            a = np.asarray(getattr(self, name), dtype=np.int64 if name == "track" else np.float64)
            if a.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
            object.__setattr__(self, name, a)

    @property
    def found(self) -> NDArray[np.bool_]:
        """(N,) frames where the detector found the tag."""
        out: NDArray[np.bool_] = np.logical_not(np.isnan(self.detected).any(axis=(1, 2)))
        return out


#: Detected corners further than this from the projection are not used to fit the noise (px).
OUTLIER_PX = 5.0
#: Frames up to this many steps apart within a track inform the fit of the correlation.
MAX_LAG = 5
#: The noise is fitted on frames whose corners' interior angles are within acos(+-0.5) = 60..120 deg
#: and whose shortest edge is at least 20 px: the operating range (the small-tag and oblique frames
#: only fit the detection limits; beyond the range the linear features extrapolate).
NOISE_FIT_MAX_COS_ANGLE = 0.5
NOISE_FIT_MIN_SIDE_PX = 20.0


def _noise_nll(
    theta: NDArray[np.float64],
    X: NDArray[np.float64],
    y: NDArray[np.float64],
    extra_n: NDArray[np.float64],
    extra_b: NDArray[np.float64],
    with_extra: bool,
) -> tuple[float, NDArray[np.float64]]:
    """Gaussian negative log-likelihood (and gradient) of the corner errors ``y`` (M, 2) along
    (radial, tangential) with features ``X`` (M, N_BASIS)."""
    p = N_BASIS
    total = 0.0
    grad = np.zeros_like(theta)
    cn, cb = (theta[4 * p], theta[4 * p + 1]) if with_extra else (0.0, 0.0)
    g_cn = g_cb = 0.0
    for k in range(2):
        beta = theta[2 * k * p : (2 * k + 1) * p]
        gamma = theta[(2 * k + 1) * p : (2 * k + 2) * p]
        mu = X @ beta
        base = np.exp(2.0 * (X @ gamma))
        s2 = base + cn * cn * extra_n + cb * cb * extra_b
        r = y[:, k] - mu
        total += float(np.sum(0.5 * np.log(s2) + 0.5 * r * r / s2))
        grad[2 * k * p : (2 * k + 1) * p] = -(r / s2) @ X
        w = 0.5 / s2 - 0.5 * r * r / (s2 * s2)
        grad[(2 * k + 1) * p : (2 * k + 2) * p] = (w * 2.0 * base) @ X
        g_cn += float(np.sum(w * 2.0 * cn * extra_n))
        g_cb += float(np.sum(w * 2.0 * cb * extra_b))
    if with_extra:
        grad[4 * p], grad[4 * p + 1] = g_cn, g_cb
    return total, grad


def _bernoulli_nll(detected: NDArray[np.bool_], p: NDArray[np.float64]) -> float:
    q = np.clip(p, 1e-9, 1.0 - 1e-9)
    return float(-np.sum(np.where(detected, np.log(q), np.log1p(-q))))


def _best_threshold(values: NDArray[np.float64], ok: NDArray[np.bool_], grid: NDArray[np.float64]) -> float:
    """The threshold ``c`` of the rule "detected iff value >= c" that agrees with ``ok`` most often
    (the middle of the best run of grid points)."""
    if values.size == 0:
        return float(grid[0])
    agree = np.array([np.sum((values >= c) == ok) for c in grid])
    best = np.flatnonzero(agree == agree.max())
    run = best[: np.argmax(np.diff(np.append(best, best[-1] + 2)) > 1) + 1]  # first run of maxima
    return float(grid[run[len(run) // 2]])


def fit_quality(samples: DetectorSamples, with_extra: bool) -> tuple[QualityParams, dict[str, Any]]:
    """Fit :class:`QualityParams` to rendered frames (see the module docstring for the model and
    :func:`ihrcf_env.cli.fit_detector` for the frames); ``with_extra`` fits the noise and blur gains
    (the realistic camera). Returns the parameters and a small report (counts and checks)."""
    from scipy.optimize import minimize

    s = samples
    radial, tangential, basis, side = corner_basis(s.corners)
    margin = image_margin(s.corners, s.width, s.height)
    qmargin = image_margin(s.quiet_zone, s.width, s.height)
    edges = s.corners[:, [1, 2, 3, 0]] - s.corners
    min_side = np.hypot(edges[..., 0], edges[..., 1]).min(axis=1)
    found = s.found
    err = np.where(found[:, None, None], s.detected - s.corners, 0.0)
    y = np.stack([(err * radial).sum(-1), (err * tangential).sum(-1)], axis=-1)  # (N, 4, 2)
    operating = (np.abs(basis[..., 6]).max(axis=1) <= NOISE_FIT_MAX_COS_ANGLE) & (
        min_side >= NOISE_FIT_MIN_SIDE_PX
    )
    use = found & operating & (np.abs(err).max(axis=(1, 2)) < OUTLIER_PX)
    report: dict[str, Any] = {
        "frames": int(len(found)),
        "detected": int(found.sum()),
        "noise_frames": int(use.sum()),
        "outliers": int((found & operating & ~use).sum()),
    }

    # 1. corner error: mean and log s.d. on the basis, plus the realistic camera's extra variance
    X = basis[use].reshape(-1, N_BASIS)
    Y = y[use].reshape(-1, 2)
    # the noise ratio in percent (gain ~ 0.1-1): a well-scaled problem for the optimiser
    extra_n = (100.0 * s.noise_ratio[use].reshape(-1)) ** 2 * (100.0 / side[use].reshape(-1))
    extra_b = np.repeat(s.blur_px[use], 4) ** 2
    p = N_BASIS
    theta0 = np.zeros(4 * p + 2)
    for k in range(2):
        theta0[2 * k * p] = float(Y[:, k].mean())
        theta0[(2 * k + 1) * p] = math.log(float(Y[:, k].std()) + 1e-6)
    theta0[4 * p :] = 0.01
    bounds = [(None, None)] * (4 * p) + [(0.0, None)] * 2
    res = minimize(
        _noise_nll,
        theta0 if with_extra else theta0[: 4 * p],
        args=(X, Y, extra_n, extra_b, with_extra),
        jac=True,
        method="L-BFGS-B",
        bounds=bounds if with_extra else None,
        options={"maxiter": 2000},
    )
    theta = np.asarray(res.x)
    coef = [tuple(float(v) for v in theta[i * p : (i + 1) * p]) for i in range(4)]
    noise_gain, blur_gain = (
        (100.0 * float(theta[4 * p]), float(theta[4 * p + 1])) if with_extra else (0.0, 0.0)
    )
    draft = QualityParams(coef[0], coef[1], coef[2], coef[3], noise_gain=noise_gain, blur_gain=blur_gain)
    mean, sd = draft.error_moments(basis, side, s.noise_ratio, s.blur_px[:, None])
    z = (y - mean) / sd  # (N, 4, 2), meaningful where `use`
    zu = z[use].reshape(-1, 2)
    report["noise_fit_converged"] = bool(res.success)
    report["normalised_sd"] = [float(v) for v in zu.std(axis=0)]
    report["normalised_kurtosis"] = [float(v) for v in (zu**4).mean(axis=0) / (zu**2).mean(axis=0) ** 2]
    report["raw_mean_xy_px"] = [float(v) for v in err[use].reshape(-1, 2).mean(axis=0)]
    report["raw_rms_px"] = float(np.sqrt((err[use] ** 2).mean()))

    # 2. correlation of the normalised error between frames of a track, against the corners' image
    # displacement between them (pairs up to MAX_LAG frames apart: a function of the displacement,
    # not a Markov chain of small steps)
    ii, jj = [], []
    for lag in range(1, MAX_LAG + 1):
        ok = use[:-lag] & use[lag:] & (s.track[:-lag] == s.track[lag:])
        i = np.flatnonzero(ok)
        ii.append(i)
        jj.append(i + lag)
    i0, i1 = np.concatenate(ii), np.concatenate(jj)
    d = np.hypot(*(s.corners[i1] - s.corners[i0]).transpose(2, 0, 1))  # (pairs, 4)
    dd = np.repeat(d[..., None], 2, axis=-1).ravel()
    a, b = z[i0].ravel(), z[i1].ravel()
    near_pairs = dd < 1.0  # beyond 1 px the correlation is ~0: only the near pairs inform the fit

    def corr_nll(v: NDArray[np.float64]) -> float:
        rho = v[0] * np.exp(-((dd[near_pairs] / v[1]) ** 2))
        q = 1.0 - rho * rho
        x, y = a[near_pairs], b[near_pairs]
        return float(np.sum(0.5 * np.log(q) + (x * x - 2.0 * rho * x * y + y * y) / (2.0 * q)))

    corr_max, corr_length = 0.0, 0.15
    if near_pairs.sum() >= 20:
        best = min(
            (
                minimize(corr_nll, [r0, l0], method="L-BFGS-B", bounds=[(0.0, 0.999), (0.02, 5.0)])
                for r0 in (0.5, 0.9)
                for l0 in (0.1, 0.5)
            ),
            key=lambda r: float(r.fun),
        )
        corr_max, corr_length = float(best.x[0]), float(best.x[1])
    report["pairs"] = int(i0.size)
    by_d = {}
    for lo, hi in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 1e9)):
        m = (dd >= lo) & (dd < hi)
        if m.sum() >= 20:
            by_d[f"{lo}-{hi if hi < 1e9 else 'inf'} px"] = [
                int(m.sum()),
                float(np.corrcoef(a[m], b[m])[0, 1]),
            ]
    report["correlation_by_displacement"] = by_d

    # 3. detection rules
    cos = s.cos_view
    sane = (cos >= 0.3) & (min_side >= 20.0)
    near = sane & (qmargin < -3.0) & (margin > -5.0) & (margin < 10.0)
    min_margin = _best_threshold(margin[near], found[near], np.arange(-2.0, 4.0001, 0.05))
    inside = margin >= min_margin
    cand = inside & sane
    band_low = band_high = 0.0
    band_prob = 0.0
    best_nll = _bernoulli_nll(found[cand], np.full(cand.sum(), found[cand].mean() if cand.any() else 1.0))
    qm, ok = qmargin[cand], found[cand]
    for lo in np.arange(-4.0, 4.0001, 0.25):
        for hi in np.arange(lo + 0.5, lo + 12.0001, 0.25):
            m = (qm >= lo) & (qm < hi)
            if m.sum() < 5 or (~m).sum() < 5:
                continue
            p_in, p_out = ok[m].mean(), ok[~m].mean()
            nll = _bernoulli_nll(ok[m], np.full(m.sum(), p_in)) + _bernoulli_nll(
                ok[~m], np.full((~m).sum(), p_out)
            )
            if nll < best_nll - 2.0:  # a band must explain at least a few failures
                best_nll, band_low, band_high = nll, float(lo), float(hi)
                band_prob = float(max(0.0, (p_out - p_in) / max(p_out, 1e-9)))
    in_band = (qmargin >= band_low) & (qmargin < band_high)
    sz = inside & ~in_band & (cos >= 0.3)

    def size_nll(v: NDArray[np.float64]) -> float:
        x = np.clip((min_side[sz] - v[0]) / v[1], -50, 50)
        return _bernoulli_nll(found[sz], (1.0 - v[2]) / (1.0 + np.exp(-x)))

    size_fit = minimize(
        size_nll, [11.0, 1.5, 0.005], method="L-BFGS-B", bounds=[(0.0, 200.0), (0.2, 20.0), (0.0, 0.5)]
    )
    size50, size_width, miss = (float(v) for v in size_fit.x)
    ob = inside & ~in_band & (min_side >= size50 + 4.0 * size_width)
    min_cos = _best_threshold(cos[ob], found[ob], np.arange(0.0, 0.5001, 0.002))
    prm = QualityParams(
        coef[0],
        coef[1],
        coef[2],
        coef[3],
        noise_gain=noise_gain,
        blur_gain=blur_gain,
        corr_max=corr_max,
        corr_length_px=corr_length,
        min_margin_px=min_margin,
        band_low_px=band_low,
        band_high_px=band_high,
        band_fail_prob=band_prob,
        size50_px=size50,
        size_width_px=size_width,
        min_cos_view=min_cos,
        miss_prob=miss,
    )
    # agreement of the fitted detection rules with the renderer (expected detection probability)
    band_p, small_p, miss_p = prm.detection_probability(qmargin, min_side)
    p_det = np.where(inside & (cos >= min_cos), (1 - band_p) * (1 - small_p) * (1 - miss_p), 0.0)
    report["detection_rate_rendered"] = float(found.mean())
    report["detection_rate_model"] = float(p_det.mean())
    report["detection_rules_frames"] = {
        "margin": int(near.sum()),
        "band": int(cand.sum()),
        "size": int(sz.sum()),
        "oblique": int(ob.sum()),
    }
    return prm, report


def merge_samples(*samples: DetectorSamples) -> DetectorSamples:
    """One :class:`DetectorSamples` of several (same image size); track ids are kept apart."""
    if not samples:
        raise ValueError("merge_samples needs at least one DetectorSamples")
    w, h = samples[0].width, samples[0].height
    if any((s.width, s.height) != (w, h) for s in samples):
        raise ValueError("merge_samples: the samples must share one image size")
    offset, tracks = 0, []
    for s in samples:
        tracks.append(s.track + offset)
        offset += int(s.track.max(initial=-1)) + 1
    return DetectorSamples(
        corners=np.concatenate([s.corners for s in samples]),
        quiet_zone=np.concatenate([s.quiet_zone for s in samples]),
        cos_view=np.concatenate([s.cos_view for s in samples]),
        noise_ratio=np.concatenate([s.noise_ratio for s in samples]),
        blur_px=np.concatenate([s.blur_px for s in samples]),
        detected=np.concatenate([s.detected for s in samples]),
        track=np.concatenate(tracks),
        width=w,
        height=h,
    )


#: The parameters of the corner error (fitted on all qualities' frames together).
NOISE_FIELDS: tuple[str, ...] = (*_COEFFICIENTS, "noise_gain", "blur_gain", "corr_max", "corr_length_px")


def fit_detector_params(
    samples: Mapping[str, DetectorSamples],
) -> tuple[dict[str, QualityParams], dict[str, Any]]:
    """Fit every quality of ``samples`` (quality -> frames): the detection rules on each quality's
    own frames, the corner error (:data:`NOISE_FIELDS`) on all frames together (the renderer's
    aliasing is the same for both qualities; the realistic frames' noise ratio and blur carry the
    extra variance, zero on ideal frames). Returns the parameters and the reports (per quality,
    and ``"pooled"`` for the error fit)."""
    qualities = list(samples)
    if not qualities:
        raise ValueError("fit_detector_params needs the samples of at least one quality")
    pooled, pooled_report = fit_quality(merge_samples(*samples.values()), with_extra=True)
    shared = {name: getattr(pooled, name) for name in NOISE_FIELDS}
    params: dict[str, QualityParams] = {}
    reports: dict[str, Any] = {"pooled": pooled_report}
    for q in qualities:
        own, report = fit_quality(samples[q], with_extra=q != "ideal")
        params[q] = replace(own, **shared)
        reports[q] = report
    return params, reports
