"""``LANDING_TARGET`` of a deck-pose fix, in the two profiles an autopilot takes.

* ``"px4"``: ``MAV_FRAME_LOCAL_NED``, ``position_valid = 1``, x, y, z the deck's absolute position
  (the drone's local position at the frame's capture plus the estimate, rotated by the drone's
  attitude at that instant) and ``q`` the deck's orientation (its FRD twin in NED). PX4 takes
  only this form as a position.
* ``"ardupilot"``: ``MAV_FRAME_BODY_FRD``, ``position_valid = 1``, x, y, z the deck in the body
  frame at the capture, ``distance`` > 0, ``q`` the deck's orientation in the body FRD frame.

Both fill ``angle_x`` / ``angle_y`` (the line of sight, :func:`ihrcf_env.mavlink.frames.target_body_frd`),
``distance``, ``size_x`` / ``size_y`` (the tag's angular size, rad), ``type =
LANDING_TARGET_TYPE_VISION_FIDUCIAL`` and ``target_num`` (the tag id); ``time_usec`` is the
vehicle-clock time of the camera frame's capture.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.mavlink import frames
from ihrcf_env.mavlink._pymavlink import dialect
from ihrcf_env.mavlink.messages import usec

#: The ``--profile`` choices.
PROFILES: tuple[str, ...] = ("px4", "ardupilot")
#: The ``--target`` choices: an estimator of the env, or the ground truth.
TARGETS: tuple[str, ...] = ("fused", "ihrcf", "atda", "truth")


class DeckFix(NamedTuple):
    """A deck pose for one camera frame: its capture ``time`` (s, vehicle clock), the deck in the
    body frame (FLU: ``position`` m, ``rotation`` ``R_body_deck``) and the drone's world pose at
    the capture (``drone_position`` m, ``drone_quaternion`` x, y, z, w)."""

    time: float
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    drone_position: NDArray[np.float64]
    drone_quaternion: NDArray[np.float64]


def landing_target(fix: DeckFix, profile: str, tag_id: int, tag_size: float) -> Any:
    """The ``LANDING_TARGET`` message of ``fix`` in ``profile`` (module docstring)."""
    m = dialect()
    body = frames.target_body_frd(fix.position)
    size = 2.0 * math.atan2(0.5 * tag_size, body.distance) if body.distance > 0 else 0.0
    if profile == "px4":
        ned = frames.target_local_ned(fix.drone_position, fix.drone_quaternion, fix.position, fix.rotation)
        frame, xyz, q = m.MAV_FRAME_LOCAL_NED, ned.position, ned.q
    elif profile == "ardupilot":
        frame, xyz, q = m.MAV_FRAME_BODY_FRD, body.position, frames.deck_quat_body_frd(fix.rotation)
    else:
        raise ValueError(f"profile must be one of {PROFILES}, got {profile!r}")
    return m.MAVLink_landing_target_message(
        usec(fix.time),
        int(tag_id) & 0xFF,
        frame,
        body.angle_x,
        body.angle_y,
        body.distance,
        size,
        size,
        *xyz.tolist(),
        q.tolist(),
        m.LANDING_TARGET_TYPE_VISION_FIDUCIAL,
        1,
    )


__all__ = ["PROFILES", "TARGETS", "DeckFix", "landing_target"]
