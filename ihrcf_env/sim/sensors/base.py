"""The sensor interface: every simulated sensor reads named arrays from the drone's true state.

A sensor is built once per world (it may hold PyBullet handles of that world's client) and is
read once per control step. ``read`` returns a mapping of observation names to arrays; all its
randomness comes from the generator it is given (the env's ``np_random``). Adding a sensor means
writing one class with this shape and registering it in ``World.sensors``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class BodyState:
    """True state of the drone at one instant (world frame unless stated; SI units).

    ``acceleration`` is the world-frame acceleration of the centre of mass over the last control
    step (m/s^2, gravity not included); ``angular_velocity`` is world-frame (rad/s).
    """

    time: float
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]  # R_world_body
    quaternion: NDArray[np.float64]  # x, y, z, w; world from body
    velocity: NDArray[np.float64]
    angular_velocity: NDArray[np.float64]
    acceleration: NDArray[np.float64]


@runtime_checkable
class Sensor(Protocol):
    """A simulated sensor: ``read`` maps the true body state to named measurement arrays."""

    name: str
    # Optional attribute ``update_interval`` (int, default 1): control steps between two samples;
    # in between, the world repeats the last reading (dm_control's ``update_interval``).

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode (re-draw biases, clear delay lines)."""

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> Mapping[str, NDArray]:
        """Measurements for ``state``; ``dt`` (s) is the time since the previous read."""
        ...


#: Name of the tag-corner sensor in ``World.sensors`` (``camera_output="corners"``).
TAG_CAMERA = "tag_camera"

#: Why a tag-corner reading has no corners, by ``tag_status`` code (0: detected). A reason not in
#: this table is reported as code 1.
TAG_STATUS: tuple[str, ...] = (
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
_STATUS_CODE = {reason: i for i, reason in enumerate(TAG_STATUS)}


def tag_status_code(reason: str) -> int:
    """The ``tag_status`` code of a reason (0 for ``""``, detected; 1 for an unknown reason)."""
    return _STATUS_CODE.get(reason, 1)


def tag_reading(corners: NDArray[np.float64] | None, reason: str) -> dict[str, NDArray]:
    """The measurement mapping of a tag-corner sensor (:data:`TAG_CAMERA`).

    ``tag_corners``: (4, 2) float64 px, the tag's corners in the (distorted) image, OpenCV
    pixel-centre convention, in :class:`~ihrcf_env.core.estimators.TagDetector`'s corner order;
    zeros when not detected. ``tag_detected``: 0-d bool array. ``tag_reason``: 0-d str array, why
    the tag was not detected (``""`` when it was); ``tag_status``: 0-d int array, its code in
    :data:`TAG_STATUS`.
    """
    if corners is None:
        why = reason or "tag not detected"
        return {
            "tag_corners": np.zeros((4, 2)),
            "tag_detected": np.array(False),
            "tag_reason": np.array(why),
            "tag_status": np.array(max(1, tag_status_code(why))),
        }
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2).copy()
    return {
        "tag_corners": c,
        "tag_detected": np.array(True),
        "tag_reason": np.array(""),
        "tag_status": np.array(0),
    }


__all__ = [
    "TAG_CAMERA",
    "TAG_STATUS",
    "BodyState",
    "Sensor",
    "tag_reading",
    "tag_status_code",
]
