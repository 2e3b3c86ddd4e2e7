"""The deck plane through the ToF touch points and its depth above camera-frame XY: the ports of
:func:`ihrcf_env.core.geometry.fit_plane` (on the used points) and ``plane_z`` for one frame (camera
frame, m)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ihrcf_env.fast.linalg3 import cross, dot, jacobi_svd

__all__ = ["fit_plane", "plane_z"]


def fit_plane(points: Array, use: Array) -> tuple[Array, Array, Array]:
    """Plane ``n . x = offset`` through the ``points`` (k, 3) with ``use`` (k,) True: three used
    points give ``(p1 - p2) x (p2 - p3)`` (in index order), more give total least squares (the right
    singular vector of least spread). Returns the unit normal (3,) (``n_z >= 0``, else its first
    non-zero component positive), the offset and an error code: 0 success, 1 coincident points, 2
    collinear points, 3 fewer than three points."""
    count = jnp.sum(use)
    pts = jnp.where(use[:, None], points, 0.0)
    s = pts[0]
    for p in pts[1:]:
        s = s + p
    centroid = s / jnp.maximum(count, 1)
    centred = jnp.where(use[:, None], points - centroid, 0.0)
    scale = jnp.sqrt(jnp.max(dot(centred, centred)))
    code = jnp.where(count < 3, 3, jnp.where(scale == 0.0, 1, 0))
    safe = jnp.where(scale > 0.0, scale, 1.0)

    order = jnp.argsort(~use, stable=True)[:3]
    p1, p2, p3 = points[order[0]], points[order[1]], points[order[2]]
    n3 = cross(p1 - p2, p2 - p3)
    norm3 = jnp.sqrt(dot(n3, n3))
    sv, _, V = jacobi_svd(centred / safe)
    k = jnp.argsort(sv)  # ascending
    n4 = V[:, k[0]]
    three = count == 3
    collinear = jnp.where(three, norm3 <= 1e-9 * safe * safe, sv[k[1]] <= 1e-9 * sv[k[2]])
    code = jnp.where((code == 0) & collinear, 2, code)
    n = jnp.where(three, n3, n4)
    norm = jnp.where(three, norm3, jnp.sqrt(dot(n4, n4)))
    ok = code == 0
    n = jnp.where(ok, n / jnp.where(ok, norm, 1.0), jnp.array([0.0, 0.0, 1.0], dtype=n.dtype))
    first = n[jnp.argmax(n != 0.0)]
    flip = (n[2] < 0) | ((n[2] == 0) & (first < 0))
    n = jnp.where(flip, -n, n)
    offset = jnp.where(ok, dot(n, jnp.where(ok, centroid, 0.0)), 0.0)
    return n, offset, code.astype(jnp.int8)


def plane_z(normal: Array, offset: Array, xy: Array) -> tuple[Array, Array]:
    """Z (m,) of the plane ``normal . x = offset`` above ``xy`` (m, 2), and False where the plane is
    parallel to z (Z is 0 there)."""
    nn = jnp.sqrt(dot(normal, normal))
    ok = ~(jnp.abs(normal[2]) < 1e-9 * nn) & jnp.any(normal != 0.0)
    n2 = jnp.where(ok, normal[2], 1.0)
    z = (offset - normal[0] * xy[:, 0] - normal[1] * xy[:, 1]) / n2
    return jnp.where(ok, z, 0.0), ok
