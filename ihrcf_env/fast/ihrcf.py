"""IHRCF (the deck pose from the tag's corners and the four ranges) for one frame: the port of
:func:`ihrcf_env.core.estimators.ihrcf.ihrcf_estimate`, with the same checks in the same order
(the first failure gives the reason code of :data:`ihrcf_env.core.estimators.reasons.REASONS`).

Frames: pixels (OpenCV), camera (OpenCV), body (``R_BODY_CAM``); the pose is the deck in the body
frame (``R_body_deck``, deck origin in m).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

from ihrcf_env.core.estimators import reasons as rs
from ihrcf_env.core.estimators.base import DEGENERATE_REL_TOL
from ihrcf_env.core.frames import R_BODY_CAM
from ihrcf_env.core.geometry import quad_is_degenerate
from ihrcf_env.core.rig import SensorRig, tag_corners_deck
from ihrcf_env.fast.homography import apply_homography, collinear, homography4
from ihrcf_env.fast.linalg3 import euler_from_matrix, matmul, matvec
from ihrcf_env.fast.plane import fit_plane, plane_z
from ihrcf_env.fast.rigid import rigid_fit
from ihrcf_env.fast.table import TouchTableArrays, lookup

__all__ = ["IHRCFSetup", "Pose", "ihrcf", "ihrcf_parts", "ihrcf_setup"]


class IHRCFSetup(NamedTuple):
    """The fixed inputs of IHRCF: the ``table`` arrays, ``sensor_xy`` (4, 2) of ps1..ps4 (camera
    frame, m), the tag ``model`` corners (4, 3; deck frame, m), ``camera_position`` (3,; body, m),
    ``max_residual`` (m) and ``degenerate_layout`` (the sensors' quad is degenerate)."""

    table: TouchTableArrays
    sensor_xy: Array
    model: Array
    camera_position: Array
    max_residual: Array
    degenerate_layout: Array


def ihrcf_setup(
    table: TouchTableArrays, rig: SensorRig, tag_size: float, max_residual: float = 0.01
) -> IHRCFSetup:
    """The :class:`IHRCFSetup` of a rig, a tag of ``tag_size`` (m) and a residual bound (m)."""
    xy = np.asarray(rig.sensor_xy_cam, dtype=np.float64)
    return IHRCFSetup(
        table,
        jnp.asarray(xy),
        jnp.asarray(tag_corners_deck(float(tag_size))),
        jnp.asarray(rig.camera_position_array),
        jnp.asarray(float(max_residual)),
        jnp.asarray(bool(quad_is_degenerate(xy, DEGENERATE_REL_TOL))),
    )


class Pose(NamedTuple):
    """A deck pose estimate (body frame): ``rotation`` (3, 3; identity when invalid), ``position``
    (3,) m and ``euler`` (3,) rad (zeros when invalid), ``valid``, ``residual`` (m; 0 when invalid),
    ``code`` (a reason code, 0 when valid), ``fit_rms`` (the RMS behind a residual failure, else 0)."""

    rotation: Array
    position: Array
    euler: Array
    valid: Array
    residual: Array
    code: Array
    fit_rms: Array


def _first(code: Array, failed: Array, reason: int) -> Array:
    return jnp.where((code == rs.OK) & failed, reason, code)


def assemble(R: Array, p: Array, residual: Array, code: Array, fit_rms: Array) -> Pose:
    """A :class:`Pose` with the invalid values reset as an invalid estimate has them."""
    ok = code == rs.OK
    R = jnp.where(ok, R, jnp.eye(3, dtype=R.dtype))
    p = jnp.where(ok, p, 0.0)
    euler = jnp.where(ok, euler_from_matrix(R), 0.0)
    rms = jnp.where(code == rs.FIT_RESIDUAL, fit_rms, 0.0)
    return Pose(R, p, euler, ok, jnp.where(ok, residual, 0.0), code.astype(jnp.int8), rms)


def ihrcf(corners_px: Array, ranges: Array, ranges_valid: Array, detected: Array, setup: IHRCFSetup) -> Pose:
    """IHRCF of one frame: tag ``corners_px`` (4, 2; aruco order), ``ranges`` (4,) m of ps1..ps4 (NaN
    allowed) with ``ranges_valid`` (4,), ``detected`` (the tag was found)."""
    return ihrcf_parts(corners_px, ranges, ranges_valid, detected, setup)[0]


def ihrcf_parts(
    corners_px: Array, ranges: Array, ranges_valid: Array, detected: Array, setup: IHRCFSetup
) -> tuple[Pose, Array, Array]:
    """:func:`ihrcf` with its intermediate results: (the pose, the tag's corners (4, 3) on the
    fitted deck plane (camera frame, m), the ranges (4,) that defined the plane)."""
    sensor_xy, model = setup.sensor_xy, setup.model
    code = jnp.where(detected, rs.OK, rs.NOT_DETECTED)
    code = _first(code, ~jnp.all(jnp.isfinite(corners_px)), rs.NONFINITE_CORNERS)
    valid = ranges_valid & jnp.isfinite(ranges) & (ranges > 0)
    code = _first(code, jnp.sum(valid) < 3, rs.FEW_RANGES)
    touch = jnp.concatenate([sensor_xy, jnp.where(valid, ranges, 0.0)[:, None]], axis=1)
    normal, offset, pcode = fit_plane(touch, valid)
    code = _first(code, pcode == 1, rs.PLANE_COINCIDENT)
    code = _first(code, pcode == 2, rs.PLANE_COLLINEAR)
    predicted, z_ok = plane_z(normal, offset, sensor_xy)
    code = _first(code, ~z_ok, rs.PLANE_PARALLEL)
    full = jnp.where(valid, ranges, predicted)
    code = _first(code, ~jnp.all(jnp.isfinite(full) & (full > 0)), rs.PREDICTED_RANGE)

    tp, inside = lookup(setup.table, jnp.where(code == rs.OK, full, 1.0))
    code = _first(code, ~jnp.all(inside), rs.OUTSIDE_TABLE)
    code = _first(code, ~jnp.all(jnp.isfinite(tp)), rs.NONFINITE_TOUCH)
    code = _first(code, setup.degenerate_layout, rs.DEGENERATE_LAYOUT)
    tp = jnp.where(code == rs.OK, tp, sensor_xy * 1000.0)
    code = _first(code, collinear(tp, DEGENERATE_REL_TOL), rs.DEGENERATE_TOUCH)

    H_inv, hcode = homography4(tp, sensor_xy)
    code = _first(code, hcode == 1, rs.HOMOGRAPHY_NOT_UNIQUE)
    code = _first(code, hcode == 2, rs.HOMOGRAPHY_H22)
    xy = apply_homography(H_inv, jnp.where(jnp.isfinite(corners_px), corners_px, 0.0))
    code = _first(code, ~jnp.all(jnp.isfinite(xy)), rs.CORNER_AT_INFINITY)
    xy = jnp.where(code == rs.OK, xy, model[:, :2])
    z, _ = plane_z(normal, offset, xy)
    code = _first(code, ~jnp.all(z > 0), rs.CORNER_BEHIND)
    corners_cam = jnp.concatenate([xy, z[:, None]], axis=1)

    code = _first(code, ~jnp.all(jnp.isfinite(corners_cam)), rs.FIT_NONFINITE)
    Q = jnp.where(code == rs.OK, corners_cam, model)
    R_cd, t_cd, rms, fit_ok = rigid_fit(model, Q)
    code = _first(code, ~fit_ok, rs.FIT_COLLINEAR)
    code = _first(code, ~(rms <= setup.max_residual), rs.FIT_RESIDUAL)
    R_bc = jnp.asarray(R_BODY_CAM, dtype=R_cd.dtype)
    R_bd = matmul(R_bc, R_cd)
    p_bd = matvec(R_bc, t_cd) + setup.camera_position
    return assemble(R_bd, p_bd, rms, code, rms), corners_cam, valid
