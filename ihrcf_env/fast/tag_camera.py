"""The projected tag camera's reading for one environment: the tag through the camera
(:func:`ihrcf_env.fast.camera.tag_view`), the depth range, the fitted detector model
(:func:`ihrcf_env.fast.detector.detect`) and the occlusion rays from the optical centre to the
tag's corners and centre (the scene and the drone's own boxes); the port of
:meth:`ihrcf_env.sim.sensors.closed_form_camera.ClosedFormTagCamera.read`.

The realistic camera's noise ratio and motion blur come from the episode's imaging draw and the
drone's velocities (:class:`Imaging`; None: the ideal camera). The draws (eight normals, one
uniform, the episode's field) are inputs. Frames and units as :mod:`ihrcf_env.fast.camera`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.config.sensors import FULL_SCALE_DN, CameraConfig
from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE, DetectorModel
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast.camera import tag_view
from ihrcf_env.fast.detector import STATUS_DEPTH, DetectorParams, detect, detector_params
from ihrcf_env.fast.linalg3 import cross, matvec, tmatvec
from ihrcf_env.fast.rays import Scene, cast_rays, own_fraction

__all__ = [
    "STATUS_OCCLUDED",
    "Imaging",
    "TagCameraSetup",
    "TagReading",
    "imaging_of",
    "tag_camera_setup",
    "tag_read",
]

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
    vignetting_exponent: float
    read_noise_e: float
    blur_threshold_px: float
    full_well_e: float


class Imaging(NamedTuple):
    """The realistic camera's inputs of a frame: the episode's ``light`` direction (3,; world,
    towards the light), ``ambient``, ``diffuse``, ``brightness`` and ``exposure`` (s) and gain
    (``gain``, 1 = 0 dB), and the drone's ``velocity`` and ``angular_velocity`` (3,; world)."""

    light: Array
    ambient: Array
    diffuse: Array
    brightness: Array
    exposure: Array
    gain: Array
    velocity: Array
    angular_velocity: Array


def imaging_of(episode: object, velocity: Array, angular_velocity: Array) -> Imaging:
    """The :class:`Imaging` of an episode's imaging draw (the fields of the simulator's
    ``EpisodeImaging``) and the drone's velocities."""
    e: Any = episode

    def f(x: object) -> Array:
        return jnp.asarray(np.asarray(x, dtype=np.float64))

    return Imaging(
        f(e.light_direction), f(e.ambient), f(e.diffuse), f(e.brightness), f(e.exposure_s), f(e.gain),
        velocity, angular_velocity,
    )  # fmt: skip


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
        float(camera.imaging.vignetting_exponent),
        float(camera.imaging.read_noise_e),
        float(camera.imaging.blur_threshold_px),
        float(camera.imaging.full_well_e),
    )


def _imaging(
    s: TagCameraSetup,
    v: Any,
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    im: Imaging,
) -> tuple[Array, Array]:
    """The realistic camera's noise ratio (4,) at the corners and motion blur (px) of a frame (the
    depth along the optical axis from a closed-form ray)."""
    P = v.points
    x = P[:4, :2] / P[:4, 2:3]
    vig = (1.0 + jnp.sum(x * x, axis=1)) ** (-0.5 * s.vignetting_exponent)
    n_w = deck_rotation[:, 2]
    cos_light = n_w[0] * im.light[0] + n_w[1] * im.light[1] + n_w[2] * im.light[2]
    shade = jnp.minimum(1.0, im.ambient + im.diffuse * jnp.maximum(0.0, cos_light))
    white = jnp.minimum(FULL_SCALE_DN * shade * im.brightness * vig, FULL_SCALE_DN)
    w = jnp.maximum(white, 1.0)
    g = s.full_well_e / (FULL_SCALE_DN * im.gain)
    noise_ratio = jnp.sqrt((s.read_noise_e / g) ** 2 + 0.5 * w / g) / w
    R_wc = rotation @ jnp.asarray(R_BODY_CAM, dtype=rotation.dtype)
    r = matvec(rotation, jnp.asarray(s.camera_offset))
    v_eye = im.velocity + cross(im.angular_velocity, r)
    # depth along the optical axis: the first surface within the far plane, else the ground
    axis = R_wc[:, 2]
    dirs = (axis * s.far)[None]
    starts = v.eye[None]
    hits = cast_rays(starts, dirs, 1.0, deck_position, deck_rotation, s.scene)
    f = jnp.where(hits.hit[0], hits.fraction[0], jnp.inf)
    own = own_fraction(
        tmatvec(rotation, starts - position), tmatvec(rotation, dirs), s.box_centres, s.box_halves
    )[0]
    f = jnp.minimum(f, own)
    down = -axis[2]
    fallback = jnp.where(down > 1e-3, v.eye[2] / jnp.where(down > 1e-3, down, 1.0), s.far)
    depth = jnp.where(jnp.isfinite(f), f * s.far, fallback)
    v_c = tmatvec(R_wc, v_eye)
    w_c = tmatvec(R_wc, im.angular_velocity)
    z = jnp.maximum(depth, 1e-3)
    du = s.K[0, 0] * (-v_c[0] / z - w_c[1]) * im.exposure
    dv = s.K[1, 1] * (-v_c[1] / z + w_c[0]) * im.exposure
    blur = jnp.hypot(du, dv)
    return noise_ratio, jnp.where(blur <= s.blur_threshold_px, 0.0, blur)


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
    imaging: Imaging | None = None,
) -> TagReading:
    """One frame of the drone at ``position`` (3,) with ``rotation`` (3, 3; world from body), the
    deck frame (its top face) at ``deck_position`` with ``deck_rotation``, given the frame's draws
    and the episode's field (:func:`~ihrcf_env.fast.detector.detect`); ``imaging``: the realistic
    camera's inputs (None: the ideal camera)."""
    s = setup
    v = tag_view(
        position, rotation, deck_position, deck_rotation, jnp.asarray(s.points_deck),
        jnp.asarray(s.camera_offset), jnp.asarray(s.K), jnp.asarray(s.distortion), s.near, s.far,
    )  # fmt: skip
    noise_ratio: Array = jnp.zeros(4, dtype=position.dtype)
    blur_px: Array = jnp.zeros((), dtype=position.dtype)
    if imaging is not None:
        noise_ratio, blur_px = _imaging(s, v, position, rotation, deck_position, deck_rotation, imaging)
    corners, status = detect(
        s.detector, v.pixels, v.quiet, v.cos_view, s.width, s.height, noise_ratio, blur_px, normals,
        uniform, omega, phase,
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
