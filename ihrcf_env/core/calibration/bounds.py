"""Physical bounds of the calibration file's fields (see
:class:`~ihrcf_env.core.calibration.file.Calibration`).

A field of the right kind but outside its bounds raises ValueError naming it: a file whose lens
or camera matrix no real camera has (``dist[0] = -1e6``) is refused when it is read, not used to
make ATDA's estimates absurd. The bounds are loose (a calibration of any real camera of the
simulator's kind passes by a wide margin) and physical:

* image size: 1 .. :data:`MAX_IMAGE_SIZE` px per side; ``fov`` in (0, pi) rad;
* ``lens_distortion`` (k1, k2 of the simulated lens): within +-:data:`LENS_DISTORTION_LIMIT`, as the
  simulated camera accepts;
* ``K``: focal lengths ``fx``, ``fy`` in [:data:`FOCAL_MIN`, :data:`FOCAL_MAX`] times the image's
  larger side (fields of view from ~0.6 deg to ~178 deg); skew ``|K[0, 1]|`` at most
  :data:`MAX_SKEW` ``fx``; principal point inside the image (``cx`` in [-0.5, W - 0.5], ``cy`` in
  [-0.5, H - 0.5] px: pixel centres at integers); last row ``0 0 1``;
* ``dist`` (k1, k2, p1, p2, k3): each within :data:`DIST_LIMITS`, and the radial distortion must not
  fold the image: ``r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` increasing from the centre out to the
  image's corners (``r`` the normalised radius), so every pixel has one line of sight;
* ``chessboard_rms``: [0, :data:`MAX_CHESSBOARD_RMS`] px; ``seed``: [0, 2^128];
* ``rig``: ``a`` in (0, :data:`MAX_RIG_A`] m and ``theta`` in (0, pi/2) rad (the rig's own
  checks), each ``camera_position`` coordinate within +-:data:`MAX_CAMERA_OFFSET` m of the body
  origin;
* tables: ranges in (0, :data:`~ihrcf_env.core.calibration.tables.MAX_TABLE_RANGE`] m, touch
  pixels within one image size around the image (``u`` in [-W, 2W], ``v`` in [-H, 2H] px).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.calibration._checks import check_keys, check_real_array
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.checks import check_real
from ihrcf_env.core.rig import SensorRig

#: Largest image side (px).
MAX_IMAGE_SIZE = 32768
#: Largest |k1|, |k2| of the simulated lens (the simulated camera's own bound).
LENS_DISTORTION_LIMIT = 1.0
#: Focal length bounds, in units of the image's larger side.
FOCAL_MIN, FOCAL_MAX = 0.01, 100.0
#: Largest |skew| ``K[0, 1]`` as a fraction of ``fx``.
MAX_SKEW = 0.1
#: Largest magnitude of each distortion coefficient (k1, k2, p1, p2, k3) (OpenCV's model).
DIST_LIMITS: tuple[float, float, float, float, float] = (2.0, 10.0, 0.2, 0.2, 50.0)
_DIST_NAMES = ("k1", "k2", "p1", "p2", "k3")
#: Largest chessboard reprojection RMS (px).
MAX_CHESSBOARD_RMS = 100.0
#: Largest ``rig.a`` (m) and ``rig.camera_position`` coordinate magnitude (m).
MAX_RIG_A = 1.0
MAX_CAMERA_OFFSET = 1.0
#: Largest RNG seed of a calibration run.
MAX_SEED = 2**128


def check_camera_matrix(K: Any, width: int, height: int) -> NDArray[np.float64]:
    """``K`` as a (3, 3) camera matrix of a ``width`` x ``height`` px image (bounds: module doc)."""
    size = float(max(width, height))
    K = check_real_array("K", K, (3, 3), "px", low=-FOCAL_MAX * size, high=FOCAL_MAX * size)
    if not (K[0, 0] > 0 and K[1, 1] > 0 and np.array_equal(K[2], [0.0, 0.0, 1.0])):
        raise ValueError(f"K must be a camera matrix (fx, fy > 0, last row 0 0 1), got {K.tolist()}")
    for name, v in (("K[0, 0] (fx)", K[0, 0]), ("K[1, 1] (fy)", K[1, 1])):
        check_real(name, v, "px", low=FOCAL_MIN * size, high=FOCAL_MAX * size)
    skew = MAX_SKEW * float(K[0, 0])
    check_real("K[0, 1] (skew)", K[0, 1], "px", low=-skew, high=skew)
    check_real("K[0, 2] (cx)", K[0, 2], "px", low=-0.5, high=width - 0.5)
    check_real("K[1, 2] (cy)", K[1, 2], "px", low=-0.5, high=height - 0.5)
    return K


def check_distortion(dist: Any, K: NDArray[np.float64], width: int, height: int) -> NDArray[np.float64]:
    """``dist`` (k1, k2, p1, p2, k3) within :data:`DIST_LIMITS`, its radial part not folding the
    image of camera matrix ``K`` (see the module docstring)."""
    d = check_real_array("dist", dist, (5,))
    for i, (name, limit) in enumerate(zip(_DIST_NAMES, DIST_LIMITS, strict=True)):
        check_real(f"dist[{i}] ({name})", d[i], low=-limit, high=limit)
    k1, k2, k3 = float(d[0]), float(d[1]), float(d[4])
    u = np.array([-0.5, width - 0.5])
    v = np.array([-0.5, height - 0.5])
    x, y = (u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1]
    r_max = float(np.sqrt(np.max(x * x) + np.max(y * y)))
    r2 = np.square(np.linspace(0.0, r_max, 257))
    slope = 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3))  # d/dr of r (1 + k1 r^2 + ...)
    if not bool((slope > 0.0).all()):
        raise ValueError(
            f"dist: the radial distortion (k1, k2, k3) = ({k1!r}, {k2!r}, {k3!r}) folds the image: "
            f"r (1 + k1 r^2 + k2 r^4 + k3 r^6) must increase out to the image corners (r = {r_max:.3g})"
        )
    return d


def check_rig(rig: SensorRig | Mapping[str, Any]) -> dict[str, Any]:
    """The rig's JSON object (``a``, ``theta``, ``camera_position``) checked (bounds: module doc)."""
    d = check_keys(
        "rig", rig.to_dict() if isinstance(rig, SensorRig) else rig, ("a", "theta", "camera_position")
    )
    out = {
        "a": check_real("rig.a", d["a"], "m"),
        "theta": check_real("rig.theta", d["theta"], "rad"),
        "camera_position": check_real_array("rig.camera_position", d["camera_position"], (3,), "m").tolist(),
    }
    try:  # the rig's own checks first (a > 0, theta in (0, pi/2)), then the upper bounds
        SensorRig(out["a"], out["theta"], tuple(out["camera_position"]))
    except ValueError as e:
        raise ValueError(f"rig: {e}") from e
    check_real("rig.a", out["a"], "m", low=0.0, low_open=True, high=MAX_RIG_A)
    check_real_array(
        "rig.camera_position",
        out["camera_position"],
        (3,),
        "m",
        low=-MAX_CAMERA_OFFSET,
        high=MAX_CAMERA_OFFSET,
    )
    return out


def check_table_pixels(tables: RangePixelTable, width: int, height: int) -> None:
    """Every touch pixel of ``tables`` within one image size around the ``width`` x ``height`` px
    image (ValueError naming the sensor otherwise)."""
    for t in tables.tables:
        for axis, (name, size) in enumerate((("u", width), ("v", height))):
            p = t.pixels[:, axis]
            i = int(np.argmax(np.abs(p - 0.5 * size)))
            check_real(
                f"tables.{t.name}.pixels[{i}, {axis}] ({name})", float(p[i]), "px", low=-size, high=2.0 * size
            )


def check_fov(fov: Any) -> float:
    """``fov`` (rad) in (0, pi)."""
    v = check_real("fov", fov, "rad")
    if not 0.0 < v < math.pi:
        raise ValueError(f"fov must be in (0, pi) rad, got {v!r}")
    return v


__all__ = [
    "DIST_LIMITS",
    "LENS_DISTORTION_LIMIT",
    "MAX_CAMERA_OFFSET",
    "MAX_CHESSBOARD_RMS",
    "MAX_IMAGE_SIZE",
    "MAX_RIG_A",
    "MAX_SEED",
    "MAX_SKEW",
    "check_camera_matrix",
    "check_distortion",
    "check_fov",
    "check_rig",
    "check_table_pixels",
]
