"""Small fixed-size linear algebra written out for JAX: 3-vectors, 3x3 matrices, the intrinsic
Z-Y-X Euler angles of :mod:`ihrcf_env.core.frames`, and the SVD of small matrices by a fixed number of
one-sided Jacobi sweeps (one rotation per step of a ``lax.scan``; no data-dependent loop, no
``jnp.linalg``)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array, lax

__all__ = [
    "cross",
    "det3",
    "dot",
    "euler_from_matrix",
    "jacobi_svd",
    "matrix_from_euler",
    "matvec",
    "matmul",
    "tmatvec",
]


def dot(a: Array, b: Array) -> Array:
    """Dot product over the last axis (3) (one product and one reduction)."""
    return jnp.sum(a * b, axis=-1)


def cross(a: Array, b: Array) -> Array:
    """Cross product over the last axis (3)."""
    return jnp.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def matvec(R: Array, v: Array) -> Array:
    """``R v`` for a 3x3 ``R`` and vectors ``v`` (..., 3)."""
    return jnp.sum(v[..., None, :] * R, axis=-1)


def tmatvec(R: Array, v: Array) -> Array:
    """``R^T v`` for a 3x3 ``R`` and vectors ``v`` (..., 3)."""
    return jnp.sum(v[..., :, None] * R, axis=-2)


def matmul(A: Array, B: Array) -> Array:
    """``A B`` of two 3x3 matrices (one broadcast product and one reduction)."""
    return jnp.sum(A[:, :, None] * B[None, :, :], axis=1)


def det3(m: Array) -> Array:
    """Determinant of a 3x3 matrix by its first-row expansion."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 0], m[1, 1], m[1, 2]
    g, h, i = m[2, 0], m[2, 1], m[2, 2]
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def euler_from_matrix(R: Array) -> Array:
    """(roll, pitch, yaw) (rad) of a rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)``; at gimbal lock
    everything goes into yaw (as :func:`ihrcf_env.core.frames.euler_from_matrix`)."""
    r20 = R[2, 0]
    pitch = jnp.arcsin(jnp.clip(-r20, -1.0, 1.0))
    lock = ~(jnp.abs(r20) < 1.0 - 1e-12)
    roll = jnp.where(lock, 0.0, jnp.arctan2(R[2, 1], R[2, 2]))
    yaw = jnp.where(lock, jnp.arctan2(-R[0, 1], R[1, 1]), jnp.arctan2(R[1, 0], R[0, 0]))
    return jnp.stack([roll, pitch, yaw])


def matrix_from_euler(euler: Array) -> Array:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3) of (roll, pitch, yaw) (rad)."""
    cr, sr = jnp.cos(euler[0]), jnp.sin(euler[0])
    cp, sp = jnp.cos(euler[1]), jnp.sin(euler[1])
    cy, sy = jnp.cos(euler[2]), jnp.sin(euler[2])
    return jnp.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def jacobi_svd(A: Array, sweeps: int = 8) -> tuple[Array, Array, Array]:
    """Thin SVD of a small (m, n) ``A`` by ``sweeps`` one-sided (Hestenes) Jacobi sweeps: singular
    values (n,) (unsorted), the rotated columns ``A V`` (m, n) (column j is ``s_j u_j``) and the
    right singular vectors (columns of (n, n)). Small singular values come out with high relative
    accuracy, as LAPACK's."""
    n = A.shape[1]
    pairs = [(p, q) for p in range(n) for q in range(p + 1, n)]
    ps = jnp.asarray([p for p, _ in pairs] * sweeps, dtype=jnp.int32)
    qs = jnp.asarray([q for _, q in pairs] * sweeps, dtype=jnp.int32)

    def col(M: Array, j: Array) -> Array:
        return lax.dynamic_index_in_dim(M, j, axis=1, keepdims=False)

    def put(M: Array, v: Array, j: Array) -> Array:
        return lax.dynamic_update_index_in_dim(M, v, j, axis=1)

    def rotate(carry: tuple[Array, Array], pq: tuple[Array, Array]) -> tuple[tuple[Array, Array], None]:
        B, V = carry
        p, q = pq
        bp, bq = col(B, p), col(B, q)
        alpha = jnp.sum(bp * bp)
        beta = jnp.sum(bq * bq)
        gamma = jnp.sum(bp * bq)
        skip = gamma == 0.0
        zeta = (beta - alpha) / jnp.where(skip, 1.0, 2.0 * gamma)
        t = jnp.where(zeta >= 0.0, 1.0, -1.0) / (jnp.abs(zeta) + jnp.sqrt(1.0 + zeta * zeta))
        t = jnp.where(skip, 0.0, t)
        c = 1.0 / jnp.sqrt(1.0 + t * t)
        s = c * t
        B = put(put(B, c * bp - s * bq, p), s * bp + c * bq, q)
        vp, vq = col(V, p), col(V, q)
        V = put(put(V, c * vp - s * vq, p), s * vp + c * vq, q)
        return (B, V), None

    # the sweeps' pairs in cyclic order, one rotation per step
    (B, V), _ = lax.scan(rotate, (A, jnp.eye(n, dtype=A.dtype)), (ps, qs))
    return jnp.sqrt(jnp.sum(B * B, axis=0)), B, V
