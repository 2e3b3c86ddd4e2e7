"""Geometry of the drone's sensor rig and of the landing tag (pure numpy, no simulator).

The rig is the downward camera plus four ToF range sensors in the camera plane, placed as in
eq. (12) of Sefidgar & Landry (2022) with equal distances ``a`` and angles ``theta``: a rectangle
centred on the camera. Sensor order and calibration pad colours (paper Fig. 5):

====  =========================  ===============  =======
name  camera-frame XY (x right,   image quadrant   pad
      y down)
====  =========================  ===============  =======
ps1   (-a cos t, -a sin t)        top-left         blue
ps2   (+a cos t, -a sin t)        top-right        green
ps3   (+a cos t, +a sin t)        bottom-right     yellow
ps4   (-a cos t, +a sin t)        bottom-left      red
====  =========================  ===============  =======

Every beam is parallel to the optical axis, so a reading ``d`` of sensor i touches the surface at
the camera-frame point ``(x_i, y_i, d)``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.frames import R_BODY_CAM, as_array

PAD_COLOURS: tuple[str, str, str, str] = ("blue", "green", "yellow", "red")


@dataclass(frozen=True)
class SensorRig:
    """Camera + four-ToF rig. Lengths in metres, angles in radians.

    Attributes:
        a: distance of each ToF sensor from the optical centre (paper: 0.1 m).
        theta: angle of each sensor from the camera x axis (paper: 45 degrees).
        camera_position: optical centre in the body frame (m). The camera's orientation is
            :data:`ihrcf_env.core.frames.R_BODY_CAM` (looking down, image top towards the nose).
    """

    a: float = 0.1
    theta: float = math.pi / 4
    camera_position: tuple[float, float, float] = field(default=(0.0, 0.0, -0.03))

    def __post_init__(self) -> None:
        if not (math.isfinite(self.a) and self.a > 0):
            raise ValueError(f"a must be a positive distance in metres, got {self.a!r}")
        if not (0.0 < self.theta < math.pi / 2):
            raise ValueError(f"theta must be in (0, pi/2) rad, got {self.theta!r}")
        as_array(self.camera_position, (3,), "camera_position")

    @functools.cached_property
    def sensor_xy_cam(self) -> NDArray[np.float64]:
        """(4, 2) XY of ps1..ps4 in the camera frame (m); read-only (computed once per rig)."""
        hx, hy = self.a * math.cos(self.theta), self.a * math.sin(self.theta)
        xy = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
        xy.setflags(write=False)
        return xy

    @functools.cached_property
    def camera_position_array(self) -> NDArray[np.float64]:
        """:attr:`camera_position` as a read-only (3,) array (m, body frame)."""
        c = np.array(self.camera_position, dtype=np.float64)
        c.setflags(write=False)
        return c

    @property
    def sensor_positions_body(self) -> NDArray[np.float64]:
        """(4, 3) positions of ps1..ps4 in the body frame (m)."""
        xyz_cam = np.column_stack([self.sensor_xy_cam, np.zeros(4)])
        return xyz_cam @ R_BODY_CAM.T + np.asarray(self.camera_position)

    def to_dict(self) -> dict[str, float | list[float]]:
        return {"a": self.a, "theta": self.theta, "camera_position": list(self.camera_position)}


def tag_corners_deck(tag_size: float) -> NDArray[np.float64]:
    """(4, 3) tag corners in the deck frame, in OpenCV's aruco order (a new array each call).

    OpenCV returns corners clockwise from the tag's top-left as drawn by
    ``cv2.aruco.generateImageMarker``. The texture is laid on the deck with its top edge towards
    deck +x and its left edge towards deck +y, so seen from above with deck +x up the image:
    0 = (+s/2, +s/2), 1 = (+s/2, -s/2), 2 = (-s/2, -s/2), 3 = (-s/2, +s/2), z = 0.
    """
    if not (math.isfinite(tag_size) and tag_size > 0):
        raise ValueError(f"tag_size must be positive (m), got {tag_size!r}")
    h = tag_size / 2
    return np.array([[h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0], [-h, h, 0.0]])


def intrinsics_from_fov(width: int, height: int, fov: float) -> NDArray[np.float64]:
    """Pinhole K (OpenCV pixel-centre convention) of a camera with vertical field of view ``fov`` (rad).

    Square pixels; the principal point is the image centre, ``((W - 1) / 2, (H - 1) / 2)``.
    (A particular renderer may put it elsewhere: see ``ihrcf_env.config.sensors.CameraConfig``.)
    """
    if width <= 0 or height <= 0:
        raise ValueError(f"image size must be positive, got {width}x{height}")
    if not (0.0 < fov < math.pi):
        raise ValueError(f"fov must be in (0, pi) rad, got {fov!r}")
    f = (height / 2.0) / math.tan(fov / 2.0)
    return np.array([[f, 0.0, (width - 1) / 2.0], [0.0, f, (height - 1) / 2.0], [0.0, 0.0, 1.0]])


__all__ = [
    "PAD_COLOURS",
    "SensorRig",
    "intrinsics_from_fov",
    "tag_corners_deck",
]
