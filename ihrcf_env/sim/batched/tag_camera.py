"""One read of the projected tag camera for N worlds at once: the batched twin of
:meth:`ProjectedTagCamera.read <ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera.read>`.

Each world's tag corners (and its quiet zone's) are projected through the true camera, the depth
range is checked, the detector model (:mod:`~ihrcf_env.sim.batched.detector`) adds the correlated
corner error from each world's own generator and decides the model's failures, and occlusion
comes from the closed-form rays of :mod:`~ihrcf_env.sim.batched.rays` (the ground, the Stewart
base, the deck plate and the drone's own collision boxes) instead of PyBullet's ``rayTestBatch``.
A row is the scalar read of that world: the same floating-point operations in the same order (the
small matrix products as stacked ``matmul``, one BLAS call per world as in the scalar code) and
the same draws from its generator; only the occlusion rays may differ from Bullet's, within its
convex-cast tolerance, where a ray passes within about a millimetre of a collision surface.

The camera quality ``"ideal"`` only: the realistic quality's motion blur needs the scene depth on
the optical axis, which Bullet reports only within its tolerance, and its episode imaging.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.detector_model import QUIET_ZONE_SCALE, CornerTrack, DetectorModel
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.sim.batched.detector import BatchedCornerTrack, model_corners
from ihrcf_env.sim.batched.rays import RayScene, cast_rays, self_hits, to_local
from ihrcf_env.sim.sensors.base import TAG_STATUS, tag_status_code
from ihrcf_env.sim.sensors.camera import CameraConfig
from ihrcf_env.sim.sensors.tag_camera import RAY_MARGIN_M, REASON_DEPTH, REASON_OCCLUDED

_DEPTH, _OCCLUDED = tag_status_code(REASON_DEPTH), tag_status_code(REASON_OCCLUDED)
_REASONS = np.array(TAG_STATUS)


class BatchedTagCamera:
    """The projected tag camera of N worlds (see the module docstring).

    Args:
        camera: the camera (its intrinsics, distortion, near/far planes; quality ``"ideal"``).
        rig: the sensor rig (camera position on the body).
        scene: the worlds' collision scene (:meth:`RayScene.of <ihrcf_env.sim.batched.rays.RayScene.of>`).
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
        if camera.quality != "ideal":
            raise ValueError(
                f'the batched projected camera supports quality "ideal" only, got {camera.quality!r}'
            )
        corners = tag_corners_deck(float(tag_size))  # validates the value
        self.camera = camera
        self.scene = scene
        self.params = model.params(camera.quality)
        self.K = camera.intrinsics
        self._dist = (float(camera.distortion[0]), float(camera.distortion[1]))
        self._cam_offset = np.asarray(rig.camera_position, dtype=np.float64)
        quiet = corners * np.array([QUIET_ZONE_SCALE, QUIET_ZONE_SCALE, 1.0])
        self._points_deck = np.vstack([corners, quiet, np.zeros((1, 3))])  # 4 corners, 4 quiet, centre

    def same_as(self, other: BatchedTagCamera) -> bool:
        """True when ``other`` reads as this one does (one batched read serves the worlds of both)."""
        return (
            self.camera == other.camera
            and self.scene == other.scene
            and self.params == other.params
            and np.array_equal(self._cam_offset, other._cam_offset)
            and np.array_equal(self._points_deck, other._points_deck)
        )

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
        s_body = to_local(starts - position[:, None, :], rotation)
        d_body = to_local(ends - starts, rotation)
        f_self, _ = self_hits(s_body.reshape(-1, 3), d_body.reshape(-1, 3), 1.0)
        blocked = hits.hit | np.isfinite(f_self).reshape(hits.hit.shape)
        return np.asarray(blocked.any(axis=1), dtype=bool)

    def read(
        self,
        position: NDArray[np.float64],
        rotation: NDArray[np.float64],
        deck_position: NDArray[np.float64],
        deck_rotation: NDArray[np.float64],
        track: BatchedCornerTrack | Sequence[CornerTrack],
        rngs: Sequence[np.random.Generator],
    ) -> dict[str, NDArray]:
        """One read of N worlds: the drone at ``position`` (N, 3) with ``rotation`` (N, 3, 3; world
        from body), the deck frame (its top face) at ``deck_position`` (N, 3) with ``deck_rotation``
        (N, 3, 3; world from deck); ``track`` each world's correlated error field (a scalar track's
        field drawn here is written back to it), ``rngs`` each world's generator (8 normals and one
        uniform each, then the field at its first use). Returns the
        :func:`~ihrcf_env.sim.sensors.base.tag_reading` fields stacked: ``tag_corners`` (N, 4, 2)
        px, ``tag_detected`` (N,), ``tag_reason`` (N,) str, ``tag_status`` (N,)."""
        n = len(rngs)
        scalar_tracks = None if isinstance(track, BatchedCornerTrack) else list(track)
        batch = BatchedCornerTrack.of(scalar_tracks) if scalar_tracks is not None else track
        assert isinstance(batch, BatchedCornerTrack)
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
                0.0,
                0.0,
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
