"""Measurement blocks of the fused deck-pose estimator and their covariances (pure numpy).

Each IHRCF / ATDA estimate becomes a :class:`Measurement` in the filter's gravity-aligned frame:
attitude blocks (ATDA's roll, pitch, yaw; IHRCF's tilt from the least-squares plane of the touch
points, :func:`plane_covariance`), IHRCF's refit on the filter's deck plane, and positions whose
depth error lies along the camera ray (:func:`ray_covariance`). The noise model is described in
``docs/fused.md``; its numbers are fields of :class:`~ihrcf_env.core.estimators.fused_params.FusedParams`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.estimators.base import PoseEstimate
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.estimators.ihrcf import IHRCFCorners, ihrcf_fit
from ihrcf_env.core.frames import R_BODY_CAM, euler_from_matrix
from ihrcf_env.core.rig import SensorRig

_R_CAM_BODY = np.ascontiguousarray(R_BODY_CAM.T)
_DIAG3 = np.diag_indices(3)


@dataclass(frozen=True)
class Measurement:
    """One measurement block in the filter frame: ``z`` over state rows ``rows``, covariance ``R``
    (exactly symmetric)."""

    name: str
    z: NDArray[np.float64]
    rows: tuple[int, int]  # state rows lo:hi
    R: NDArray[np.float64]


@functools.lru_cache(maxsize=32)
def _plane_shape(xy_key: bytes) -> tuple[NDArray[np.float64], float]:
    """``(A^T A)^-1`` (3, 3) of the least-squares plane ``z = c0 + c1 x + c2 y`` through points at
    ``xy`` (m, camera frame; ``xy_key`` its float64 bytes, A rows ``[1, x_i, y_i]``) and the
    largest eigenvalue of its slope block: the plane's covariance and tilt variance per unit
    range variance (the rig is fixed: cached per set of used sensors)."""
    xy = np.frombuffer(xy_key, dtype=np.float64).reshape(-1, 2)
    A = np.column_stack([np.ones(len(xy)), xy])
    C = np.asarray(np.linalg.inv(A.T @ A), dtype=np.float64)
    C.setflags(write=False)
    a, b, c = float(C[1, 1]), 0.5 * float(C[1, 2] + C[2, 1]), float(C[2, 2])
    return C, 0.5 * (a + c) + math.hypot(0.5 * (a - c), b)


def plane_covariance(xy: NDArray[np.float64], sigma_r: float) -> tuple[NDArray[np.float64], float]:
    """Covariance (3, 3) of ``(c0, c1, c2)`` of the least-squares plane ``z = c0 + c1 x + c2 y``
    through points at ``xy`` (m, camera frame) whose z has noise ``sigma_r`` (m), and its largest
    slope variance (the tilt variance, rad^2)."""
    C, tilt = _plane_shape(np.ascontiguousarray(xy, dtype=np.float64).tobytes())
    var = sigma_r * sigma_r
    return var * C, var * tilt


def ray_covariance(
    point: NDArray[np.float64],
    R_wc: NDArray[np.float64],
    depth_var: float,
    lateral_var: float,
    depth_floor_var: float,
) -> NDArray[np.float64]:
    """Covariance, in the filter's world axes, of a camera-frame point whose depth error moves it
    along its ray (``depth_var``), plus lateral and depth floors: ``R_wc (dv u u^T + diag(lat, lat,
    floor)) R_wc^T`` with ``u`` the ray through ``point`` scaled to unit depth, written as
    ``dv w w^T + lat I + (floor - lat) c c^T`` (``w = R_wc u``, ``c`` the optical axis): exactly
    symmetric, as the filter needs."""
    w = R_wc @ (point / point[2])
    c = R_wc[:, 2]
    C = depth_var * np.outer(w, w) + (depth_floor_var - lateral_var) * np.outer(c, c)
    C[_DIAG3] += lateral_var
    return C


class MeasurementBlocks:
    """The fused estimator's measurement blocks, in the filter's world axes (``R_wb`` the IMU
    attitude of the frame): the noise of each block is described in ``docs/fused.md``.

    Args:
        params: the estimator's :class:`FusedParams`.
        rig: sensor geometry. tag_size: tag side, m.
        max_residual: IHRCF rigid-fit RMS above which a refit is not used, m.
    """

    def __init__(self, params: FusedParams, rig: SensorRig, tag_size: float, max_residual: float) -> None:
        self.params = params
        self.rig = rig
        self.tag_size = tag_size
        self.max_residual = max_residual
        self._camera_position = np.array(rig.camera_position, dtype=np.float64)

    @property
    def camera_position(self) -> NDArray[np.float64]:
        """The camera's position in the body frame (3,), m."""
        return self._camera_position

    def depth_scale(self, depth: float) -> float:
        """``depth`` (m, floored at 1 mm) over the parameters' reference depth."""
        return max(depth, 1e-3) / self.params.reference_depth

    def cam_point(self, est: PoseEstimate) -> NDArray[np.float64]:
        """The deck origin of a body-frame estimate in the camera frame (m)."""
        return _R_CAM_BODY @ (est.position - self._camera_position)

    def atda_attitude(self, atda: PoseEstimate, R_wb: NDArray[np.float64]) -> Measurement:
        p = self.params
        d = self.depth_scale(self.cam_point(atda)[2])
        tilt, yaw = p.atda_tilt_sigma * d * d, p.atda_yaw_sigma * d
        return Measurement(
            "atda.attitude",
            euler_from_matrix(R_wb @ atda.rotation),
            (0, 3),
            np.diag([tilt**2, tilt**2, yaw**2]),
        )

    def ihrcf_yaw_var(self, depth: float, sigma_r: float) -> float:
        p = self.params
        return (p.ihrcf_yaw_floor * self.depth_scale(depth)) ** 2 + (
            p.ihrcf_yaw_per_range * sigma_r / max(depth, 1e-3)
        ) ** 2

    def ihrcf_attitude(
        self, ihrcf: PoseEstimate, corners: IHRCFCorners, R_wb: NDArray[np.float64], sigma_r: float, yaw: bool
    ) -> Measurement:
        p = self.params
        _, tilt_var = plane_covariance(self.rig.sensor_xy_cam[corners.ranges_used], sigma_r)
        tilt_var += p.ihrcf_tilt_floor**2
        euler = euler_from_matrix(R_wb @ ihrcf.rotation)
        if yaw:
            yaw_var = self.ihrcf_yaw_var(self.cam_point(ihrcf)[2], sigma_r)
            return Measurement("ihrcf.attitude", euler, (0, 3), np.diag([tilt_var, tilt_var, yaw_var]))
        return Measurement("ihrcf.tilt", euler[:2], (0, 2), np.diag([tilt_var, tilt_var]))

    def ihrcf_position(
        self, ihrcf: PoseEstimate, corners: IHRCFCorners, R_wb: NDArray[np.float64], sigma_r: float
    ) -> Measurement:
        p = self.params
        X = self.cam_point(ihrcf)
        xy = self.rig.sensor_xy_cam[corners.ranges_used]
        C, tilt_var = plane_covariance(xy, sigma_r)
        g = np.array([1.0, X[0], X[1]])
        depth_var = float(g @ C @ g)
        lever = (self.tag_size / 2) ** 2 / max(X[2], 1e-3)
        lat = (p.ihrcf_lateral_floor * self.depth_scale(X[2])) ** 2 + lever**2 * tilt_var
        C = ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return Measurement("ihrcf.position", R_wb @ ihrcf.position, (0, 3), C)

    def refit(
        self, corners: IHRCFCorners, ranges: NDArray[np.float64], R_bd: NDArray[np.float64]
    ) -> PoseEstimate | None:
        """IHRCF's corner rays intersected with the deck plane of orientation ``R_bd`` (the filter's
        deck rotation in the body frame) through the touch points of ``ranges`` (m); None if the
        rays miss it or the fit fails."""
        n = -(_R_CAM_BODY @ R_bd[:, 2])  # deck normal in the camera frame, into the deck (n_z > 0)
        used = corners.ranges_used
        c = float((self.rig.sensor_xy_cam[used] @ n[:2] + ranges[used] * n[2]).sum()) / int(used.sum())
        along = corners.corners_cam @ n
        if not (along.min() > 1e-6 and c > 0):
            return None
        est = ihrcf_fit(
            corners.corners_cam * (c / along)[:, None], self.rig, self.tag_size, self.max_residual
        )
        return est if est.valid else None

    def refit_yaw(self, refit: PoseEstimate, sigma_r: float, R_wb: NDArray[np.float64]) -> Measurement:
        var = self.ihrcf_yaw_var(self.cam_point(refit)[2], sigma_r)
        return Measurement(
            "ihrcf.yaw", euler_from_matrix(R_wb @ refit.rotation)[2:], (2, 3), np.array([[var]])
        )

    def refit_position(
        self,
        refit: PoseEstimate,
        corners: IHRCFCorners,
        R_wb: NDArray[np.float64],
        sigma_r: float,
        tilt_var: float,
    ) -> Measurement:
        """The refit's position: the mean of the used ranges along the ray plus the filter's tilt
        variance ``tilt_var`` (rad^2) times the squared distance from the touch points' centroid."""
        p = self.params
        X = self.cam_point(refit)
        xy = self.rig.sensor_xy_cam[corners.ranges_used]
        dxy = X[:2] - xy.sum(axis=0) / len(xy)
        rho2 = float(dxy @ dxy)
        depth_var = sigma_r**2 / len(xy) + rho2 * tilt_var
        lat = (p.ihrcf_lateral_floor * self.depth_scale(X[2])) ** 2
        C = ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return Measurement("ihrcf.position", R_wb @ refit.position, (0, 3), C)

    def atda_position(self, atda: PoseEstimate, R_wb: NDArray[np.float64]) -> Measurement:
        p = self.params
        X = self.cam_point(atda)
        d = self.depth_scale(X[2])
        dv, lat = (p.atda_depth_sigma * d * d) ** 2, (p.atda_lateral_sigma * d) ** 2
        return Measurement(
            "atda.position", R_wb @ atda.position, (0, 3), ray_covariance(X, R_wb @ R_BODY_CAM, dv, lat, 0.0)
        )


__all__ = [
    "Measurement",
    "MeasurementBlocks",
    "plane_covariance",
    "ray_covariance",
]
