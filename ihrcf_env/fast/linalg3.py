"""Small fixed-size linear algebra written out for JAX: 3-vectors, 3x3 matrices, the intrinsic
Z-Y-X Euler angles of :mod:`ihrcf_env.core.frames`, and the SVD of small matrices by a fixed number of
one-sided Jacobi sweeps (no data-dependent loop, no ``jnp.linalg``)."""

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
    """Dot product over the last axis (3), summed in index order."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


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
    return jnp.stack([dot(v, R[i]) for i in range(3)], axis=-1)


def tmatvec(R: Array, v: Array) -> Array:
    """``R^T v`` for a 3x3 ``R`` and vectors ``v`` (..., 3)."""
    return jnp.stack([dot(v, R[:, j]) for j in range(3)], axis=-1)


def matmul(A: Array, B: Array) -> Array:
    """``A B`` of two 3x3 matrices, each entry summed in index order."""
    return A[:, 0, None] * B[None, 0, :] + A[:, 1, None] * B[None, 1, :] + A[:, 2, None] * B[None, 2, :]


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

    def sweep(carry: tuple[Array, Array], _: None) -> tuple[tuple[Array, Array], None]:
        B, V = carry
        for p, q in pairs:
            bp, bq = B[:, p], B[:, q]
            alpha = jnp.sum(bp * bp)
            beta = jnp.sum(bq * bq)
            gamma = jnp.sum(bp * bq)
            skip = gamma == 0.0
            zeta = (beta - alpha) / jnp.where(skip, 1.0, 2.0 * gamma)
            t = jnp.where(zeta >= 0.0, 1.0, -1.0) / (jnp.abs(zeta) + jnp.sqrt(1.0 + zeta * zeta))
            t = jnp.where(skip, 0.0, t)
            c = 1.0 / jnp.sqrt(1.0 + t * t)
            s = c * t
            B = B.at[:, p].set(c * bp - s * bq).at[:, q].set(s * bp + c * bq)
            vp, vq = V[:, p], V[:, q]
            V = V.at[:, p].set(c * vp - s * vq).at[:, q].set(s * vp + c * vq)
        return (B, V), None

    (B, V), _ = lax.scan(sweep, (A, jnp.eye(n, dtype=A.dtype)), None, length=sweeps)
    return jnp.sqrt(jnp.sum(B * B, axis=0)), B, V
