"""The projected tag camera's reading for one environment: the tag through the camera
(:func:`ihrcf_env.fast.camera.tag_view`), the depth range, the fitted detector model
(:func:`ihrcf_env.fast.detector.detect`) and the occlusion rays from the optical centre to the
tag's corners and centre (the scene and the drone's own boxes); the port of
:meth:`ihrcf_env.sim.batched.tag_camera.BatchedTagCamera.read`.

The realistic camera's imaging inputs (noise ratio, motion blur) are arguments (zero: the ideal
camera). The draws (eight normals, one uniform, the episode's field) are inputs. Frames and units
as :mod:`ihrcf_env.fast.camera`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE, DetectorModel
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast.camera import tag_view
from ihrcf_env.fast.detector import STATUS_DEPTH, DetectorParams, detect, detector_params
from ihrcf_env.fast.linalg3 import matvec, tmatvec
from ihrcf_env.fast.rays import Scene, cast_rays, own_fraction

__all__ = ["STATUS_OCCLUDED", "TagCameraSetup", "TagReading", "tag_camera_setup", "tag_read"]

#: Status code of a tag hidden behind a collision body (the reading's status table).
STATUS_OCCLUDED = 10


class TagCameraSetup(NamedTuple):
    """Host-side constants of the projected camera: the tag's ``points_deck`` (9, 3: corners,
    quiet-zone corners, centre), ``camera_offset`` (3,; body), ``K`` (3, 3), ``distortion`` (k1,
    k2), ``near`` / ``far`` (m), ``width`` / ``height`` (px), the ``detector`` parameters of the
    camera's quality, the collision ``scene``, the drone's ``box_centres`` / ``box_halves`` (B, 3;
    body) and ``ray_margin`` (m: the occlusion rays stop that short of the deck's surface)."""

    points_deck: np.ndarray
    camera_offset: np.ndarray
    K: np.ndarray
    distortion: np.ndarray
    near: float
    far: float
    width: int
    height: int
    detector: DetectorParams
    scene: Scene
    box_centres: np.ndarray
    box_halves: np.ndarray
    ray_margin: float


class TagReading(NamedTuple):
    """The tag-corner reading: ``corners`` (4, 2) px (zeros when not detected), ``detected``,
    ``status`` (the reading's status code, 0: detected)."""

    corners: Array
    detected: Array
    status: Array


def tag_camera_setup(
    camera: CameraConfig,
    rig: SensorRig,
    tag_size: float,
    model: DetectorModel,
    scene: Scene,
    boxes: tuple[np.ndarray, np.ndarray],
    ray_margin: float = 0.002,
) -> TagCameraSetup:
    """The :class:`TagCameraSetup` of a camera, rig, tag (edge ``tag_size`` m), fitted detector
    model, collision scene and the drone's collision ``boxes`` (centres, half extents)."""
    corners = tag_corners_deck(float(tag_size))
    quiet = corners * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0])
    return TagCameraSetup(
        np.vstack([corners, quiet, np.zeros((1, 3))]),
        np.asarray(rig.camera_position, dtype=np.float64),
        np.asarray(camera.intrinsics, dtype=np.float64),
        np.asarray(camera.distortion, dtype=np.float64),
        float(camera.near),
        float(camera.far),
        int(camera.width),
        int(camera.height),
        detector_params(model.params(camera.quality)),
        scene,
        np.asarray(boxes[0], dtype=np.float64),
        np.asarray(boxes[1], dtype=np.float64),
        float(ray_margin),
    )


def tag_read(
    setup: TagCameraSetup,
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    normals: Array,
    uniform: Array,
    omega: Array,
    phase: Array,
    noise_ratio: Array | float = 0.0,
    blur_px: Array | float = 0.0,
) -> TagReading:
    """One frame of the drone at ``position`` (3,) with ``rotation`` (3, 3; world from body), the
    deck frame (its top face) at ``deck_position`` with ``deck_rotation``, given the frame's draws
    and the episode's field (:func:`~ihrcf_env.fast.detector.detect`)."""
    s = setup
    v = tag_view(
        position, rotation, deck_position, deck_rotation, jnp.asarray(s.points_deck),
        jnp.asarray(s.camera_offset), jnp.asarray(s.K), jnp.asarray(s.distortion), s.near, s.far,
    )  # fmt: skip
    corners, status = detect(
        s.detector, v.pixels, v.quiet, v.cos_view, s.width, s.height, jnp.asarray(noise_ratio),
        jnp.asarray(blur_px), normals, uniform, omega, phase,
    )  # fmt: skip
    status = jnp.where(v.in_range, status, STATUS_DEPTH)
    # occlusion: rays from the optical centre to the tag's corners and centre
    pts = jnp.asarray(s.points_deck)[jnp.array([0, 1, 2, 3, 8])]
    targets = deck_position + matvec(deck_rotation, pts)
    d = targets - v.eye
    ends = targets - d * (s.ray_margin / jnp.sqrt(jnp.sum(d * d, axis=1)))[:, None]
    starts = jnp.broadcast_to(v.eye, ends.shape)
    seg = ends - starts
    hits = cast_rays(starts, seg, 1.0, deck_position, deck_rotation, s.scene)
    f_self = own_fraction(
        tmatvec(rotation, starts - position), tmatvec(rotation, seg), s.box_centres, s.box_halves
    )
    occluded = jnp.any(hits.hit | jnp.isfinite(f_self))
    status = jnp.where((status == 0) & occluded, STATUS_OCCLUDED, status)
    detected = status == 0
    return TagReading(jnp.where(detected, corners, 0.0), detected, status)
