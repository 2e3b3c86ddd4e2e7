"""Least-squares rigid transform ``Q ~ R P + t`` (Kabsch without scale, det +1): the port of
:func:`ihrcf_env.core.geometry.rigid_fit` for one point set, the SVD by one-sided
Jacobi sweeps."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ihrcf_env.fast.linalg3 import cross, dot, jacobi_svd, matvec

__all__ = ["rigid_fit"]


def _mean(P: Array) -> Array:
    s = P[0]
    for p in P[1:]:
        s = s + p
    return s / P.shape[0]


def rigid_fit(P: Array, Q: Array) -> tuple[Array, Array, Array, Array]:
    """``R`` (3, 3), ``t`` (3,), RMS residual and success (False where ``P`` (k, 3) is collinear
    or coincident: identity and zeros then) of ``Q`` (k, 3) ~ ``R P + t``.

    With the SVD ``H = Qc^T Pc = sum s_i u_i v_i^T`` (s_1 >= s_2 >= s_3), the rotation is
    ``u_1 v_1^T + u_2 v_2^T + (u_1 x u_2)(v_1 x v_2)^T`` (the reflection-corrected Kabsch solution,
    also for coplanar points)."""
    k = P.shape[0]
    cp, cq = _mean(P), _mean(Q)
    Pc, Qc = P - cp, Q - cq
    sp, _, _ = jacobi_svd(Pc)
    sp = jnp.sort(sp)[::-1]
    ok = ~(sp[1] <= 1e-9 * jnp.maximum(sp[0], 1e-300))
    H = Qc.T @ Pc
    s, HV, V = jacobi_svd(H)
    order = jnp.argsort(-s)
    i1, i2 = order[0], order[1]
    u1 = HV[:, i1] / jnp.where(s[i1] > 0.0, s[i1], 1.0)
    u2 = HV[:, i2] / jnp.where(s[i2] > 0.0, s[i2], 1.0)
    v1, v2 = V[:, i1], V[:, i2]
    u3, v3 = cross(u1, u2), cross(v1, v2)
    R = u1[:, None] * v1[None, :] + u2[:, None] * v2[None, :] + u3[:, None] * v3[None, :]
    R = jnp.where(ok, R, jnp.eye(3, dtype=R.dtype))
    t = jnp.where(ok, cq - matvec(R, cp), 0.0)
    res = matvec(R, P) + t - Q
    rms = jnp.where(ok, jnp.sqrt(jnp.sum(dot(res, res)) / k), 0.0)
    return R, t, rms, ok
