"""Frames of the MAVLink face: the env's world (z up) and body (FLU) <-> MAVLink's NED and FRD.

Defined once, here, as pure functions (no sockets, no env):

* **World -> local NED**: north = world x, east = -world y, down = -world z. The env's world is
  not tied to the compass: its x axis is taken as north (a rotation of pi about x, det +1), so a
  drone with world yaw 0 heads north (MAVLink yaw 0) and a world yaw psi is a NED yaw -psi.
  The local NED origin is the world origin (the deck's base centre on the ground).
* **Body FLU -> body FRD**: forward = x, right = -y, down = -z (the same matrix :data:`FLIP`).
* Attitude: ``R_ned_frd = FLIP @ R_world_body @ FLIP``; quaternions are (x, y, z, w) in the env
  (:mod:`ihrcf_env.core.frames`) and (w, x, y, z) in MAVLink.
* Body rates: (p, q, r)_FRD = (p, -q, -r)_FLU (rad/s).
* The deck frame D (x forward, y left, z up out of the deck, see :mod:`ihrcf_env.core.frames`)
  has an FRD twin the same way: ``R_ned_deck_frd = FLIP @ R_world_deck @ FLIP``, so a level deck
  reads the identity quaternion in NED.

Units: metres, m/s, radians, rad/s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.frames import (
    as_array,
    euler_from_matrix,
    matrix_from_quat,
    quat_from_matrix,
    wrap_angle,
)

#: The one matrix of both conversions: world (z up) <-> NED and body FLU <-> FRD (its own inverse).
FLIP: NDArray[np.float64] = np.diag([1.0, -1.0, -1.0])


def world_to_ned(v: ArrayLike) -> NDArray[np.float64]:
    """A world-frame vector (or point, m) in local NED: (x, -y, -z)."""
    return FLIP @ as_array(v, (3,), "world vector")


def ned_to_world(v: ArrayLike) -> NDArray[np.float64]:
    """A local-NED vector (or point, m) in the world frame: (n, -e, -d)."""
    return FLIP @ as_array(v, (3,), "NED vector")


def flu_to_frd(v: ArrayLike) -> NDArray[np.float64]:
    """A body FLU vector (m, m/s or rad/s) in body FRD: (x, -y, -z)."""
    return FLIP @ as_array(v, (3,), "FLU vector")


def frd_to_flu(v: ArrayLike) -> NDArray[np.float64]:
    """A body FRD vector in body FLU: (x, -y, -z)."""
    return FLIP @ as_array(v, (3,), "FRD vector")


def rotation_to_ned(R_world_body: ArrayLike) -> NDArray[np.float64]:
    """``R_ned_frd`` of a world-from-body (FLU) rotation: ``FLIP @ R @ FLIP``."""
    return FLIP @ as_array(R_world_body, (3, 3), "R_world_body") @ FLIP


def quat_to_mavlink(q_xyzw: ArrayLike) -> NDArray[np.float64]:
    """The MAVLink quaternion (w, x, y, z; NED from FRD, w >= 0) of the env's world-from-body
    quaternion (x, y, z, w)."""
    x, y, z, w = quat_from_matrix(rotation_to_ned(matrix_from_quat(q_xyzw)))
    return np.array([w, x, y, z])


def quat_from_mavlink(q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """The env's world-from-body quaternion (x, y, z, w) of a MAVLink one (w, x, y, z; NED from
    FRD): the inverse of :func:`quat_to_mavlink`."""
    w, x, y, z = as_array(q_wxyz, (4,), "MAVLink quaternion").tolist()
    return quat_from_matrix(rotation_to_ned(matrix_from_quat([x, y, z, w])))


class Attitude(NamedTuple):
    """MAVLink ``ATTITUDE``: roll, pitch, yaw (rad, NED from FRD, Z-Y-X) and body rates (rad/s, FRD)."""

    roll: float
    pitch: float
    yaw: float
    rollspeed: float
    pitchspeed: float
    yawspeed: float


def attitude_to_mavlink(q_xyzw: ArrayLike, rates_flu: ArrayLike) -> Attitude:
    """``ATTITUDE`` of the env's world-from-body quaternion (x, y, z, w) and body rates (FLU, rad/s)."""
    roll, pitch, yaw = euler_from_matrix(rotation_to_ned(matrix_from_quat(q_xyzw))).tolist()
    p, q, r = flu_to_frd(rates_flu).tolist()
    return Attitude(roll, pitch, yaw, p, q, r)


def yaw_world_to_ned(yaw: float) -> float:
    """A heading about world z (rad, counter-clockwise seen from above) as a NED yaw (clockwise
    from north), wrapped to (-pi, pi]."""
    return float(wrap_angle(-yaw))


def velocity_command(
    velocity_ned: ArrayLike, yaw_rate_ned: float, yaw_world: float
) -> tuple[NDArray[np.float64], float]:
    """The env's velocity command of a NED velocity setpoint (m/s) and a NED yaw rate (rad/s,
    clockwise seen from above), for a drone whose heading about world z is ``yaw_world`` (rad):
    ``((vx, vy) in the heading frame (x forward, y left), vz world up)`` in m/s and the yaw rate
    about world z (rad/s), as :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`'s velocity
    action takes them (before its ``max_velocity`` scale)."""
    v_world = ned_to_world(velocity_ned)
    c, s = math.cos(yaw_world), math.sin(yaw_world)
    vx = c * v_world[0] + s * v_world[1]
    vy = -s * v_world[0] + c * v_world[1]
    return np.array([vx, vy, v_world[2]]), -float(yaw_rate_ned)


def body_velocity_to_ned(velocity_frd: ArrayLike, yaw_ned: float) -> NDArray[np.float64]:
    """A velocity in MAVLink's ``MAV_FRAME_BODY_NED`` (forward, right, down along the vehicle's
    heading, m/s) in local NED, for a NED yaw ``yaw_ned`` (rad)."""
    f, r, d = as_array(velocity_frd, (3,), "body velocity").tolist()
    c, s = math.cos(yaw_ned), math.sin(yaw_ned)
    return np.array([c * f - s * r, s * f + c * r, d])


class TargetNed(NamedTuple):
    """The deck's pose for ``LANDING_TARGET`` in ``MAV_FRAME_LOCAL_NED``: position (m) and the
    quaternion (w, x, y, z) of the deck's FRD twin in NED."""

    position: NDArray[np.float64]
    q: NDArray[np.float64]


def target_local_ned(
    drone_position_world: ArrayLike,
    drone_q_xyzw: ArrayLike,
    deck_position_body: ArrayLike,
    deck_rotation_body: ArrayLike,
) -> TargetNed:
    """The deck pose in local NED, given the drone's world pose (m; quaternion x, y, z, w world
    from body) and the deck pose in the body frame (FLU: position m, ``R_body_deck``)."""
    R_wb = matrix_from_quat(drone_q_xyzw)
    p_w = as_array(drone_position_world, (3,), "drone position") + R_wb @ as_array(
        deck_position_body, (3,), "deck position"
    )
    R_wd = R_wb @ as_array(deck_rotation_body, (3, 3), "deck rotation")
    x, y, z, w = quat_from_matrix(rotation_to_ned(R_wd))
    return TargetNed(world_to_ned(p_w), np.array([w, x, y, z]))


class TargetBody(NamedTuple):
    """The deck for ``LANDING_TARGET`` in ``MAV_FRAME_BODY_FRD``: position (m, FRD), the distance
    (m) and the line-of-sight angles (rad): ``angle_x = atan(y / z)`` (positive to the right),
    ``angle_y = atan(-x / z)`` (positive towards the tail), the image-plane angles of a downward
    camera whose image top is the nose (ArduPilot reads the line of sight as
    ``(-tan angle_y, tan angle_x, 1)``)."""

    position: NDArray[np.float64]
    distance: float
    angle_x: float
    angle_y: float


def target_body_frd(deck_position_body: ArrayLike) -> TargetBody:
    """The deck position in the body frame (FLU, m) as a ``MAV_FRAME_BODY_FRD`` target."""
    p = flu_to_frd(deck_position_body)
    x, y, z = p.tolist()
    return TargetBody(p, float(np.linalg.norm(p)), math.atan2(y, z), math.atan2(-x, z))


def deck_quat_body_frd(deck_rotation_body: ArrayLike) -> NDArray[np.float64]:
    """The quaternion (w, x, y, z) of the deck's FRD twin in the body FRD frame, of
    ``R_body_deck`` (FLU): ``FLIP @ R @ FLIP``."""
    x, y, z, w = quat_from_matrix(FLIP @ as_array(deck_rotation_body, (3, 3), "deck rotation") @ FLIP)
    return np.array([w, x, y, z])


__all__ = [
    "FLIP",
    "Attitude",
    "TargetBody",
    "TargetNed",
    "attitude_to_mavlink",
    "body_velocity_to_ned",
    "deck_quat_body_frd",
    "flu_to_frd",
    "frd_to_flu",
    "ned_to_world",
    "quat_from_mavlink",
    "quat_to_mavlink",
    "rotation_to_ned",
    "target_body_frd",
    "target_local_ned",
    "velocity_command",
    "world_to_ned",
    "yaw_world_to_ned",
]
