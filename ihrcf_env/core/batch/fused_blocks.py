"""The fused filter's measurement blocks
(:class:`~ihrcf_env.core.estimators.fused_measurements.MeasurementBlocks`) over n rows at once.

Each function takes the rows' estimates as arrays (body-frame rotations (n, 3, 3), positions
(n, 3)) and the IMU attitudes ``R_wb`` (n, 3, 3), and returns ``(z, R)`` in the filter's world
axes: ``z`` (n, k), ``R`` (n, k, k) exactly symmetric. The plane-fit shapes are the single
filter's cached ones (one per set of used sensors), so both share them bit for bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.batch.geometry import euler_batch, rigid_fit_batch
from ihrcf_env.core.estimators.fused_measurements import _plane_shape
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

F64 = NDArray[np.float64]
_R_CAM_BODY = np.ascontiguousarray(R_BODY_CAM.T)
_POW2 = np.array([1, 2, 4, 8])


class BlocksBatch:
    """Batched measurement blocks of one filter configuration (arguments as
    :class:`~ihrcf_env.core.estimators.fused_measurements.MeasurementBlocks`)."""

    def __init__(self, params: FusedParams, rig: SensorRig, tag_size: float, max_residual: float) -> None:
        self.params = params
        self.rig = rig
        self.tag_size = tag_size
        self.max_residual = max_residual
        self.model = tag_corners_deck(tag_size)
        self._camera_position = np.array(rig.camera_position, dtype=np.float64)
        xy = rig.sensor_xy_cam
        # per mask of used sensors (bit j = sensor j): plane covariance shape (3, 3), tilt factor
        self._shape = np.zeros((16, 3, 3))
        self._tilt = np.zeros(16)
        for key in range(16):
            used = (key & _POW2) > 0
            if used.sum() >= 3:
                C, tilt = _plane_shape(np.ascontiguousarray(xy[used], dtype=np.float64).tobytes())
                self._shape[key], self._tilt[key] = C, tilt

    def plane(self, used: NDArray[np.bool_], sigma_r: F64) -> tuple[F64, F64]:
        """:func:`plane_covariance` per row: (n, 3, 3) and tilt variance (n,)."""
        key = used.astype(np.int64) @ _POW2
        var = sigma_r * sigma_r
        return var[:, None, None] * self._shape[key], var * self._tilt[key]

    def depth_scale(self, depth: F64) -> F64:
        return np.maximum(depth, 1e-3) / self.params.reference_depth

    def cam_point(self, position: F64) -> F64:
        return (position - self._camera_position) @ _R_CAM_BODY.T

    @staticmethod
    def ray_covariance(point: F64, R_wc: F64, depth_var: F64, lateral_var: F64, floor_var: float) -> F64:
        w = np.einsum("nij,nj->ni", R_wc, point / point[:, 2:3])
        c = R_wc[:, :, 2]
        C = depth_var[:, None, None] * (w[:, :, None] * w[:, None, :]) + (floor_var - lateral_var)[
            :, None, None
        ] * (c[:, :, None] * c[:, None, :])
        C[:, [0, 1, 2], [0, 1, 2]] += lateral_var[:, None]
        return C

    @staticmethod
    def _diag(*d: F64) -> F64:
        out = np.zeros((len(d[0]), len(d), len(d)))
        for k, v in enumerate(d):
            out[:, k, k] = v
        return out

    def atda_attitude(self, R_bd: F64, p_bd: F64, R_wb: F64) -> tuple[F64, F64]:
        p = self.params
        d = self.depth_scale(self.cam_point(p_bd)[:, 2])
        tilt, yaw = p.atda_tilt_sigma * d * d, p.atda_yaw_sigma * d
        return euler_batch(R_wb @ R_bd), self._diag(tilt**2, tilt**2, yaw**2)

    def yaw_var(self, depth: F64, sigma_r: F64) -> F64:
        p = self.params
        return (p.ihrcf_yaw_floor * self.depth_scale(depth)) ** 2 + (
            p.ihrcf_yaw_per_range * sigma_r / np.maximum(depth, 1e-3)
        ) ** 2

    def ihrcf_attitude(
        self, R_bd: F64, p_bd: F64, used: NDArray[np.bool_], R_wb: F64, sigma_r: F64, yaw: bool
    ) -> tuple[F64, F64]:
        tilt_var = self.plane(used, sigma_r)[1] + self.params.ihrcf_tilt_floor**2
        euler = euler_batch(R_wb @ R_bd)
        if yaw:
            yaw_var = self.yaw_var(self.cam_point(p_bd)[:, 2], sigma_r)
            return euler, self._diag(tilt_var, tilt_var, yaw_var)
        return euler[:, :2], self._diag(tilt_var, tilt_var)

    def ihrcf_position(self, p_bd: F64, used: NDArray[np.bool_], R_wb: F64, sigma_r: F64) -> tuple[F64, F64]:
        p = self.params
        X = self.cam_point(p_bd)
        C, tilt_var = self.plane(used, sigma_r)
        g = np.column_stack([np.ones(len(X)), X[:, 0], X[:, 1]])
        depth_var = np.einsum("ni,nij,nj->n", g, C, g)
        lever = (self.tag_size / 2) ** 2 / np.maximum(X[:, 2], 1e-3)
        lat = (p.ihrcf_lateral_floor * self.depth_scale(X[:, 2])) ** 2 + lever**2 * tilt_var
        C = self.ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return np.einsum("nij,nj->ni", R_wb, p_bd), C

    def refit(
        self, corners_cam: F64, used: NDArray[np.bool_], ranges: F64, R_bd: F64
    ) -> tuple[F64, F64, NDArray[np.bool_]]:
        """:meth:`MeasurementBlocks.refit` per row: (R_bd (n, 3, 3), p_bd (n, 3), ok (n,))."""
        n = -(R_bd[:, :, 2] @ _R_CAM_BODY.T)
        xy = self.rig.sensor_xy_cam
        along_xy = xy[None, :, 0] * n[:, None, 0] + xy[None, :, 1] * n[:, None, 1]
        terms = np.where(used, along_xy + ranges * n[:, 2:3], 0.0)
        c = terms.sum(axis=1) / used.sum(axis=1)
        along = np.einsum("nkj,nj->nk", corners_cam, n)
        ok = (along.min(axis=1) > 1e-6) & (c > 0)
        scale = np.where(ok[:, None], c[:, None] / np.where(ok[:, None], along, 1.0), 1.0)
        Q = corners_cam * scale[:, :, None]
        ok &= np.isfinite(Q).all(axis=(1, 2))
        Q = np.where(ok[:, None, None], Q, self.model)
        R_cd, t_cd, rms, fit_ok = rigid_fit_batch(self.model, Q)
        ok &= fit_ok & (rms <= self.max_residual)
        R_out = np.einsum("ij,njk->nik", R_BODY_CAM, R_cd)
        p_out = t_cd @ R_BODY_CAM.T + self.rig.camera_position_array
        return R_out, p_out, ok

    def refit_yaw(self, R_bd: F64, p_bd: F64, sigma_r: F64, R_wb: F64) -> tuple[F64, F64]:
        var = self.yaw_var(self.cam_point(p_bd)[:, 2], sigma_r)
        return euler_batch(R_wb @ R_bd)[:, 2:], var[:, None, None]

    def refit_position(
        self, p_bd: F64, used: NDArray[np.bool_], R_wb: F64, sigma_r: F64, tilt_var: F64
    ) -> tuple[F64, F64]:
        p = self.params
        X = self.cam_point(p_bd)
        xy = self.rig.sensor_xy_cam
        m = used.sum(axis=1)
        centre = np.einsum("nk,kj->nj", used.astype(np.float64), xy) / m[:, None]
        dxy = X[:, :2] - centre
        rho2 = np.einsum("ni,ni->n", dxy, dxy)
        depth_var = sigma_r**2 / m + rho2 * tilt_var
        lat = (p.ihrcf_lateral_floor * self.depth_scale(X[:, 2])) ** 2
        C = self.ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return np.einsum("nij,nj->ni", R_wb, p_bd), C

    def atda_position(self, p_bd: F64, R_wb: F64) -> tuple[F64, F64]:
        p = self.params
        X = self.cam_point(p_bd)
        d = self.depth_scale(X[:, 2])
        dv, lat = (p.atda_depth_sigma * d * d) ** 2, (p.atda_lateral_sigma * d) ** 2
        C = self.ray_covariance(X, R_wb @ R_BODY_CAM, dv, lat, 0.0)
        return np.einsum("nij,nj->ni", R_wb, p_bd), C


__all__ = [
    "BlocksBatch",
]
