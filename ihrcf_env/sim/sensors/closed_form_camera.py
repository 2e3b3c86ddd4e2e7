"""The projected tag camera with closed-form rays: :class:`ClosedFormTagCamera`, one read of
:meth:`ProjectedTagCamera.read <ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera.read>` for N
worlds at once (the numpy reference of the JAX backend's :mod:`ihrcf_env.fast.tag_camera`).

Each world's tag corners (and its quiet zone's) are projected through the true camera, the depth
range is checked, the detector model (:mod:`~ihrcf_env.sim.sensors.corner_model`) adds the
correlated corner error from each world's own generator and decides the model's failures, and occlusion
comes from the closed-form rays of :mod:`~ihrcf_env.sim.sensors.rays` (the ground, the Stewart
base, the deck plate and the drone's own collision boxes) instead of PyBullet's ``rayTestBatch``.
A row is the scalar read of that world: the same floating-point operations in the same order (the
small matrix products as stacked ``matmul``, one BLAS call per world as in the scalar code) and
the same draws from its generator; only the occlusion rays may differ from Bullet's, within its
convex-cast tolerance, where a ray passes within about a millimetre of a collision surface.

The realistic quality needs each world's :class:`~ihrcf_env.sim.sensors.imaging.EpisodeImaging`
and the drone's velocities: its noise ratio (vignetting, light, exposure) and motion blur are the
scalar read's, with the scene depth on the optical axis from a closed-form ray too. Bullet reports
that depth only within its tolerance, so the realistic rows follow the scalar read closely, and
bit for bit the world's own read with closed-form rays
(:class:`~ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera` with ``closed_form=True``, which
is this read of one world).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.sensors import FULL_SCALE_DN, CameraConfig
from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE, CornerTrack, DetectorModel
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.sim.sensors.base import TAG_STATUS, tag_status_code
from ihrcf_env.sim.sensors.corner_model import CornerTracks, model_corners
from ihrcf_env.sim.sensors.imaging import EpisodeImaging
from ihrcf_env.sim.sensors.rays import RayScene, cast_rays, self_hits, to_local
from ihrcf_env.sim.sensors.tag_camera import RAY_MARGIN_M, REASON_DEPTH, REASON_OCCLUDED

_DEPTH, _OCCLUDED = tag_status_code(REASON_DEPTH), tag_status_code(REASON_OCCLUDED)
_REASONS = np.array(TAG_STATUS)


class ClosedFormTagCamera:
    """The projected tag camera of N worlds (see the module docstring).

    Args:
        camera: the camera (its intrinsics, distortion, near/far planes; quality ``"ideal"``).
        rig: the sensor rig (camera position on the body).
        scene: the worlds' collision scene (:meth:`RayScene.of <ihrcf_env.sim.sensors.rays.RayScene.of>`).
        tag_size: edge of the tag's black square (m).
        model: the fitted detector model.
    """

    def __init__(
        self, camera: CameraConfig, rig: SensorRig, scene: RayScene, tag_size: float, model: DetectorModel
    ) -> None:
        if not isinstance(camera, CameraConfig):
            raise TypeError(f"camera must be a CameraConfig, got {type(camera).__name__}")
        if not isinstance(rig, SensorRig):
            raise TypeError(f"rig must be a SensorRig, got {type(rig).__name__}")
        if not isinstance(scene, RayScene):
            raise TypeError(f"scene must be a RayScene, got {type(scene).__name__}")
        if not isinstance(model, DetectorModel):
            raise TypeError(f"model must be a DetectorModel, got {type(model).__name__}")
        if isinstance(tag_size, bool) or not isinstance(tag_size, int | float | np.floating):
            raise TypeError(f"tag_size must be a real number (m), got {type(tag_size).__name__}")
        corners = tag_corners_deck(float(tag_size))  # validates the value
        self.camera = camera
        self.scene = scene
        self.params = model.params(camera.quality)
        self.K = camera.intrinsics
        self._dist = (float(camera.distortion[0]), float(camera.distortion[1]))
        self._cam_offset = np.asarray(rig.camera_position, dtype=np.float64)
        quiet = corners * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0])
        self._points_deck = np.vstack([corners, quiet, np.zeros((1, 3))])  # 4 corners, 4 quiet, centre
        self.realistic = camera.quality == "realistic"
        im = camera.imaging
        self._vignetting_exponent = float(im.vignetting_exponent)
        self._read_noise = float(im.read_noise_e)
        self._blur_threshold = float(im.blur_threshold_px)

    def _project(self, P: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixels (N, M, 2) of camera-frame points (N, M, 3) (as ``project_points``)."""
        K = self.K
        x = P[..., 0] / P[..., 2]
        y = P[..., 1] / P[..., 2]
        k1, k2 = self._dist
        if k1 or k2:
            r2 = x * x + y * y
            s = 1.0 + k1 * r2 + k2 * r2 * r2
            x, y = x * s, y * s
        return np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], axis=-1)

    def occluded(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        eye: NDArray[np.float64],
        targets: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> NDArray[np.bool_]:
        """(N,) whether a collision body lies between the optical centres ``eye`` (N, 3) and any of
        ``targets`` (N, R, 3) (world, m); the rays stop ``RAY_MARGIN_M`` short of the targets."""
        d = targets - eye[:, None, :]
        ends = targets - d * (RAY_MARGIN_M / np.sqrt((d * d).sum(axis=2)))[..., None]
        starts = np.broadcast_to(eye[:, None, :], ends.shape)
        hits = cast_rays(starts, ends - starts, 1.0, deck_position, deck_rotation, self.scene)
        f_self = _own_fraction(starts, ends - starts, position, rotation)
        blocked = hits.hit | np.isfinite(f_self)
        return np.asarray(blocked.any(axis=1), dtype=bool)

    def read(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
        track: CornerTracks | Sequence[CornerTrack],
        rngs: Sequence[np.random.Generator],
        velocity: NDArray[np.float64] | None = None,
        angular_velocity: NDArray[np.float64] | None = None,
        episodes: Sequence[EpisodeImaging] | None = None,
    ) -> dict[str, NDArray]:
        """One read of N worlds: the drone at ``position`` (N, 3) with ``rotation`` (N, 3, 3; world
        from body), the deck frame (its top face) at ``deck_position`` (N, 3) with ``deck_rotation``
        (N, 3, 3; world from deck); ``track`` each world's correlated error field (a scalar track's
        field drawn here is written back to it), ``rngs`` each world's generator (8 normals and one
        uniform each, then the field at its first use); the realistic quality also takes the
        drones' ``velocity`` and ``angular_velocity`` (N, 3; world, m/s and rad/s) and each world's
        ``episodes`` imaging. Returns the
        :func:`~ihrcf_env.sim.sensors.base.tag_reading` fields stacked: ``tag_corners`` (N, 4, 2)
        px, ``tag_detected`` (N,), ``tag_reason`` (N,) str, ``tag_status`` (N,)."""
        n = len(rngs)
        scalar_tracks = None if isinstance(track, CornerTracks) else list(track)
        batch = CornerTracks.of(scalar_tracks) if scalar_tracks is not None else track
        assert isinstance(batch, CornerTracks)
        if len(batch) != n or len(position) != n:
            raise ValueError(f"{n} generators for {len(position)} poses and {len(batch)} tracks")
        c = self.camera
        R_wb = np.asarray(rotation, dtype=np.float64)
        R_wd = np.asarray(deck_rotation, dtype=np.float64)
        eye = np.asarray(position, dtype=np.float64) + R_wb @ self._cam_offset
        R_wc = R_wb @ R_BODY_CAM
        pts_w = np.asarray(deck_position, dtype=np.float64)[:, None, :] + self._points_deck @ R_wd.transpose(
            0, 2, 1
        )
        P = (pts_w - eye[:, None, :]) @ R_wc  # camera frame
        z = P[:, :8, 2]
        in_range = ~((z.min(axis=1) <= c.near) | (z[:, :4].max(axis=1) >= c.far))
        normals = np.empty((n, 4, 2))
        uniforms = np.empty(n)
        for i, rng in enumerate(rngs):
            normals[i] = rng.standard_normal((4, 2))
            uniforms[i] = rng.random()
        if self.params.corr_max > 0.0:
            for i in np.flatnonzero(in_range & ~batch.drawn).tolist():
                batch._draw(i, rngs[i])
                if scalar_tracks is not None:
                    scalar_tracks[i].omega, scalar_tracks[i].phase = (
                        batch.omega[i].copy(),
                        batch.phase[i].copy(),
                    )
        noise_ratio: NDArray[np.float64] | float = 0.0
        blur: NDArray[np.float64] | float = 0.0
        if self.realistic:
            if velocity is None or angular_velocity is None or episodes is None or len(episodes) != n:
                raise ValueError("the realistic quality needs velocity, angular_velocity and n episodes")
            noise_ratio, blur = self._imaging(
                P, R_wb, R_wc, R_wd, eye, position, deck_position, velocity, angular_velocity, episodes
            )
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            px = self._project(P[:, :8])
            centre = P[:, 8]
            n_c = np.matmul(R_wd[:, None, :, 2], R_wc)
            cos_view = np.abs(n_c @ centre[:, :, None])[:, 0, 0] / np.sqrt(
                (centre[:, None, :] @ centre[:, :, None])[:, 0, 0]
            )
            corners, status = model_corners(
                self.params,
                px[:, :4],
                px[:, 4:],
                cos_view,
                c.width,
                c.height,
                noise_ratio,
                blur,
                normals,
                uniforms,
                batch,
            )
        status[~in_range] = _DEPTH
        check = np.flatnonzero(status == 0)
        if check.size:
            occ = self.occluded(
                position[check],
                R_wb[check],
                eye[check],
                pts_w[check][:, [0, 1, 2, 3, 8]],
                deck_position[check],
                R_wd[check],
            )
            status[check[occ]] = _OCCLUDED
        detected = status == 0
        return {
            "tag_corners": np.where(detected[:, None, None], corners, 0.0),
            "tag_detected": detected,
            "tag_reason": _REASONS[status],
            "tag_status": status,
        }

    def _imaging(
        self,
        P: NDArray[np.float64],
        R_wb: NDArray[np.float64],
        R_wc: NDArray[np.float64],
        R_wd: NDArray[np.float64],
        eye: NDArray[np.float64],
        position: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        velocity: NDArray[np.float64],
        angular_velocity: NDArray[np.float64],
        episodes: Sequence[EpisodeImaging],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The realistic quality's noise ratio (N, 4) at the corners and motion blur (N,) px, as
        :meth:`ProjectedTagCamera._observe` computes them (the depth from a closed-form ray)."""
        imaging = self.camera.imaging
        light = np.array([e.light_direction for e in episodes], dtype=np.float64)
        ambient = np.array([e.ambient for e in episodes])
        diffuse = np.array([e.diffuse for e in episodes])
        brightness = np.array([e.brightness for e in episodes])
        exposure = np.array([e.exposure_s for e in episodes])
        e_per_dn = np.array([imaging.electrons_per_dn(e.gain) for e in episodes])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            x = P[:, :4, :2] / P[:, :4, 2:3]
            vig = (1.0 + (x * x).sum(axis=2)) ** (-0.5 * self._vignetting_exponent)
            n_w = R_wd[:, :, 2]
            cos_light = n_w[:, 0] * light[:, 0] + n_w[:, 1] * light[:, 1] + n_w[:, 2] * light[:, 2]
            shade = np.minimum(1.0, ambient + diffuse * np.maximum(0.0, cos_light))
            white = np.minimum(FULL_SCALE_DN * shade[:, None] * brightness[:, None] * vig, FULL_SCALE_DN)
            w = np.maximum(white, 1.0)
            g = e_per_dn[:, None]
            noise_ratio = np.sqrt((self._read_noise / g) ** 2 + 0.5 * w / g) / w
        omega = np.asarray(angular_velocity, dtype=np.float64)
        r = R_wb @ self._cam_offset
        v_eye = np.asarray(velocity, dtype=np.float64) + np.stack(
            [
                omega[:, 1] * r[:, 2] - omega[:, 2] * r[:, 1],
                omega[:, 2] * r[:, 0] - omega[:, 0] * r[:, 2],
                omega[:, 0] * r[:, 1] - omega[:, 1] * r[:, 0],
            ],
            axis=1,
        )
        depth = self.axis_depth(position, R_wb, eye, R_wc, deck_position, R_wd)
        v_c = np.einsum("nji,nj->ni", R_wc, v_eye)
        w_c = np.einsum("nji,nj->ni", R_wc, omega)
        z = np.maximum(depth, 1e-3)
        K = self.K
        du = K[0, 0] * (-v_c[:, 0] / z - w_c[:, 1]) * exposure
        dv = K[1, 1] * (-v_c[:, 1] / z + w_c[:, 0]) * exposure
        blur = np.hypot(du, dv)
        return noise_ratio, np.where(blur <= self._blur_threshold, 0.0, blur)

    def axis_depth(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        eye: NDArray[np.float64],
        R_wc: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """(N,) distance (m) along the optical axis to the first collision surface within the far
        plane (the drone's own boxes included), else to the ground plane z = 0 (the far plane when
        the axis does not look down), as the scalar read's depth."""
        far = self.camera.far
        axis = R_wc[:, :, 2]
        starts = eye[:, None, :]
        dirs = axis[:, None, :] * far
        hits = cast_rays(starts, dirs, 1.0, deck_position, deck_rotation, self.scene)
        f = np.where(hits.hit[:, 0], hits.fraction[:, 0], np.inf)
        f = np.minimum(f, _own_fraction(starts, dirs, position, rotation)[:, 0])
        down = -axis[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            fallback = np.where(down > 1e-3, eye[:, 2] / down, far)
        return np.where(np.isfinite(f), f * far, fallback)


def _own_fraction(
    starts: NDArray[np.float64],
    segments: NDArray[np.float64],
    position: NDArray[np.float64],
    rotation: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(N, R) fraction at which each segment ``starts + f segments`` (N, R, 3; world) enters its
    drone's own collision boxes (``inf``: never), the drone at ``position`` with ``rotation``."""
    s_body = to_local(starts - position[:, None, :], rotation)
    d_body = to_local(np.broadcast_to(segments, s_body.shape), rotation)
    f, _ = self_hits(s_body.reshape(-1, 3), d_body.reshape(-1, 3), 1.0)
    return f.reshape(s_body.shape[:2])


__all__ = [
    "ClosedFormTagCamera",
]
