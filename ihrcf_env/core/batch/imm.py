"""Interacting multiple models (:class:`~ihrcf_env.core.estimators.imm.Imm`) of N independent
filters as stacked arrays: each row is one env's filter bank, alive or not.

Every operation takes the rows ``i`` (int array) it applies to and leaves the others untouched,
so per-env branches of the single filter become row selections. The per-``dt`` model (Markov
switch, transition, process noise) is the single filter's own (computed by one
:class:`~ihrcf_env.core.estimators.imm.Imm` kept as a prototype), so both share it bit for bit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.estimators.imm import Imm, wrap_angles

F64 = NDArray[np.float64]
Rows = NDArray[np.intp]


def mahalanobis2_batch(S: F64, v: F64) -> F64:
    """:func:`~ihrcf_env.core.linalg.mahalanobis2` per row: ``v^T S^-1 v`` of v (n, k) under S
    (n, k, k), k in 1..3 (upper triangle read, the adjugate); inf where S is not positive definite
    or the result is not finite."""
    k = v.shape[1]
    with np.errstate(all="ignore"):
        if k == 1:
            a, x = S[:, 0, 0], v[:, 0]
            q = np.where(a > 0.0, x * x / np.where(a > 0.0, a, 1.0), np.inf)
        elif k == 2:
            a, b, d = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
            x, y = v[:, 0], v[:, 1]
            det = a * d - b * b
            ok = (a > 0.0) & (det > 0.0)
            q = np.where(ok, (d * x * x - 2.0 * b * x * y + a * y * y) / np.where(ok, det, 1.0), np.inf)
        else:
            a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 0, 2]
            d, e, f = S[:, 1, 1], S[:, 1, 2], S[:, 2, 2]
            x, y, z = v[:, 0], v[:, 1], v[:, 2]
            c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
            c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
            det = a * c00 + b * c01 + c * c02
            ok = (a > 0.0) & (c22 > 0.0) & (det > 0.0)
            num = c00 * x * x + c11 * y * y + c22 * z * z + 2.0 * (c01 * x * y + c02 * x * z + c12 * y * z)
            q = np.where(ok, num / np.where(ok, det, 1.0), np.inf)
    return np.where(np.isfinite(q), q, np.inf)


def largest_eigenvalue_batch(C: F64) -> F64:
    """:func:`~ihrcf_env.core.estimators.imm.largest_eigenvalue` per row of symmetric (n, 3, 3)."""
    a, b, c = C[:, 0, 0], C[:, 0, 1], C[:, 0, 2]
    d, e, f = C[:, 1, 1], C[:, 1, 2], C[:, 2, 2]
    q = (a + d + f) / 3.0
    p1 = b * b + c * c + e * e
    a, d, f = a - q, d - q, f - q
    p2 = (a * a + d * d + f * f + 2.0 * p1) / 6.0
    scalar = ~(p2 > 0.0)
    p2s = np.where(scalar, 1.0, p2)
    p = np.sqrt(p2s)
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    r = np.clip(det / (2.0 * p * p2s), -1.0, 1.0)
    return np.where(scalar, q, q + 2.0 * p * np.cos(np.arccos(r) / 3.0))


def _spd_inverse(S: F64) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Inverses (..., k, k), log-determinants (...) and "positive definite" flags (...) of
    symmetric (..., k, k), k in 1..3, by the adjugate (inverse of a non-PD row: garbage)."""
    k = S.shape[-1]
    with np.errstate(all="ignore"):
        if k == 1:
            det = S[..., 0, 0]
            inv = 1.0 / S
        elif k == 2:
            a, b, d = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
            det = a * d - b * b
            adj = np.stack([np.stack([d, -b], -1), np.stack([-b, a], -1)], -2)
            inv = adj / det[..., None, None]
        else:
            inv = np.asarray(np.linalg.inv(np.where(np.isfinite(S), S, 0.0)), dtype=np.float64)
            det = np.linalg.det(S)
        ok = np.isfinite(det) & (det > 0.0)
        logdet = np.log(np.where(ok, det, 1.0))
    return inv, logdet, ok


class BatchImm:
    """N :class:`~ihrcf_env.core.estimators.imm.Imm` filters (same models) side by side; a row is
    ``alive`` once :meth:`start` ed, until :meth:`drop` ped. Arguments as :class:`Imm`."""

    def __init__(
        self,
        n: int,
        sigmas: tuple[float, float, float],
        drifts: list[F64],
        q_white: F64,
        switch_time: float,
        angles: bool = False,
        q_value: F64 | None = None,
    ) -> None:
        self._proto = Imm(sigmas, drifts, q_white, switch_time, 0.0, angles, q_value)
        m = len(drifts)
        self.angles = angles
        self.X = np.zeros((n, m, 9))
        self.Ps = np.repeat(self._proto.Ps[None], n, axis=0)
        self.mu = np.full((n, m), 1.0 / m)
        self.alive = np.zeros(n, dtype=bool)
        self.frames = np.zeros(n, dtype=np.int64)
        self.rejected_run = np.zeros(n, dtype=np.int64)
        self.last_accepted = np.zeros(n)

    def start(self, i: Rows, time: F64) -> None:
        """New filters in rows ``i`` at ``time`` (len(i),) s."""
        p = self._proto
        self.X[i] = 0.0
        self.Ps[i] = p.Ps
        self.mu[i] = 1.0 / p.mu.size
        self.alive[i] = True
        self.frames[i] = 0
        self.rejected_run[i] = 0
        self.last_accepted[i] = time

    def drop(self, i: Rows | NDArray[np.bool_]) -> None:
        self.alive[i] = False

    def reseed(self, i: Rows, z: F64, R: F64, rate_var: float) -> None:
        """:meth:`Imm.reseed` of rows ``i``: values ``z`` (k, 3) with covariances ``R`` (k, 3, 3)."""
        X, Ps = self.X[i], self.Ps[i]
        X[:, :, 0:3] = z[:, None, :]
        Ps[:, :, 0:3, :] = 0.0
        Ps[:, :, :, 0:3] = 0.0
        Ps[:, :, 0:3, 0:3] = R[:, None]
        Ps[:, :, 3:6, 3:6] += rate_var * np.eye(3)
        self.X[i], self.Ps[i] = X, 0.5 * (Ps + Ps.transpose(0, 1, 3, 2))

    def copy(self) -> BatchImm:
        out = object.__new__(BatchImm)
        out.__dict__.update(self.__dict__)
        for name in ("X", "Ps", "mu", "alive", "frames", "rejected_run", "last_accepted"):
            setattr(out, name, getattr(self, name).copy())
        return out

    # -- combined estimate --------------------------------------------------------------------
    def _deviations(self, i: Rows, lo: int, hi: int) -> tuple[F64, F64]:
        X, mu = self.X[i, :, lo:hi], self.mu[i]
        ref = X[np.arange(len(i)), mu.argmax(axis=1)]
        D = X - ref[:, None, :]
        if self.angles and lo < 3:
            D[:, :, : 3 - lo] = wrap_angles(D[:, :, : 3 - lo])
        return ref, D

    @staticmethod
    def _mixture_cov(mu: F64, covs: F64, dev: F64) -> F64:
        return np.einsum("nm,nmij->nij", mu, covs) + np.einsum("nm,nmi,nmj->nij", mu, dev, dev)

    def x(self, i: Rows) -> F64:
        """Combined states (len(i), 9), values wrapped for angles."""
        ref, D = self._deviations(i, 0, 9)
        x = ref + np.einsum("nm,nmk->nk", self.mu[i], D)
        if self.angles:
            x[:, 0:3] = wrap_angles(x[:, 0:3])
        return x

    def value_cov(self, i: Rows) -> F64:
        """Combined covariances of the values (len(i), 3, 3)."""
        mu = self.mu[i]
        D = self._deviations(i, 0, 3)[1]
        dev = D - np.einsum("nm,nmk->nk", mu, D)[:, None, :]
        return self._mixture_cov(mu, self.Ps[i, :, 0:3, 0:3], dev)

    def value_sigma(self, i: Rows) -> F64:
        """Largest 1-sigma of the combined values (len(i),)."""
        return np.sqrt(np.maximum(largest_eigenvalue_batch(self.value_cov(i)), 0.0))

    def finite(self, i: Rows) -> NDArray[np.bool_]:
        return (
            np.isfinite(self.X[i]).all(axis=(1, 2))
            & np.isfinite(self.Ps[i]).all(axis=(1, 2, 3))
            & np.isfinite(self.mu[i]).all(axis=1)
        )

    # -- prediction ----------------------------------------------------------------------------
    def predict(self, i: Rows, dt: F64, u: F64 | None = None, q_value: F64 | None = None) -> None:
        """:meth:`Imm.predict` of rows ``i`` over ``dt`` (len(i),) s (rows with dt <= 0 unchanged);
        ``u`` (len(i), 3) with NaN rows for "no input"; ``q_value`` (len(i), 3, 3) or None."""
        go = dt > 0
        i, dt = i[go], dt[go]
        if i.size == 0:
            return
        u = None if u is None else u[go]
        q_value = None if q_value is None else q_value[go]
        m = self.mu.shape[1]
        steps, inverse = np.unique(dt, return_inverse=True)
        models = [self._proto._model(float(s)) for s in steps]
        T = np.stack([md[0] for md in models])[inverse]
        Ft = np.stack([md[1] for md in models])[inverse]
        Q0 = np.stack([md[2] for md in models])[inverse]
        X, Ps, mu = self.X[i], self.Ps[i], self.mu[i]
        if m > 1:
            c = np.einsum("nm,nmk->nk", mu, T)
            W = T.transpose(0, 2, 1) * mu[:, None, :]
            W /= c[:, :, None]
            ref, D = self._deviations(i, 0, 9)
            mean = W @ D
            X = ref[:, None, :] + mean
            G = Ps + D[:, :, :, None] * D[:, :, None, :]
            Ps = (W @ G.reshape(len(i), m, 81)).reshape(len(i), m, 9, 9) - mean[:, :, :, None] * mean[
                :, :, None, :
            ]
            mu = c / c.sum(axis=1, keepdims=True)
        X = X @ Ft
        if u is not None:
            has: NDArray[np.bool_] = np.asarray(np.isfinite(u).all(axis=1))
            uu = np.where(has[:, None], u, 0.0)
            d = dt[:, None]
            X[:, :, 0:3] += np.where(has[:, None], 0.5 * d * d * uu, 0.0)[:, None, :]
            X[:, :, 3:6] += np.where(has[:, None], d * uu, 0.0)[:, None, :]
        if self.angles:
            X[:, :, 0:3] = wrap_angles(X[:, :, 0:3])
        Ps = Ft.transpose(0, 2, 1)[:, None] @ Ps @ Ft[:, None] + Q0
        if q_value is not None:
            Ps[:, :, 0:3, 0:3] += (q_value * dt[:, None, None])[:, None]
        self.X[i] = X
        self.Ps[i] = 0.5 * (Ps + Ps.transpose(0, 1, 3, 2))
        self.mu[i] = mu

    # -- measurement update ----------------------------------------------------------------------
    def update(
        self, i: Rows, z: F64, rows: tuple[int, int], R: F64, gate: F64
    ) -> tuple[NDArray[np.bool_], F64]:
        """:meth:`Imm.update` of rows ``i``: values ``rows`` measured as ``z`` (len(i), k) with
        covariance ``R`` (len(i), k, k), gated at ``gate`` (len(i),; inf: not gated). Returns
        (accepted, squared Mahalanobis distance), each (len(i),)."""
        lo, hi = rows
        mu, Ps, X = self.mu[i], self.Ps[i], self.X[i]
        NU = z[:, None, :] - X[:, :, lo:hi]
        if self.angles:
            NU = wrap_angles(NU)
        Ss = Ps[:, :, lo:hi, lo:hi] + R[:, None]
        nu = np.einsum("nm,nmk->nk", mu, NU)
        S = self._mixture_cov(mu, Ss, NU - nu[:, None, :])
        d2 = mahalanobis2_batch(S, nu)
        Sinv, logdet, pd = _spd_inverse(Ss)
        ok = np.isfinite(d2) & ~(d2 > gate)
        ok_inv = pd.all(axis=1)
        d2 = np.where(ok & ~ok_inv, np.inf, d2)
        ok &= ok_inv
        if not ok.any():
            return ok, d2
        j = i[ok]
        mu, Ps, X, NU, Sinv, logdet = mu[ok], Ps[ok], X[ok], NU[ok], Sinv[ok], logdet[ok]
        PHt = Ps[:, :, :, lo:hi]
        y = Sinv @ NU[:, :, :, None]
        X = X + (PHt @ y)[:, :, :, 0]
        Ps = Ps - (PHt @ Sinv) @ PHt.transpose(0, 1, 3, 2)
        self.Ps[j] = 0.5 * (Ps + Ps.transpose(0, 1, 3, 2))
        if self.angles:
            X[:, :, 0:3] = wrap_angles(X[:, :, 0:3])
        self.X[j] = X
        if mu.shape[1] > 1:
            loglik = np.einsum("nmk,nmk->nm", NU, y[:, :, :, 0]) + logdet
            best = loglik.min(axis=1, keepdims=True)
            w = mu * np.exp(0.5 * (best - loglik))
            w = np.maximum(w / w.sum(axis=1, keepdims=True), 1e-12)
            self.mu[j] = w / w.sum(axis=1, keepdims=True)
        return ok, d2

    def update_along(self, i: Rows, z: F64, h: F64, var: F64, gate: F64) -> tuple[NDArray[np.bool_], F64]:
        """:meth:`Imm.update_along` of rows ``i``: ``h @ values = z`` with ``z`` (len(i),), ``h``
        (len(i), 3), variance ``var`` (len(i),), gated at ``gate`` (len(i),; inf: not gated).
        Returns (accepted, squared Mahalanobis distance), each (len(i),)."""
        mu, Ps, X = self.mu[i], self.Ps[i], self.X[i]
        NU = z[:, None] - np.einsum("nmk,nk->nm", X[:, :, 0:3], h)
        PHt = np.einsum("nmik,nk->nmi", Ps[:, :, :, 0:3], h)
        Ss = np.einsum("nmk,nk->nm", PHt[:, :, 0:3], h) + var[:, None]
        nu = np.einsum("nm,nm->n", mu, NU)
        dev = NU - nu[:, None]
        S = np.einsum("nm,nm->n", mu, Ss) + np.einsum("nm,nm->n", mu, dev * dev)
        with np.errstate(all="ignore"):
            d2 = np.where(S > 0.0, nu * nu / np.where(S > 0.0, S, 1.0), np.inf)
        d2 = np.where(np.isfinite(d2), d2, np.inf)
        ok = np.isfinite(d2) & ~(d2 > gate)
        pd = (Ss > 0.0).all(axis=1)
        d2 = np.where(ok & ~pd, np.inf, d2)
        ok &= pd
        if not ok.any():
            return ok, d2
        j = i[ok]
        mu, Ps, X, NU, PHt, Ss = mu[ok], Ps[ok], X[ok], NU[ok], PHt[ok], Ss[ok]
        y = NU / Ss
        self.X[j] = X + PHt * y[:, :, None]
        Ps = Ps - (PHt[:, :, :, None] * PHt[:, :, None, :]) / Ss[:, :, None, None]
        self.Ps[j] = 0.5 * (Ps + Ps.transpose(0, 1, 3, 2))
        if mu.shape[1] > 1:
            loglik = NU * y + np.log(Ss)
            best = loglik.min(axis=1, keepdims=True)
            w = mu * np.exp(0.5 * (best - loglik))
            w = np.maximum(w / w.sum(axis=1, keepdims=True), 1e-12)
            self.mu[j] = w / w.sum(axis=1, keepdims=True)
        return ok, d2

    def assign(self, i: Rows, other: BatchImm) -> None:
        """Rows ``i`` of this bank set to those of ``other`` (same models)."""
        for name in ("X", "Ps", "mu", "alive", "frames", "rejected_run", "last_accepted"):
            getattr(self, name)[i] = getattr(other, name)[i]


__all__ = [
    "BatchImm",
    "Rows",
    "largest_eigenvalue_batch",
    "mahalanobis2_batch",
]
