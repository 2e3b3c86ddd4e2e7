"""Hover-tracking controller: hold a height above the moving deck and follow it with one pose estimate.

For ``action_mode="velocity"`` of ``ihrcf_env/DeckHover-v0``. It flies from a deck-pose estimate
in the drone body frame (FLU; ``obs["ihrcf"]`` in the examples) and the IMU attitude, never from
ground truth:

* the estimated deck position is rotated from the body frame to the heading frame with the IMU's
  roll and pitch (the two frames differ by the drone's tilt, which is as large as the deck's motion
  when the drone rides it), then ``vx = k_xy * x``, ``vy = k_xy * y`` drive the drone over the tag
  centre;
* ``vz = k_z * (height - h)`` holds the drone ``height`` above the deck, ``h`` being the estimated
  height of the drone above the tag centre along world up: the drone rides the deck's heave;
* ``yaw_rate = k_yaw * yaw`` turns the nose with the deck's estimated heading;
* while the estimate is invalid the command is zero: the built-in autopilot holds position.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ihrcf_env.core.checks import check_fields, check_real
from ihrcf_env.core.frames import euler_from_matrix, matrix_from_euler, matrix_from_quat


@dataclass(frozen=True)
class HoverGains:
    """Proportional tracking gains: (m/s)/m for x, y and z, (rad/s)/rad for yaw."""

    k_xy: float = 1.0
    k_z: float = 1.0
    k_yaw: float = 1.0

    def __post_init__(self) -> None:
        check_fields(self, lambda f: f"HoverGains.{f}", {f: (0.0, 100.0) for f in ("k_xy", "k_z", "k_yaw")})


def tracking_action(
    estimate: Mapping[str, Any],
    quaternion: ArrayLike,
    height: float,
    max_velocity: ArrayLike,
    gains: HoverGains | None = None,
) -> NDArray[np.float64]:
    """Normalised velocity action that tracks the deck from one pose estimate (body frame).

    Args:
        estimate: ``obs["ihrcf"]``-like: ``position`` (3,) m, ``euler`` (3,) rad, ``valid`` 0/1.
        quaternion: the IMU attitude (x, y, z, w), world from body; only roll and pitch are used.
        height: wanted height of the drone above the tag centre (m, world up).
        max_velocity: the env's action scale (m/s, m/s, m/s, rad/s).
        gains: tracking gains (default :class:`HoverGains`).

    Returns:
        ``(vx, vy, vz, yaw_rate) / max_velocity`` clipped to [-1, 1]; zeros if the estimate is invalid.
    """
    if not estimate["valid"]:
        return np.zeros(4)
    g = gains if gains is not None else HoverGains()
    roll, pitch, _ = euler_from_matrix(matrix_from_quat(quaternion))
    R_heading_body = matrix_from_euler(roll, pitch, 0.0)
    p = R_heading_body @ np.asarray(estimate["position"], dtype=np.float64)  # deck in the heading frame
    h = -p[2]  # drone above the tag centre
    v = np.array([g.k_xy * p[0], g.k_xy * p[1], g.k_z * (height - h), g.k_yaw * float(estimate["euler"][2])])
    return np.clip(v / np.asarray(max_velocity, dtype=np.float64), -1.0, 1.0)


class HoverTracker:
    """:func:`tracking_action` as a policy over the env's observation.

    Args:
        height: wanted height of the drone above the tag centre (m, world up).
        max_velocity: the env's action scale (``env.unwrapped.max_velocity``: m/s, m/s, m/s, rad/s).
        estimator: observation key of the deck-pose estimate to fly on (``"ihrcf"`` or ``"atda"``).
        gains: tracking gains.
    """

    def __init__(
        self,
        height: float = 1.0,
        max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        estimator: str = "ihrcf",
        gains: HoverGains | None = None,
    ) -> None:
        self.height = check_real("height", height, "m", low=0.0, high=100.0)
        self.max_velocity = np.asarray(max_velocity, dtype=np.float64)
        self.estimator = estimator
        self.gains = gains if gains is not None else HoverGains()

    def act(self, obs: Mapping[str, Any]) -> NDArray[np.float64]:
        """Normalised velocity action in [-1, 1]^4 for this observation (zeros without an estimate)."""
        return tracking_action(
            obs[self.estimator], obs["imu"]["quaternion"], self.height, self.max_velocity, self.gains
        )


__all__ = [
    "HoverGains",
    "HoverTracker",
    "tracking_action",
]
