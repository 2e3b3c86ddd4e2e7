"""The fused filter's measurement blocks for one environment: the port of
:class:`ihrcf_env.core.estimators.fused_measurements.MeasurementBlocks` (ATDA's and IHRCF's
attitude and position measurements with their covariances in the filter's world axes, the refit
on the filtered deck normal and its yaw), of the IMU sample
(:func:`ihrcf_env.core.estimators.fused_delay.imu_sample`) and of the range-noise and
range-offset estimates of :class:`~ihrcf_env.core.estimators.fused.FusedEstimator`.

Configuration is host-side (:func:`fused_consts`: the parameters, the rig, the plane-fit shapes
per set of used sensors); estimates and measurements are arrays. Frames: body (world from body
``R_wb`` from the IMU), deck pose in the body frame (``R_bd``, ``p_bd``), camera (OpenCV,
``R_BODY_CAM``); m, rad.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array
from numpy.typing import NDArray

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import fused_reasons as fr
from ihrcf_env.core.estimators.fused_measurements import _plane_shape
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast.linalg3 import euler_from_matrix, matmul
from ihrcf_env.fast.rigid import rigid_fit

__all__ = [
    "LOG_CHI2_1_MEAN",
    "FusedConsts",
    "atda_attitude",
    "atda_position",
    "cam_point",
    "fused_consts",
    "ihrcf_attitude",
    "ihrcf_position",
    "imu_sample",
    "plane",
    "q_tilt",
    "range_noise",
    "range_offset",
    "refit",
    "refit_position",
    "refit_yaw",
]

#: E[ln X] for X ~ chi-square(1).
LOG_CHI2_1_MEAN = -1.2703628454614782
_R_CAM_BODY = np.ascontiguousarray(R_BODY_CAM.T)
_POW2 = np.array([1, 2, 4, 8])


class FusedConsts(NamedTuple):
    """Host-side constants of one filter configuration: ``params``, ``tag_size`` (m),
    ``max_residual`` (m), the tag's corners ``model`` (4, 3; deck frame), ``camera_position`` (3,;
    body), ``sensor_xy`` (4, 2; camera frame, m), the plane covariance ``shape`` (16, 3, 3) and
    ``tilt`` factor (16,) per mask of used sensors (bit j: sensor j), the ranges'
    ``residual_direction`` (4,) and the chi-square ``gate`` of 1, 2 and 3 values."""

    params: FusedParams
    tag_size: float
    max_residual: float
    model: NDArray[np.float64]
    camera_position: NDArray[np.float64]
    sensor_xy: NDArray[np.float64]
    shape: NDArray[np.float64]
    tilt: NDArray[np.float64]
    residual_direction: NDArray[np.float64]
    gate: tuple[float, float, float]


def fused_consts(params: FusedParams, rig: SensorRig, tag_size: float, max_residual: float) -> FusedConsts:
    """The :class:`FusedConsts` of a configuration (as
    :class:`~ihrcf_env.core.estimators.fused.FusedEstimator` derives them)."""
    from scipy.stats import chi2

    xy = np.asarray(rig.sensor_xy_cam, dtype=np.float64)
    shape, tilt = np.zeros((16, 3, 3)), np.zeros(16)
    for key in range(16):
        used = (key & _POW2) > 0
        if used.sum() >= 3:
            C, t = _plane_shape(np.ascontiguousarray(xy[used], dtype=np.float64).tobytes())
            shape[key], tilt[key] = C, t
    A = np.column_stack([np.ones(4), xy])
    gate = tuple(float(chi2.ppf(params.gate_probability, k)) for k in (1, 2, 3))
    return FusedConsts(
        params,
        float(tag_size),
        float(max_residual),
        np.asarray(tag_corners_deck(tag_size), dtype=np.float64),
        np.array(rig.camera_position, dtype=np.float64),
        xy,
        shape,
        tilt,
        np.linalg.svd(A)[0][:, 3].copy(),
        (gate[0], gate[1], gate[2]),
    )


def imu_sample(q: Array, f: Array, w: Array) -> tuple[Array, Array, Array]:
    """The IMU sample's ``R_wb`` (3, 3), the drone's acceleration (3,; world, m/s^2) and its code
    (0, ``IMU_NONFINITE``, ``IMU_ZERO``) from the quaternion ``q`` (4,), specific force ``f`` and
    body rates ``w``; a bad sample reads as identity and ``-g``."""
    qq = jnp.sum(q * q)
    total = qq + jnp.sum(f * f) + jnp.sum(w * w)
    code = jnp.where(~jnp.isfinite(total), fr.IMU_NONFINITE, jnp.where(qq < 1e-12, fr.IMU_ZERO, 0))
    ok = code == 0
    qn = jnp.where(ok, q, jnp.array([0.0, 0.0, 0.0, 1.0], dtype=q.dtype))
    qn = qn / jnp.sqrt(jnp.sum(qn * qn))
    x, y, z, s = qn[0], qn[1], qn[2], qn[3]
    R = jnp.stack(
        [
            jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * s), 2 * (x * z + y * s)]),
            jnp.stack([2 * (x * y + z * s), 1 - 2 * (x * x + z * z), 2 * (y * z - x * s)]),
            jnp.stack([2 * (x * z - y * s), 2 * (y * z + x * s), 1 - 2 * (x * x + y * y)]),
        ]
    )
    fo = jnp.where(ok, f, 0.0)
    a = R @ fo + jnp.array([0.0, 0.0, -GRAVITY], dtype=f.dtype)
    return R, a, code


def _key(used: Array) -> Array:
    return jnp.sum(used.astype(jnp.int32) * jnp.asarray(_POW2, jnp.int32))


def plane(c: FusedConsts, used: Array, sigma_r: Array) -> tuple[Array, Array]:
    """The ranges' plane-fit covariance (3, 3) and tilt variance for the ``used`` (4,) sensors of
    range noise ``sigma_r`` (m)."""
    k = _key(used)
    var = sigma_r * sigma_r
    return var * jnp.asarray(c.shape)[k], var * jnp.asarray(c.tilt)[k]


def depth_scale(c: FusedConsts, depth: Array) -> Array:
    return jnp.maximum(depth, 1e-3) / c.params.reference_depth


def cam_point(c: FusedConsts, position: Array) -> Array:
    """A body-frame point (3,) in the camera frame."""
    return jnp.asarray(_R_CAM_BODY) @ (position - jnp.asarray(c.camera_position))


def ray_covariance(
    point: Array, R_wc: Array, depth_var: Array, lateral_var: Array, floor_var: float
) -> Array:
    w = R_wc @ (point / point[2])
    cz = R_wc[:, 2]
    C = depth_var * (w[:, None] * w[None, :]) + (floor_var - lateral_var) * (cz[:, None] * cz[None, :])
    return C + lateral_var * jnp.eye(3, dtype=C.dtype)


def atda_attitude(c: FusedConsts, R_bd: Array, p_bd: Array, R_wb: Array) -> tuple[Array, Array]:
    p = c.params
    d = depth_scale(c, cam_point(c, p_bd)[2])
    tilt, yaw = p.atda_tilt_sigma * d * d, p.atda_yaw_sigma * d
    return euler_from_matrix(matmul(R_wb, R_bd)), jnp.diag(jnp.stack([tilt**2, tilt**2, yaw**2]))


def yaw_var(c: FusedConsts, depth: Array, sigma_r: Array) -> Array:
    p = c.params
    return (p.ihrcf_yaw_floor * depth_scale(c, depth)) ** 2 + (
        p.ihrcf_yaw_per_range * sigma_r / jnp.maximum(depth, 1e-3)
    ) ** 2


def ihrcf_attitude(
    c: FusedConsts, R_bd: Array, p_bd: Array, used: Array, R_wb: Array, sigma_r: Array, yaw: bool
) -> tuple[Array, Array]:
    """IHRCF's attitude: (roll, pitch, yaw) and its covariance (3, 3), or (roll, pitch) and (2, 2)
    without ``yaw``."""
    tilt_var = plane(c, used, sigma_r)[1] + c.params.ihrcf_tilt_floor**2
    euler = euler_from_matrix(matmul(R_wb, R_bd))
    if yaw:
        yv = yaw_var(c, cam_point(c, p_bd)[2], sigma_r)
        return euler, jnp.diag(jnp.stack([tilt_var, tilt_var, yv]))
    return euler[:2], jnp.diag(jnp.stack([tilt_var, tilt_var]))


def ihrcf_position(
    c: FusedConsts, p_bd: Array, used: Array, R_wb: Array, sigma_r: Array
) -> tuple[Array, Array]:
    p = c.params
    X = cam_point(c, p_bd)
    C, tilt_var = plane(c, used, sigma_r)
    g = jnp.stack([jnp.ones_like(X[0]), X[0], X[1]])
    depth_var = g @ C @ g
    lever = (c.tag_size / 2) ** 2 / jnp.maximum(X[2], 1e-3)
    lat = (p.ihrcf_lateral_floor * depth_scale(c, X[2])) ** 2 + lever**2 * tilt_var
    cov = ray_covariance(X, R_wb @ jnp.asarray(R_BODY_CAM), depth_var, lat, p.ihrcf_depth_floor**2)
    return R_wb @ p_bd, cov


def refit(
    c: FusedConsts, corners_cam: Array, used: Array, ranges: Array, R_bd: Array
) -> tuple[Array, Array, Array]:
    """The tag's pose refitted with the ranges on the filtered deck normal of ``R_bd``: (R_bd,
    p_bd, ok)."""
    n = -(jnp.asarray(_R_CAM_BODY) @ R_bd[:, 2])
    xy = jnp.asarray(c.sensor_xy)
    along_xy = xy[:, 0] * n[0] + xy[:, 1] * n[1]
    terms = jnp.where(used, along_xy + ranges * n[2], 0.0)
    cc = jnp.sum(terms) / jnp.sum(used)
    along = corners_cam @ n
    ok = (jnp.min(along) > 1e-6) & (cc > 0)
    scale = jnp.where(ok, cc / jnp.where(ok, along, 1.0), 1.0)
    Q = corners_cam * scale[:, None]
    ok &= jnp.all(jnp.isfinite(Q))
    Q = jnp.where(ok, Q, jnp.asarray(c.model))
    R_cd, t_cd, rms, fit_ok = rigid_fit(jnp.asarray(c.model, dtype=Q.dtype), Q)
    ok &= fit_ok & (rms <= c.max_residual)
    R_out = jnp.asarray(R_BODY_CAM) @ R_cd
    p_out = jnp.asarray(R_BODY_CAM) @ t_cd + jnp.asarray(c.camera_position)
    return R_out, p_out, ok


def refit_yaw(c: FusedConsts, R_bd: Array, p_bd: Array, sigma_r: Array, R_wb: Array) -> tuple[Array, Array]:
    var = yaw_var(c, cam_point(c, p_bd)[2], sigma_r)
    return euler_from_matrix(matmul(R_wb, R_bd))[2:], var[None, None]


def refit_position(
    c: FusedConsts, p_bd: Array, used: Array, R_wb: Array, sigma_r: Array, tilt_var: Array
) -> tuple[Array, Array]:
    p = c.params
    X = cam_point(c, p_bd)
    xy = jnp.asarray(c.sensor_xy)
    m = jnp.sum(used)
    centre = used.astype(X.dtype) @ xy / m
    dxy = X[:2] - centre
    rho2 = jnp.sum(dxy * dxy)
    depth_var = sigma_r**2 / m + rho2 * tilt_var
    lat = (p.ihrcf_lateral_floor * depth_scale(c, X[2])) ** 2
    cov = ray_covariance(X, R_wb @ jnp.asarray(R_BODY_CAM), depth_var, lat, p.ihrcf_depth_floor**2)
    return R_wb @ p_bd, cov


def atda_position(c: FusedConsts, p_bd: Array, R_wb: Array) -> tuple[Array, Array]:
    p = c.params
    X = cam_point(c, p_bd)
    d = depth_scale(c, X[2])
    dv, lat = (p.atda_depth_sigma * d * d) ** 2, (p.atda_lateral_sigma * d) ** 2
    cov = ray_covariance(X, R_wb @ jnp.asarray(R_BODY_CAM), dv, lat, 0.0)
    return R_wb @ p_bd, cov


def range_noise(
    c: FusedConsts, ranges: Array, valid: Array, take: Array, log_var: Array, weight: Array
) -> tuple[Array, Array]:
    """The range-noise estimate (log variance, window weight) after one sample from ``ranges`` (4,)
    when ``take`` and the four ranges are valid, finite and positive (unchanged otherwise)."""
    p = c.params
    ok = take & jnp.all(valid) & jnp.all(jnp.isfinite(ranges)) & (jnp.min(ranges) > 0)
    r = jnp.where(ok, ranges, 1.0)
    ssr = (r @ jnp.asarray(c.residual_direction)) ** 2
    sample = jnp.log(jnp.maximum(ssr, p.tof_sigma_min**2)) - LOG_CHI2_1_MEAN
    w = jnp.minimum(weight + 1.0, float(p.tof_sigma_window))
    return jnp.where(ok, log_var + (sample - log_var) / w, log_var), jnp.where(ok, w, weight)


def range_offset(
    c: FusedConsts,
    take: Array,
    p_ihrcf: Array,
    used: Array,
    p_atda: Array,
    sigma_r: Array,
    bias: Array,
    bias_P: Array,
) -> tuple[Array, Array]:
    """The (range offset, ATDA depth bias) estimate ``bias`` (2,) and its covariance (2, 2) after
    comparing IHRCF's and ATDA's depths when ``take`` (gated; unchanged otherwise)."""
    p = c.params
    X, Y = cam_point(c, p_ihrcf), cam_point(c, p_atda)
    d = depth_scale(c, Y[2])
    m = jnp.sum(used)
    var = sigma_r**2 / jnp.maximum(m, 1) + (p.atda_depth_sigma * d * d) ** 2 + p.ihrcf_depth_floor**2
    H = jnp.array([1.0, -1.0], dtype=bias.dtype)
    nu = (X[2] - Y[2]) - bias @ H + bias[0]
    S = H @ bias_P @ H + var
    ok = take & ~(nu * nu / S > c.gate[0])
    Kg = (bias_P @ H) / S
    b = bias + Kg * nu
    P = bias_P - Kg[:, None] * (H @ bias_P)[None, :]
    P = 0.5 * (P + P.T)
    return jnp.where(ok, b, bias), jnp.where(ok, P, bias_P)


def q_tilt(walk2: float, r: Array) -> Array:
    """The IMU tilt wander's noise on the relative position ``r`` (3,): ``walk2 (|r|^2 I - r r^T)``."""
    return walk2 * (jnp.sum(r * r) * jnp.eye(3, dtype=r.dtype) - r[:, None] * r[None, :])
