"""The "projected" tag camera: the tag's corners as the rendered detector would report them, without
rendering (a :class:`~ihrcf_env.sim.sensors.base.Sensor` named :data:`TAG_CAMERA`).

Every read projects the tag's corners (and the outer corners of its white quiet zone) exactly
through the true camera -- ``CameraConfig.intrinsics`` (principal point (W/2, H/2 - 1),
TinyRenderer's), its radial distortion (k1, k2) and the drone's pose through the rig, as
:meth:`~ihrcf_env.sim.sensors.camera.DownCamera.pose` --
and hands them to the fitted :class:`~ihrcf_env.core.detector_model.DetectorModel`,
which adds the corner error of the render + ``TagDetector`` (``refine="subpix"``) pipeline, its
frame-to-frame correlation, and its failures (tag at or over the image border, its quiet zone cut
by the border, too small, too oblique). What only the simulator knows is decided here: the tag
outside the camera's depth range (behind it, nearer than ``near`` or beyond ``far``: the renderer
would not draw it) and occlusion, by one ``rayTestBatch`` from the optical centre to the four
corners and the tag centre (bodies with a collision shape only: visual-only bodies are invisible to
rays). The realistic quality draws the episode's light, exposure and gain exactly as the rendered
camera does (:func:`~ihrcf_env.sim.sensors.imaging.draw_episode`) and turns them into the noise
ratio of each corner, and the drone's motion into the image motion during the exposure (the same
formula as the rendered blur, with the scene depth on the optical axis from one more ray).

It renders nothing, so a read costs a small fraction of a rendered frame (``docs/results.md``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.config.sensors import FULL_SCALE_DN, CameraConfig
from ihrcf_env.core.detector_model import (
    QUIET_ZONE_SCALE,
    CornerTrack,
    DetectorModel,
    TagFeatures,
    noise_to_contrast,
    project_points,
    tag_features,
)
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.sim.deck import Deck
from ihrcf_env.sim.sensors.base import TAG_CAMERA, BodyState, tag_reading
from ihrcf_env.sim.sensors.imaging import EpisodeImaging, draw_episode, image_motion_px

if TYPE_CHECKING:
    from ihrcf_env.sim.sensors.closed_form_camera import ClosedFormTagCamera

#: Failure reasons decided by the simulator (the model's are in detector_model).
REASON_DEPTH = "tag outside the camera's depth range"
REASON_OCCLUDED = "tag occluded"

#: Occlusion rays stop this far (m) before the tag's corners, which lie on the deck's surface.
RAY_MARGIN_M = 0.002


class ProjectedTagCamera:
    """Tag corners from the exact projection + the fitted detector model (see the module docstring).

    Args:
        client: PyBullet client of the world (for the occlusion rays).
        camera: the camera (its intrinsics, distortion, near/far planes, quality and imaging).
        rig: the sensor rig (camera position on the body).
        deck: the world's deck (its pose is read at every read).
        tag_size: edge of the tag's black square (m).
        model: the fitted detector model (:meth:`DetectorModel.load`).
        closed_form: cast the occlusion and depth rays in closed form against the world's scene
            (:class:`~ihrcf_env.sim.sensors.closed_form_camera.ClosedFormTagCamera`, its read of
            this one world) instead of PyBullet's ``rayTestBatch``.

    ``read`` returns :func:`~ihrcf_env.sim.sensors.base.tag_reading`; :attr:`last_features` keeps
    the last frame's :class:`~ihrcf_env.core.detector_model.TagFeatures` (None when the
    tag was outside the depth range).
    """

    name = TAG_CAMERA

    def __init__(
        self,
        client: int,
        camera: CameraConfig,
        rig: SensorRig,
        deck: Deck,
        tag_size: float,
        model: DetectorModel,
        closed_form: bool = False,
    ) -> None:
        if not isinstance(camera, CameraConfig):
            raise TypeError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        if not isinstance(rig, SensorRig):
            raise TypeError(f"rig must be a SensorRig, got {type(rig).__name__}")
        if not isinstance(model, DetectorModel):
            raise TypeError(f"model must be a DetectorModel, got {type(model).__name__}")
        if isinstance(tag_size, bool) or not isinstance(tag_size, int | float | np.floating):
            raise TypeError(f"tag_size must be a real number (m), got {type(tag_size).__name__}")
        corners = tag_corners_deck(float(tag_size))  # validates the value
        self.client = int(client)
        self.camera = camera
        self.deck = deck
        self.model = model
        self.quality = camera.quality
        model.params(camera.quality)  # the model must cover this quality
        self.K = camera.intrinsics
        self._dist = (float(camera.distortion[0]), float(camera.distortion[1]))
        self._cam_offset = np.asarray(rig.camera_position, dtype=np.float64)
        quiet = corners * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0])
        self._points_deck = np.vstack([corners, quiet, np.zeros((1, 3))])  # 4 corners, 4 quiet, centre
        self.track = CornerTrack()
        self.episode: EpisodeImaging | None = None
        self.last_features: TagFeatures | None = None
        im = camera.imaging
        self._vignetting_exponent = float(im.vignetting_exponent)
        self._read_noise = float(im.read_noise_e)
        self._blur_threshold = float(im.blur_threshold_px)
        self._e_per_dn = math.nan
        self._deck_half = float(deck.config.thickness) / 2.0
        #: closed-form rays: every read is the closed-form camera's read of this world (None:
        #: PyBullet's rays)
        self.closed_form: ClosedFormTagCamera | None = None
        if closed_form:
            from ihrcf_env.sim.sensors.closed_form_camera import ClosedFormTagCamera
            from ihrcf_env.sim.sensors.rays import RayScene

            g = deck.geometry
            scene = RayScene.of(deck.config.size, deck.config.thickness, g.base_radius, g.base_height)
            self.closed_form = ClosedFormTagCamera(camera, rig, scene, float(tag_size), model)

    def reset(self, rng: np.random.Generator, episode: EpisodeImaging | None = None) -> None:
        """Start an episode. The realistic quality first draws the episode's light, exposure and
        gain from ``rng`` exactly as the rendered camera's first draw
        (:func:`~ihrcf_env.sim.sensors.imaging.draw_episode`), unless ``episode`` gives them (e.g.
        a rendered camera's :attr:`~ihrcf_env.sim.sensors.camera.DownCamera.episode`); then both
        qualities draw the episode's correlated-error field
        (:class:`~ihrcf_env.core.detector_model.CornerTrack`, 768 numbers)."""
        if self.quality == "realistic":
            self.episode = episode if episode is not None else draw_episode(self.camera.imaging, rng)
            self._e_per_dn = self.camera.imaging.electrons_per_dn(self.episode.gain)
        self.track.reset(rng)

    def _deck_pose(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World pose of the deck frame (as :meth:`Deck.pose <ihrcf_env.sim.deck.Deck.pose>`, faster)."""
        pos, quat = p.getBasePositionAndOrientation(self.deck.body, physicsClientId=self.client)
        R = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        return np.array(pos) + R[:, 2] * self._deck_half, R

    def _geometry(
        self, state: BodyState
    ) -> tuple[
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
    ]:
        """(eye, R_wb, R_wc, R_wd, world points (9, 3): corners, quiet zone, centre)."""
        R_wb = np.asarray(state.rotation, dtype=np.float64)
        eye = np.asarray(state.position, dtype=np.float64) + R_wb @ self._cam_offset
        deck_pos, R_wd = self._deck_pose()
        return eye, R_wb, R_wb @ R_BODY_CAM, R_wd, deck_pos + self._points_deck @ R_wd.T

    def _rays(
        self, eye: NDArray[np.float64], R_wc: NDArray[np.float64], pts_w: NDArray[np.float64], axis: bool
    ) -> tuple[bool, float]:
        """One ``rayTestBatch``: occlusion of the four corners and the centre (rays stop
        :data:`RAY_MARGIN_M` short of the deck surface) and, with ``axis``, the depth (m) along the
        optical axis to the first collision body (else to the ground plane z = 0, as the rendered
        camera's blur uses the z-buffer at the principal point; NaN without ``axis``)."""
        targets = pts_w[[0, 1, 2, 3, 8]]
        d = targets - eye
        ends = targets - d * (RAY_MARGIN_M / np.sqrt((d * d).sum(axis=1)))[:, None]
        far = self.camera.far
        starts = [eye.tolist()] * (6 if axis else 5)
        end_list = ends.tolist()
        if axis:
            end_list.append((eye + R_wc[:, 2] * far).tolist())
        hits = p.rayTestBatch(starts, end_list, physicsClientId=self.client)
        occluded = any(h[0] >= 0 for h in hits[:5])
        depth = math.nan
        if axis:
            h = hits[5]
            if h[0] >= 0:
                depth = float(h[2]) * far
            else:
                down = -float(R_wc[2, 2])
                depth = float(eye[2]) / down if down > 1e-3 else far
        return occluded, depth

    def features(self, state: BodyState) -> tuple[TagFeatures | None, str]:
        """The frame's :class:`TagFeatures` from the true state, or ``(None, reason)`` when the tag
        is outside the camera's depth range. Occlusion is not checked here (see :meth:`occluded`)."""
        f, reason, _ = self._observe(state, rays=False)
        return f, reason

    def occluded(self, state: BodyState) -> bool:
        """Whether a collision body lies between the optical centre and any of the tag's four
        corners or its centre (rays stop :data:`RAY_MARGIN_M` short of the deck surface)."""
        eye, _, R_wc, _, pts_w = self._geometry(state)
        return self._rays(eye, R_wc, pts_w, axis=False)[0]

    def _observe(self, state: BodyState, rays: bool) -> tuple[TagFeatures | None, str, bool]:
        """(features or None, reason, occluded); the rays are cast only with ``rays`` (then the
        realistic camera's scene depth comes from the same batch)."""
        eye, R_wb, R_wc, R_wd, pts_w = self._geometry(state)
        P = (pts_w - eye) @ R_wc  # camera frame
        c = self.camera
        z = P[:8, 2]
        if z.min() <= c.near or z[:4].max() >= c.far:
            return None, REASON_DEPTH, False
        realistic = self.quality == "realistic"
        occluded, depth = self._rays(eye, R_wc, pts_w, realistic) if rays else (False, math.nan)
        px = project_points(P[:8], self.K, self._dist)
        centre = P[8]
        n_c = R_wd[:, 2] @ R_wc
        cos_view = abs(float(n_c @ centre)) / math.sqrt(float(centre @ centre))
        noise_ratio: NDArray[np.float64] | float = 0.0
        blur = 0.0
        if realistic:
            ep = self.episode
            if ep is None:
                raise RuntimeError("the realistic projected camera needs reset(rng) before read")
            x = P[:4, :2] / P[:4, 2:3]
            vig = (1.0 + (x * x).sum(axis=1)) ** (-0.5 * self._vignetting_exponent)
            light = ep.light_direction
            n_w = R_wd[:, 2]
            cos_light = float(n_w[0] * light[0] + n_w[1] * light[1] + n_w[2] * light[2])
            shade = min(1.0, ep.ambient + ep.diffuse * max(0.0, cos_light))
            white = np.minimum(FULL_SCALE_DN * shade * ep.brightness * vig, FULL_SCALE_DN)
            noise_ratio = noise_to_contrast(white, self._e_per_dn, self._read_noise)
            omega = np.asarray(state.angular_velocity, dtype=np.float64)
            r = R_wb @ self._cam_offset
            v_eye = np.asarray(state.velocity, dtype=np.float64) + np.array(
                [
                    omega[1] * r[2] - omega[2] * r[1],
                    omega[2] * r[0] - omega[0] * r[2],
                    omega[0] * r[1] - omega[1] * r[0],
                ]
            )
            if math.isnan(depth):
                depth = self._rays(eye, R_wc, pts_w, True)[1]
            du, dv = image_motion_px(self.K, R_wc, v_eye, omega, depth, ep.exposure_s)
            blur = math.hypot(du, dv)
            if blur <= self._blur_threshold:  # the rendered camera does not blur below it
                blur = 0.0
        f = tag_features(px[:4], px[4:], cos_view, c.width, c.height, noise_ratio, blur)
        return f, "", occluded

    def read(self, state: BodyState, dt: float, rng: np.random.Generator) -> dict[str, NDArray]:
        """:func:`~ihrcf_env.sim.sensors.base.tag_reading` of the frame at ``state``. Draws 8
        normals and one uniform from ``rng`` whatever happens (reproducible streams; and the
        realistic episode first, if :meth:`reset` was not called)."""
        if self.closed_form is not None:
            return self._read_closed_form(state, rng)
        if self.quality == "realistic" and self.episode is None:
            self.reset(rng)  # as the rendered camera: the episode drawn at the first read
        f, reason, occluded = self._observe(state, rays=True)
        self.last_features = f
        if f is None:
            rng.standard_normal((4, 2))
            rng.random()
            return tag_reading(None, reason)
        corners, reason = self.model.corners(f, rng, self.quality, self.track)
        if corners is not None and occluded:
            return tag_reading(None, REASON_OCCLUDED)
        return tag_reading(corners, reason)

    def _read_closed_form(self, state: BodyState, rng: np.random.Generator) -> dict[str, NDArray]:
        """The closed-form camera's read of this world (one row)."""
        deck_pos, R_wd = self._deck_pose()
        self.last_features = None
        assert self.closed_form is not None
        if self.quality == "realistic" and self.episode is None:
            self.reset(rng)  # as the rendered camera: the episode drawn at the first read
        pos, R, dp, dR = self.batch_inputs(state, deck_pos, R_wd)
        out = self.closed_form.read(pos, R, dp, dR, [self.track], [rng], **self.imaging_inputs(state))
        return reading_row(out, 0)

    def batch_inputs(
        self, state: BodyState, deck_pos: NDArray[np.float64], R_wd: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The poses of one world as :meth:`ClosedFormTagCamera.read` takes them (rows of N = 1)."""
        pos = np.asarray(state.position, dtype=np.float64)[None]
        R = np.asarray(state.rotation, dtype=np.float64)[None]
        return pos, R, deck_pos[None], R_wd[None]

    def imaging_inputs(self, state: BodyState) -> dict[str, Any]:
        """The realistic quality's inputs of one world to :meth:`ClosedFormTagCamera.read` (none for
        the ideal one)."""
        if self.quality != "realistic":
            return {}
        return {
            "velocity": np.asarray(state.velocity, dtype=np.float64)[None],
            "angular_velocity": np.asarray(state.angular_velocity, dtype=np.float64)[None],
            "episodes": [self.episode],
        }


def reading_row(out: dict[str, NDArray], i: int) -> dict[str, NDArray]:
    """Row ``i`` of a tag reading of N worlds (:meth:`ClosedFormTagCamera.read
    <ihrcf_env.sim.sensors.closed_form_camera.ClosedFormTagCamera.read>`) as
    :func:`~ihrcf_env.sim.sensors.base.tag_reading` gives it."""
    return {
        "tag_corners": np.array(out["tag_corners"][i], dtype=np.float64),
        "tag_detected": np.array(bool(out["tag_detected"][i])),
        "tag_reason": np.array(str(out["tag_reason"][i])),
        "tag_status": np.array(int(out["tag_status"][i])),
    }


__all__ = [
    "RAY_MARGIN_M",
    "REASON_DEPTH",
    "REASON_OCCLUDED",
    "ProjectedTagCamera",
    "reading_row",
]
