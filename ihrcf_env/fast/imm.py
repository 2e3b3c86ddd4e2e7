"""Interacting multiple models for one environment: the filter bank of the fused estimator
(the port of :class:`ihrcf_env.core.estimators.imm.Imm`):
m constant-acceleration models of three values (positions, or angles wrapped to (-pi, pi]) that
differ in their acceleration drift, mixed through a Markov switch.

State per model: ``[values (3), rates (3), accelerations (3)]``. The model of one prediction (the
switch matrix, the transition and the process noise) is computed from ``dt`` here, so ``dt`` may
differ between environments. Small solves are written out (3x3 by cofactors).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

__all__ = [
    "ImmConfig",
    "ImmState",
    "imm_config",
    "imm_model",
    "imm_start",
    "largest_eigenvalue",
    "mahalanobis2",
    "predict",
    "predict_banks",
    "reseed",
    "update",
    "update_along",
    "value_cov",
    "value_sigma",
    "wrap_angles",
    "x",
]


class ImmConfig(NamedTuple):
    """The bank's models: initial 1-sigmas ``sigmas`` (3,) of (value, rate, acceleration),
    ``drifts`` (m, 3) per model and axis, ``q_white`` (3,) white-noise densities on the rates'
    derivative, ``q_value`` (3, 3) on the values', ``switch_time`` (s); ``angles`` (static) whether
    the values are angles."""

    sigmas: Array
    drifts: Array
    q_white: Array
    q_value: Array
    switch_time: Array
    angles: bool


def imm_config(
    sigmas: tuple[float, float, float],
    drifts: list[np.ndarray],
    q_white: np.ndarray,
    switch_time: float,
    angles: bool = False,
    q_value: np.ndarray | None = None,
) -> ImmConfig:
    """An :class:`ImmConfig` from :class:`~ihrcf_env.core.estimators.imm.Imm`'s arguments."""
    return ImmConfig(
        jnp.asarray(np.asarray(sigmas, dtype=np.float64)),
        jnp.asarray(np.asarray(drifts, dtype=np.float64)),
        jnp.asarray(np.asarray(q_white, dtype=np.float64)),
        jnp.asarray(np.zeros((3, 3)) if q_value is None else np.asarray(q_value, dtype=np.float64)),
        jnp.asarray(float(switch_time)),
        bool(angles),
    )


class ImmState(NamedTuple):
    """One bank: model states ``X`` (m, 9), covariances ``Ps`` (m, 9, 9), probabilities ``mu`` (m,)."""

    X: Array
    Ps: Array
    mu: Array


def wrap_angles(a: Array) -> Array:
    """Angles wrapped to (-pi, pi]."""
    return math.pi - jnp.mod(math.pi - a, 2 * math.pi)


def imm_start(cfg: ImmConfig) -> ImmState:
    """A new bank: zero states, the initial covariances, equal probabilities."""
    m = cfg.drifts.shape[0]
    P0 = jnp.diag(jnp.repeat(cfg.sigmas**2, 3))
    return ImmState(
        jnp.zeros((m, 9)), jnp.broadcast_to(P0, (m, 9, 9)), jnp.full(m, 1.0 / m, dtype=jnp.result_type(float))
    )


def _per_axis(block: Array, weights: Array) -> Array:
    """``kron(block (3, 3), diag(weights (3,)))`` in the state order (values, rates, accelerations)."""
    return (block[:, None, :, None] * jnp.diag(weights)[None, :, None, :]).reshape(9, 9)


def imm_model(dt: Array, cfg: ImmConfig) -> tuple[Array, Array, Array]:
    """(switch T (m, m), transition transposed F^T (9, 9), process noise Q (m, 9, 9)) over ``dt`` s."""
    m = cfg.drifts.shape[0]
    if m > 1:
        stay = jnp.exp(-dt / cfg.switch_time)
        T = jnp.where(jnp.eye(m, dtype=bool), stay, (1.0 - stay) / (m - 1))
    else:
        T = jnp.ones((1, 1))
    z = jnp.zeros_like(dt)
    one = jnp.ones_like(dt)
    F1 = jnp.array([[one, dt, 0.5 * dt * dt], [z, one, dt], [z, z, one]])
    Qw = jnp.array([[dt**3 / 3, dt**2 / 2, z], [dt**2 / 2, dt, z], [z, z, z]])
    Qd = jnp.array(
        [[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2], [dt**3 / 6, dt**2 / 2, dt]]
    )
    Ft = _per_axis(F1, jnp.ones(3)).T
    Q = _per_axis(Qw, cfg.q_white**2)[None] + jax.vmap(lambda d: _per_axis(Qd, d**2))(cfg.drifts)
    Q = Q.at[:, 0:3, 0:3].add(cfg.q_value * dt)
    return T, Ft, Q


def _wrap_if(a: Array, angles: bool | Array) -> Array:
    """``a`` wrapped where ``angles`` (static, or an array flag: a selection)."""
    if isinstance(angles, bool):
        return wrap_angles(a) if angles else a
    return jnp.where(angles, wrap_angles(a), a)


def _deviations(st: ImmState, lo: int, hi: int, angles: bool | Array) -> tuple[Array, Array]:
    Xs = st.X[:, lo:hi]
    first = jnp.arange(Xs.shape[0]) == jnp.argmax(st.mu)  # the most probable model (one-hot)
    ref = jnp.sum(jnp.where(first[:, None], Xs, 0.0), axis=0)
    D = Xs - ref
    if angles is not False and lo < 3:
        D = D.at[:, : 3 - lo].set(_wrap_if(D[:, : 3 - lo], angles))
    return ref, D


def _mixture_cov(mu: Array, covs: Array, dev: Array) -> Array:
    return jnp.einsum("m,mij->ij", mu, covs) + jnp.einsum("m,mi,mj->ij", mu, dev, dev)


def x(st: ImmState, cfg: ImmConfig) -> Array:
    """The combined state (9,), values wrapped for angles."""
    ref, D = _deviations(st, 0, 9, cfg.angles)
    out = ref + st.mu @ D
    if cfg.angles:
        out = out.at[0:3].set(wrap_angles(out[0:3]))
    return out


def value_cov(st: ImmState, cfg: ImmConfig) -> Array:
    """The combined covariance (3, 3) of the values."""
    D = _deviations(st, 0, 3, cfg.angles)[1]
    dev = D - st.mu @ D
    return _mixture_cov(st.mu, st.Ps[:, 0:3, 0:3], dev)


def largest_eigenvalue(C: Array) -> Array:
    """Largest eigenvalue of a symmetric (3, 3) (the trigonometric solution of the cubic)."""
    a, b, c = C[0, 0], C[0, 1], C[0, 2]
    d, e, f = C[1, 1], C[1, 2], C[2, 2]
    q = (a + d + f) / 3.0
    p1 = b * b + c * c + e * e
    a, d, f = a - q, d - q, f - q
    p2 = (a * a + d * d + f * f + 2.0 * p1) / 6.0
    scalar = ~(p2 > 0.0)
    p2s = jnp.where(scalar, 1.0, p2)
    p = jnp.sqrt(p2s)
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    r = jnp.clip(det / (2.0 * p * p2s), -1.0, 1.0)
    return jnp.where(scalar, q, q + 2.0 * p * jnp.cos(jnp.arccos(r) / 3.0))


def value_sigma(st: ImmState, cfg: ImmConfig) -> Array:
    """The largest 1-sigma of the combined values."""
    return jnp.sqrt(jnp.maximum(largest_eigenvalue(value_cov(st, cfg)), 0.0))


def predict(
    st: ImmState, dt: Array, cfg: ImmConfig, u: Array | None = None, q_value: Array | None = None
) -> ImmState:
    """The bank predicted over ``dt`` s (unchanged when ``dt <= 0``), with an optional input
    acceleration ``u`` (3,) (NaN: none) and an optional value noise density ``q_value`` (3, 3)."""
    return _predict(st, dt, cfg, cfg.angles, u, q_value)


def predict_banks(st: ImmState, dt: Array, cfgs: tuple[ImmConfig, ...], u: Array, q_value: Array) -> ImmState:
    """Banks stacked on a leading axis, one per config of ``cfgs`` (the same number of models),
    each predicted as :func:`predict` over its ``dt`` (B,) s with its input ``u`` (B, 3) (NaN:
    none) and value noise density ``q_value`` (B, 3, 3): one call over the bank axis."""
    if len({c.drifts.shape for c in cfgs}) != 1:
        raise ValueError("predict_banks: the banks must have the same number of models")
    fields = [jnp.stack([jnp.asarray(getattr(c, k)) for c in cfgs]) for k in ImmConfig._fields[:5]]
    angles = jnp.asarray([c.angles for c in cfgs])

    def one(s: ImmState, d: Array, f: list[Array], a: Array, uu: Array, qq: Array) -> ImmState:
        return _predict(s, d, ImmConfig(f[0], f[1], f[2], f[3], f[4], False), a, uu, qq)

    return jax.vmap(one)(st, dt, fields, angles, u, q_value)


def _predict(
    st: ImmState, dt: Array, cfg: ImmConfig, angles: bool | Array, u: Array | None, q_value: Array | None
) -> ImmState:
    go = dt > 0
    dts = jnp.where(go, dt, 1.0)
    T, Ft, Q0 = imm_model(dts, cfg)
    X, Ps, mu = st
    m = mu.shape[0]
    if m > 1:
        c = mu @ T
        W = T.T * mu[None, :] / c[:, None]
        ref, D = _deviations(st, 0, 9, angles)
        mean = W @ D
        X = ref[None, :] + mean
        G = Ps + D[:, :, None] * D[:, None, :]
        Ps = (W @ G.reshape(m, 81)).reshape(m, 9, 9) - mean[:, :, None] * mean[:, None, :]
        mu = c / jnp.sum(c)
    X = X @ Ft
    if u is not None:
        has = jnp.all(jnp.isfinite(u))
        uu = jnp.where(has, u, 0.0)
        X = X.at[:, 0:3].add(jnp.where(has, 0.5 * dts * dts * uu, 0.0))
        X = X.at[:, 3:6].add(jnp.where(has, dts * uu, 0.0))
    if angles is not False:
        X = X.at[:, 0:3].set(_wrap_if(X[:, 0:3], angles))
    Ps = Ft.T[None] @ Ps @ Ft[None] + Q0
    if q_value is not None:
        Ps = Ps.at[:, 0:3, 0:3].add(q_value * dts)
    new = ImmState(X, 0.5 * (Ps + jnp.swapaxes(Ps, 1, 2)), mu)
    return ImmState(*(jnp.where(go, a, b) for a, b in zip(new, st, strict=True)))


def mahalanobis2(S: Array, v: Array) -> Array:
    """``v^T S^-1 v`` of ``v`` (k,) under ``S`` (k, k), k in 1..3 (upper triangle, the adjugate);
    inf where ``S`` is not positive definite or the result is not finite."""
    k = v.shape[0]
    if k == 1:
        a, xx = S[0, 0], v[0]
        q = jnp.where(a > 0.0, xx * xx / jnp.where(a > 0.0, a, 1.0), jnp.inf)
    elif k == 2:
        a, b, d = S[0, 0], S[0, 1], S[1, 1]
        xx, y = v[0], v[1]
        det = a * d - b * b
        ok = (a > 0.0) & (det > 0.0)
        q = jnp.where(ok, (d * xx * xx - 2.0 * b * xx * y + a * y * y) / jnp.where(ok, det, 1.0), jnp.inf)
    else:
        a, b, c = S[0, 0], S[0, 1], S[0, 2]
        d, e, f = S[1, 1], S[1, 2], S[2, 2]
        xx, y, z = v[0], v[1], v[2]
        c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
        c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
        det = a * c00 + b * c01 + c * c02
        ok = (a > 0.0) & (c22 > 0.0) & (det > 0.0)
        num = c00 * xx * xx + c11 * y * y + c22 * z * z + 2.0 * (c01 * xx * y + c02 * xx * z + c12 * y * z)
        q = jnp.where(ok, num / jnp.where(ok, det, 1.0), jnp.inf)
    return jnp.where(jnp.isfinite(q), q, jnp.inf)


def _spd_inverse(S: Array) -> tuple[Array, Array, Array]:
    """Inverse (k, k), log-determinant and "positive definite" flag of a symmetric ``S``, k in
    1..3, by the adjugate."""
    k = S.shape[-1]
    if k == 1:
        det = S[0, 0]
        inv = 1.0 / S
    elif k == 2:
        a, b, d = S[0, 0], S[0, 1], S[1, 1]
        det = a * d - b * b
        inv = jnp.array([[d, -b], [-b, a]]) / det
    else:
        a, b, c = S[0, 0], S[0, 1], S[0, 2]
        d, e, f = S[1, 0], S[1, 1], S[1, 2]
        g, h, i = S[2, 0], S[2, 1], S[2, 2]
        adj = jnp.array(
            [
                [e * i - f * h, c * h - b * i, b * f - c * e],
                [f * g - d * i, a * i - c * g, c * d - a * f],
                [d * h - e * g, b * g - a * h, a * e - b * d],
            ]
        )
        det = a * adj[0, 0] + b * adj[1, 0] + c * adj[2, 0]
        inv = adj / det
    ok = jnp.isfinite(det) & (det > 0.0)
    return inv, jnp.log(jnp.where(ok, det, 1.0)), ok


def _reweigh(mu: Array, loglik: Array) -> Array:
    best = jnp.min(loglik)
    w = mu * jnp.exp(0.5 * (best - loglik))
    w = jnp.maximum(w / jnp.sum(w), 1e-12)
    return w / jnp.sum(w)


def update(
    st: ImmState, z: Array, lo: int, hi: int, R: Array, gate: Array, cfg: ImmConfig
) -> tuple[ImmState, Array, Array]:
    """The bank after measuring the values ``lo:hi`` (static) as ``z`` (k,) with covariance ``R``
    (k, k), gated at ``gate`` (inf: not gated): (new state, accepted, squared Mahalanobis distance);
    a rejected measurement leaves the state unchanged."""
    X, Ps, mu = st
    m = mu.shape[0]
    NU = z[None, :] - X[:, lo:hi]
    if cfg.angles:
        NU = wrap_angles(NU)
    Ss = Ps[:, lo:hi, lo:hi] + R[None]
    nu = mu @ NU
    S = _mixture_cov(mu, Ss, NU - nu[None, :])
    d2 = mahalanobis2(S, nu)
    Sinv_a, logdet_a, pd_a = jax.vmap(_spd_inverse)(Ss)  # the models in one call
    ok = jnp.isfinite(d2) & ~(d2 > gate)
    ok_inv = jnp.all(pd_a)
    d2 = jnp.where(ok & ~ok_inv, jnp.inf, d2)
    ok &= ok_inv
    PHt = Ps[:, :, lo:hi]
    y = jnp.einsum("mij,mj->mi", Sinv_a, NU)
    Xn = X + jnp.einsum("mij,mj->mi", PHt, y)
    Pn = Ps - (PHt @ Sinv_a) @ jnp.swapaxes(PHt, 1, 2)
    Pn = 0.5 * (Pn + jnp.swapaxes(Pn, 1, 2))
    if cfg.angles:
        Xn = Xn.at[:, 0:3].set(wrap_angles(Xn[:, 0:3]))
    mun = _reweigh(mu, jnp.sum(NU * y, axis=1) + logdet_a) if m > 1 else mu
    new = ImmState(Xn, Pn, mun)
    return ImmState(*(jnp.where(ok, a, b) for a, b in zip(new, st, strict=True))), ok, d2


def update_along(
    st: ImmState, z: Array, h: Array, var: Array, gate: Array, cfg: ImmConfig
) -> tuple[ImmState, Array, Array]:
    """The bank after the scalar measurement ``h . values = z`` (``h`` (3,)) of variance ``var``,
    gated at ``gate``: (new state, accepted, squared Mahalanobis distance)."""
    X, Ps, mu = st
    m = mu.shape[0]
    NU = z - X[:, 0:3] @ h
    PHt = Ps[:, :, 0:3] @ h
    Ss = PHt[:, 0:3] @ h + var
    nu = mu @ NU
    dev = NU - nu
    S = mu @ Ss + mu @ (dev * dev)
    d2 = jnp.where(S > 0.0, nu * nu / jnp.where(S > 0.0, S, 1.0), jnp.inf)
    d2 = jnp.where(jnp.isfinite(d2), d2, jnp.inf)
    ok = jnp.isfinite(d2) & ~(d2 > gate)
    pd = jnp.all(Ss > 0.0)
    d2 = jnp.where(ok & ~pd, jnp.inf, d2)
    ok &= pd
    Sss = jnp.where(Ss > 0.0, Ss, 1.0)
    y = NU / Sss
    Xn = X + PHt * y[:, None]
    Pn = Ps - (PHt[:, :, None] * PHt[:, None, :]) / Sss[:, None, None]
    Pn = 0.5 * (Pn + jnp.swapaxes(Pn, 1, 2))
    mun = _reweigh(mu, NU * y + jnp.log(Sss)) if m > 1 else mu
    new = ImmState(Xn, Pn, mun)
    return ImmState(*(jnp.where(ok, a, b) for a, b in zip(new, st, strict=True))), ok, d2


def reseed(st: ImmState, z: Array, R: Array, rate_var: Array | float) -> ImmState:
    """The bank restarted on the values ``z`` (3,) with covariance ``R`` (3, 3), the rates'
    variance raised by ``rate_var``."""
    X = st.X.at[:, 0:3].set(z[None, :])
    Ps = st.Ps.at[:, 0:3, :].set(0.0).at[:, :, 0:3].set(0.0).at[:, 0:3, 0:3].set(R[None])
    Ps = Ps.at[:, 3:6, 3:6].add(rate_var * jnp.eye(3))
    return ImmState(X, 0.5 * (Ps + jnp.swapaxes(Ps, 1, 2)), st.mu)
