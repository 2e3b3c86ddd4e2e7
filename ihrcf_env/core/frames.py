"""Frame conventions and conversions: the one place where frames are defined.

Frames (all right-handed, metres, radians):

* **World** (W): z up, gravity -z (PyBullet's world).
* **Body** (B): drone body frame FLU: x forward, y left, z up; origin at the centre of mass.
* **Camera** (C): OpenCV: x right in the image, y down in the image, z along the optical axis.
  The camera looks straight down the body -z axis with the top of the image towards the drone's
  nose, so ``x_C = -y_B``, ``y_C = -x_B``, ``z_C = -z_B`` (see :data:`R_BODY_CAM`).
* **Deck** (D): origin at the centre of the tag on the deck's top surface, x forward (the tag's
  "top" edge, i.e. the side of OpenCV corner 0 -> 1), y left, z up out of the deck.

Euler angles are intrinsic Z-Y-X (yaw, then pitch, then roll): ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``,
reported in the order (roll, pitch, yaw). A level deck straight below a level drone therefore reads
position (0, 0, -h) and zero roll/pitch/yaw in the body frame.

Quaternions are (x, y, z, w), as in PyBullet.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Rotation taking camera-frame vectors to body-frame vectors (columns: camera axes in body).
R_BODY_CAM: NDArray[np.float64] = np.array(
    [[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]], dtype=np.float64
)


def as_array(x: ArrayLike, shape: tuple[int, ...], name: str) -> NDArray[np.float64]:
    """Return ``x`` as a finite float64 array of exactly ``shape``; ValueError naming ``name`` otherwise."""
    a = np.asarray(x, dtype=np.float64)
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
    if not math.isfinite(np.add.reduce(a, axis=None)) and not np.isfinite(a).all():
        raise ValueError(f"{name} contains NaN or inf")  # (the sum alone also overflows for huge values)
    return a


def matrix_from_euler(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """Rotation matrix ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (radians)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrices_from_euler(rpy: ArrayLike) -> NDArray[np.float64]:
    """(n, 3, 3) rotation matrices ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` of (n, 3) angles (roll,
    pitch, yaw) in radians: :func:`matrix_from_euler` on arrays (equal to scipy's intrinsic
    ``"ZYX"`` rotations up to rounding)."""
    a = np.asarray(rpy, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"rpy must have shape (n, 3), got {a.shape}")
    cr, sr = np.cos(a[:, 0]), np.sin(a[:, 0])
    cp, sp = np.cos(a[:, 1]), np.sin(a[:, 1])
    cy, sy = np.cos(a[:, 2]), np.sin(a[:, 2])
    out = np.empty((a.shape[0], 3, 3))
    out[:, 0, 0] = cy * cp
    out[:, 0, 1] = cy * sp * sr - sy * cr
    out[:, 0, 2] = cy * sp * cr + sy * sr
    out[:, 1, 0] = sy * cp
    out[:, 1, 1] = sy * sp * sr + cy * cr
    out[:, 1, 2] = sy * sp * cr - cy * sr
    out[:, 2, 0] = -sp
    out[:, 2, 1] = cp * sr
    out[:, 2, 2] = cp * cr
    return out


def euler_from_matrix(R: ArrayLike) -> NDArray[np.float64]:
    """(roll, pitch, yaw) in radians of a rotation matrix, inverse of :func:`matrix_from_euler`.

    Pitch is in [-pi/2, pi/2]; roll and yaw in (-pi, pi].
    """
    return _euler(as_array(R, (3, 3), "R"))


def _euler(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`euler_from_matrix` of a checked (3, 3) float64 array."""
    (r00, _, _), (r10, r11, _), (r20, r21, r22) = R.tolist()
    pitch = math.asin(max(-1.0, min(1.0, -r20)))
    if abs(r20) < 1.0 - 1e-12:
        roll = math.atan2(r21, r22)
        yaw = math.atan2(r10, r00)
    else:  # gimbal lock: put everything in yaw
        roll = 0.0
        yaw = math.atan2(-R[0, 1], r11)
    return np.array([roll, pitch, yaw])


def matrix_from_quat(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a quaternion (x, y, z, w); the quaternion is normalised first."""
    x, y, z, w = as_array(q, (4,), "quaternion").tolist()  # plain floats: cheaper than numpy scalars
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if n < 1e-12:
        raise ValueError("quaternion has zero norm")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_from_matrix(R: ArrayLike) -> NDArray[np.float64]:
    """Quaternion (x, y, z, w) with w >= 0 of a rotation matrix."""
    R = as_array(R, (3, 3), "R")
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2
        q = [0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s]
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2
        q = [(R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s]
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2
        q = [(R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s]
    qa = np.array(q, dtype=np.float64)
    qa /= np.linalg.norm(qa)
    return -qa if qa[3] < 0 else qa


def relative_pose(
    R_wa: ArrayLike, p_wa: ArrayLike, R_wb: ArrayLike, p_wb: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pose of frame b expressed in frame a, given both in a common frame w: ``(R_ab, p_ab)``."""
    R_wa = as_array(R_wa, (3, 3), "R_wa")
    R_wb = as_array(R_wb, (3, 3), "R_wb")
    p_wa = as_array(p_wa, (3,), "p_wa")
    p_wb = as_array(p_wb, (3,), "p_wb")
    return R_wa.T @ R_wb, R_wa.T @ (p_wb - p_wa)


def cam_pose_to_body(
    R_cam_obj: ArrayLike, t_cam_obj: ArrayLike, cam_position_body: ArrayLike, check: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Convert an object pose measured in the camera frame to the body frame.

    ``cam_position_body`` is the camera's optical centre in the body frame (m); the camera's
    orientation is the fixed :data:`R_BODY_CAM`. ``check=False`` skips the shape and finiteness
    checks (for float64 arrays a caller has already checked).
    """
    if check:
        R_co = as_array(R_cam_obj, (3, 3), "R_cam_obj")
        t_co = as_array(t_cam_obj, (3,), "t_cam_obj")
        c = as_array(cam_position_body, (3,), "cam_position_body")
    else:
        R_co, t_co, c = R_cam_obj, t_cam_obj, cam_position_body  # type: ignore[assignment]
    return R_BODY_CAM @ R_co, R_BODY_CAM @ t_co + c


def body_pose_to_cam(
    R_body_obj: ArrayLike, t_body_obj: ArrayLike, cam_position_body: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Inverse of :func:`cam_pose_to_body`: an object pose in the body frame -> camera frame."""
    R_bo = as_array(R_body_obj, (3, 3), "R_body_obj")
    t_bo = as_array(t_body_obj, (3,), "t_body_obj")
    c = as_array(cam_position_body, (3,), "cam_position_body")
    return R_BODY_CAM.T @ R_bo, R_BODY_CAM.T @ (t_bo - c)


def rotation_angle(R_a: ArrayLike, R_b: ArrayLike, check: bool = True) -> float:
    """Angle (rad) of the rotation taking ``R_a`` to ``R_b`` (``check=False``: two (3, 3) float64
    arrays a caller has already checked)."""
    if check:
        Ra, Rb = as_array(R_a, (3, 3), "R_a"), as_array(R_b, (3, 3), "R_b")
    else:
        Ra, Rb = R_a, R_b  # type: ignore[assignment]
    trace = float(np.einsum("ij,ij->", Ra, Rb))  # tr(Ra^T Rb)
    return math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0)))


def wrap_angle(a: ArrayLike, period: float = 2 * math.pi) -> NDArray[np.float64]:
    """Wrap angles (rad) to (-period/2, period/2]: (-pi, pi] by default.

    The one angle-wrapping helper of the package; ``period = pi/2`` gives the heading error modulo
    the square deck's 90 deg symmetry, in (-pi/4, pi/4].
    """
    if not (math.isfinite(period) and period > 0):
        raise ValueError(f"period must be positive, got {period!r}")
    a = np.asarray(a, dtype=np.float64)
    half = 0.5 * period
    return half - np.mod(half - a, period)


__all__ = [
    "R_BODY_CAM",
    "as_array",
    "body_pose_to_cam",
    "cam_pose_to_body",
    "euler_from_matrix",
    "matrices_from_euler",
    "matrix_from_euler",
    "matrix_from_quat",
    "quat_from_matrix",
    "relative_pose",
    "rotation_angle",
    "wrap_angle",
]
