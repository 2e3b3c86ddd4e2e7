"""The per-frame features that drive the detector model: the projected tag's corners, their local
frames and the features of the corner error (:func:`corner_basis`), the image margins, the
realistic camera's noise ratio (:func:`noise_to_contrast`), gathered in :class:`TagFeatures`.

Pure numpy. Pixels: OpenCV pixel-centre convention, ``u`` = column, ``v`` = row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

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
    """:func:`corner_basis` of one quad (4, 2) in plain Python (the per-frame path: on four points
    plain Python avoids numpy's per-call overhead), plus its :func:`image_margin` and shortest edge."""
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


__all__ = [
    "BASIS_NAMES",
    "N_BASIS",
    "QUIET_ZONE_SCALE",
    "TagFeatures",
    "corner_basis",
    "image_margin",
    "noise_to_contrast",
    "project_points",
    "tag_features",
]
