"""The raw reading of one landing env after a control step, as arrays (one env, no batch axis).

:class:`RawReading` holds what :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`'s raw
observation holds with the projected camera and ``camera_output="corners"`` (the keys in the
comments), plus the episode time; :class:`Truth` holds the ground truth the env's ``info`` carries
(for the privileged observation block and for analysis; never fed to the estimators). The physics
and sensor step (:mod:`ihrcf_env.fast`) produces both; the estimator stage and the observation take
a :class:`RawReading`. Frames: world z up; body (world from body); heading as in
:mod:`ihrcf_env.wrappers.landing_obs`. Units SI.
"""

from __future__ import annotations

from typing import NamedTuple

from jax import Array

__all__ = ["RawReading", "Truth"]


class RawReading(NamedTuple):
    """One env's raw sensor reading at the end of a control step."""

    time: Array  # s, episode time (control steps x control period)
    tag_corners: Array  # (4, 2) px, "tag_corners" (zeros when not detected)
    tag_detected: Array  # bool, "tag_detected"
    tag_status: Array  # int32, "tag_status" (0: detected; TAG_STATUS codes)
    camera_age: Array  # s, "camera_age" (age of the frame shown since its exposure; 10 before the first)
    camera_frame: Array  # int32, "camera_frame" (frames delivered so far; with a camera latency)
    ranges: Array  # (4,) m, "ranges" (invalid readings read max_range)
    ranges_valid: Array  # (4,) bool, "ranges_valid"
    imu_quaternion: Array  # (4,) x, y, z, w world from body, "imu"["quaternion"]
    imu_angular_velocity: Array  # (3,) rad/s body, "imu"["angular_velocity"]
    imu_linear_acceleration: Array  # (3,) m/s^2 specific force body, "imu"["linear_acceleration"]
    nav_velocity: Array  # (3,) m/s world, "nav_velocity"


class Truth(NamedTuple):
    """One env's ground truth at the end of a control step (the env's ``info`` keys)."""

    drone_position_world: Array  # (3,) m
    drone_quaternion_world: Array  # (4,) x, y, z, w
    deck_position_world: Array  # (3,) m, the deck origin (tag centre on the top face)
    deck_quaternion_world: Array  # (4,) x, y, z, w
    deck_position_body: Array  # (3,) m, body frame
    deck_rotation_body: Array  # (3, 3) body from deck
    relative_velocity: Array  # (3,) m/s world, drone minus deck point under it
    wind_velocity: Array  # (3,) m/s world
