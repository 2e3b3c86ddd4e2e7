"""Interacting multiple models of a kinematic Kalman filter (pure numpy).

:class:`Imm` runs three axes of ``[value, rate, rate of rate]`` under several process-noise levels
at once (Blom and Bar-Shalom), the generic filter bank of the fused estimator
(:mod:`ihrcf_env.core.estimators.fused`); :func:`wrap_angles` and :func:`largest_eigenvalue` are
its small helpers.
"""

from __future__ import annotations

import copy
import functools
import math

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.linalg import mahalanobis2, spd_inverse


def wrap_angles(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles wrapped to (-pi, pi] (:func:`~ihrcf_env.core.frames.wrap_angle` without the checks)."""
    return math.pi - np.mod(math.pi - a, 2 * math.pi)


@functools.lru_cache(maxsize=8)
def _kinematics(dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per-axis transition ``F1`` (3, 3) of ``[value, rate, acceleration]`` over ``dt`` s, and the
    process-noise shapes of a white rate derivative ``Qw`` and a white acceleration derivative ``Qd``
    (unit spectral density)."""
    F1 = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    Qw = np.array([[dt**3 / 3, dt**2 / 2, 0.0], [dt**2 / 2, dt, 0.0], [0.0, 0.0, 0.0]])
    Qd = np.array(
        [[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2], [dt**3 / 6, dt**2 / 2, dt]]
    )
    for m in (F1, Qw, Qd):
        m.setflags(write=False)
    return F1, Qw, Qd


def _per_axis(block: NDArray[np.float64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """The (9, 9) matrix of a per-axis (3, 3) ``block`` scaled by ``weights`` (3,) per axis, in the
    state order ``[values (3), rates (3), accelerations (3)]`` (``kron(block, diag(weights))``)."""
    return (block[:, None, :, None] * np.diag(weights)[None, :, None, :]).reshape(9, 9)


def largest_eigenvalue(C: NDArray[np.float64]) -> float:
    """Largest eigenvalue of a symmetric (3, 3) matrix (closed form: the trigonometric solution of
    the characteristic cubic, Smith 1961)."""
    (a, b, c), (_, d, e), (_, _, f) = C.tolist()
    q = (a + d + f) / 3.0
    p1 = b * b + c * c + e * e
    a, d, f = a - q, d - q, f - q
    p2 = (a * a + d * d + f * f + 2.0 * p1) / 6.0
    if p2 <= 0.0:  # a multiple of the identity
        return q
    p = math.sqrt(p2)
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    r = max(-1.0, min(1.0, det / (2.0 * p * p2)))
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)


class Imm:
    """Kalman filters of three axes of ``[value, rate, rate of rate]`` (state (9,) ordered
    ``[values (3), rates (3), accelerations (3)]``), as interacting multiple models (Blom and
    Bar-Shalom): the same filter under several process-noise levels (``drifts``, one (3,) density of
    the acceleration's derivative per model), mixed at every prediction through a Markov switch of
    mean sojourn ``switch_time`` s and weighted by their measurement likelihoods. A slow deck selects
    the quiet model (long averaging), a sea-state deck the agile one, without retuning. One model is
    a plain Kalman filter. Gating uses the combined estimate; the counters serve the validity and
    re-initialisation rules. All models are propagated and corrected at once (stacked arrays), and
    every step is written for tiny matrices: a measurement's rows are a contiguous block, so its
    ``H`` is a slice, and the combined estimate is moment-matched only where it is read (the
    measured block for the gate; the state and the values' covariance for the output)."""

    def __init__(
        self,
        sigmas: tuple[float, float, float],
        drifts: list[NDArray[np.float64]],
        q_white: NDArray[np.float64],
        switch_time: float,
        time: float,
        angles: bool = False,
        q_value: NDArray[np.float64] | None = None,
    ) -> None:
        """Initial 1-sigmas ``sigmas`` of (value, rate, acceleration), the same on every axis; the
        models' ``drifts``; white-noise spectral densities ``q_white`` (3,) on the rates' derivative
        (1 sigma per sqrt(Hz)) and ``q_value`` (3, 3) on the values' derivative (value^2/s; constant
        here, a varying one is given to :meth:`predict`); initial ``time`` s."""
        n = len(drifts)
        self.X = np.zeros((n, 9))  # model states
        self.Ps = np.repeat(np.diag(np.repeat(np.square(sigmas), 3))[None], n, axis=0)  # (n, 9, 9)
        self.drifts = np.asarray(drifts, dtype=np.float64)  # (n, 3)
        self.mu = np.full(n, 1.0 / n)
        self.q_white = np.array(q_white, dtype=np.float64)
        self.q_value = np.zeros((3, 3)) if q_value is None else np.array(q_value, dtype=np.float64)
        self.switch_time = switch_time
        self.angles = angles  # values are angles: wrapped innovations and states
        self.frames = 0  # frames with at least one accepted measurement
        self.rejected_run = 0  # consecutive frames whose every measurement was rejected
        self.last_accepted = time  # time of the last accepted measurement, s
        self._x: NDArray[np.float64] | None = None  # combined state, cached until the next change
        self._value_cov: NDArray[np.float64] | None = None  # combined values' covariance, cached
        #: per dt: Markov switch T (n, n), transition F^T (9, 9), process noise (n, 9, 9) (the
        #: filter runs at a fixed frame rate: computed once)
        self._model_cache: dict[float, tuple[NDArray[np.float64], ...]] = {}

    def _model(self, dt: float) -> tuple[NDArray[np.float64], ...]:
        """(T, F^T, Q) of one prediction over ``dt`` s (see :meth:`predict`), cached."""
        hit = self._model_cache.get(dt)
        if hit is not None:
            return hit
        n = len(self.mu)
        T = np.ones((1, 1))  # one model: no switching
        if n > 1:
            stay = math.exp(-dt / self.switch_time)
            T = np.full((n, n), (1.0 - stay) / (n - 1))
            np.fill_diagonal(T, stay)
        F1, Qw, Qd = _kinematics(float(dt))
        Ft = np.ascontiguousarray(_per_axis(F1, np.ones(3)).T)
        Q = _per_axis(Qw, np.square(self.q_white))[None] + np.stack(
            [_per_axis(Qd, np.square(d)) for d in self.drifts]
        )
        Q[:, 0:3, 0:3] += self.q_value * dt
        for m in (T, Ft, Q):
            m.setflags(write=False)
        if len(self._model_cache) >= 8:
            self._model_cache.clear()
        self._model_cache[dt] = (T, Ft, Q)
        return T, Ft, Q

    def _deviations(self, lo: int, hi: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The most probable model's state rows ``lo:hi`` (reference) and every model's deviation
        from it (n, hi - lo), angles wrapped: the mixture is taken around one model, so angles near
        +-pi mix correctly."""
        Xr = self.X[:, lo:hi]
        ref = Xr[int(self.mu.argmax())]
        D = Xr - ref
        if self.angles and lo < 3:
            D[:, : 3 - lo] = wrap_angles(D[:, : 3 - lo])
        return ref, D

    def _changed(self) -> None:
        self._x = None
        self._value_cov = None

    @property
    def x(self) -> NDArray[np.float64]:
        """The combined (moment-matched) state (9,), values wrapped for angles."""
        if self._x is None:
            ref, D = self._deviations(0, self.X.shape[1])
            x = ref + self.mu @ D
            if self.angles:
                x[0:3] = wrap_angles(x[0:3])
            self._x = x
        return self._x

    def _mixture_cov(self, covs: NDArray[np.float64], dev: NDArray[np.float64]) -> NDArray[np.float64]:
        """Moment-matched covariance of the models' ``covs`` (n, k, k) about points whose deviations
        from the combined mean are ``dev`` (n, k): ``sum_i mu_i (C_i + d_i d_i^T)``."""
        return np.einsum("n,nij->ij", self.mu, covs) + (dev.T * self.mu) @ dev

    @property
    def value_cov(self) -> NDArray[np.float64]:
        """The combined covariance (3, 3) of the values."""
        if self._value_cov is None:
            D = self._deviations(0, 3)[1]
            self._value_cov = self._mixture_cov(self.Ps[:, 0:3, 0:3], D - self.mu @ D)
        return self._value_cov

    def predict(
        self, dt: float, u: NDArray[np.float64] | None = None, q_value: NDArray[np.float64] | None = None
    ) -> None:
        """Mix the models, then propagate each ``dt`` s: ``u`` (3,) a known acceleration of the
        values, ``q_value`` (3, 3) a white-noise spectral density on the values' derivative
        (value^2/s) added to the constant one for this step; the process noise is the filter's
        (see the constructor) plus each model's drift on the accelerations' derivative."""
        if dt <= 0:
            return
        n, k = self.X.shape
        T, Ft, Q0 = self._model(float(dt))
        X, Ps = self.X, self.Ps
        if n > 1:  # mixing: model j starts from the mixture of the models weighted by P(i | j)
            c = self.mu @ T  # predicted model probabilities
            W = T.T * self.mu
            W /= c[:, None]  # W[j, i] = P(i | j) = T[i, j] mu_i / c_j
            ref, D = self._deviations(0, k)
            mean = W @ D  # (n, k)
            X = ref + mean
            # sum_i W[j, i] (P_i + (D_i - m_j)(D_i - m_j)^T) = sum_i W[j, i] (P_i + D_i D_i^T) - m_j m_j^T
            G = Ps + D[:, :, None] * D[:, None, :]
            Ps = (W @ G.reshape(n, k * k)).reshape(n, k, k) - mean[:, :, None] * mean[:, None, :]
            self.mu = c / c.sum()
        if Ft.ndim == 2:  # one transition for every model
            X = X @ Ft
        else:  # (n, k, k): one per model
            X = np.einsum("ni,nij->nj", X, Ft)
        if u is not None:
            X[:, 0:3] += 0.5 * dt * dt * u
            X[:, 3:6] += dt * u
        if self.angles:
            X[:, 0:3] = wrap_angles(X[:, 0:3])
        Ps = (Ft.T if Ft.ndim == 2 else Ft.transpose(0, 2, 1)) @ Ps @ Ft + Q0
        if q_value is not None:
            Ps[:, 0:3, 0:3] += q_value * dt
        self.X = X
        self.Ps = 0.5 * (Ps + Ps.transpose(0, 2, 1))
        self._changed()

    def predicted(
        self, dt: float, u: NDArray[np.float64] | None = None, q_value: NDArray[np.float64] | None = None
    ) -> Imm:
        """A copy of this filter predicted ``dt`` s ahead (see :meth:`predict`); this one is unchanged
        (the copy shares no array it modifies: :meth:`predict` and :meth:`update` replace them)."""
        out = copy.copy(self)
        out.predict(dt, u, q_value)
        return out

    def update(
        self, z: NDArray[np.float64], rows: tuple[int, int], R: NDArray[np.float64], gate: float | None
    ) -> tuple[bool, float]:
        """Measure the values ``rows = (lo, hi)`` (state rows ``lo:hi``, within 0..3) as ``z`` with
        covariance ``R`` (exactly symmetric); gated on the combined estimate (squared Mahalanobis
        distance beyond ``gate``: rejected, nothing changes). Returns (accepted, squared distance)."""
        lo, hi = rows
        mu, Ps = self.mu, self.Ps
        NU = z - self.X[:, lo:hi]  # (n, k) innovation of each model
        if self.angles:
            NU = wrap_angles(NU)
        Ss = Ps[:, lo:hi, lo:hi] + R  # (n, k, k) innovation covariance of each model (symmetric:
        # the covariances are symmetrised after every change and R must be exactly symmetric)
        # the combined estimate's innovation and covariance (moment matching; sum(mu) = 1)
        nu = mu @ NU
        S = self._mixture_cov(Ss, NU - nu)  # (sum(mu) = 1: the mixture of P + R is P's mixture + R)
        d2 = mahalanobis2(S, nu)
        if not math.isfinite(d2) or (gate is not None and d2 > gate):
            return False, d2
        inverses = spd_inverse(Ss)
        if inverses is None:
            return False, math.inf
        Sinv, logdet = inverses
        # every model: Kalman update (H selects rows lo:hi; gain K = P H^T S^-1; x + K nu and
        # P - K S K^T = P - K (P H^T)^T, symmetrised) and the likelihood of its innovation
        PHt = Ps[:, :, lo:hi]  # (n, 9, k) = P H^T
        y = Sinv @ NU[:, :, None]  # (n, k, 1) = S^-1 nu
        X = self.X + (PHt @ y)[:, :, 0]
        Ps = Ps - (PHt @ Sinv) @ PHt.transpose(0, 2, 1)
        self.Ps = 0.5 * (Ps + Ps.transpose(0, 2, 1))
        if self.angles:
            X[:, 0:3] = wrap_angles(X[:, 0:3])
        self.X = X
        if len(mu) > 1:
            self._bayes((np.einsum("nk,nk->n", NU, y[:, :, 0]) + logdet).tolist())
        self._changed()
        return True, d2

    def _bayes(self, loglik: list[float]) -> None:
        """Bayes on the model probabilities from each model's ``-2 log`` likelihood (mu >= 1e-12 >
        0), the likelihoods scaled by the largest (plain floats: n numbers)."""
        best = min(loglik)
        w = [m * math.exp(0.5 * (best - ll)) for m, ll in zip(self.mu.tolist(), loglik, strict=True)]
        total = sum(w)
        w = [max(x / total, 1e-12) for x in w]
        total = sum(w)
        self.mu = np.array([x / total for x in w])

    def update_along(
        self, z: float, h: NDArray[np.float64], var: float, gate: float | None
    ) -> tuple[bool, float]:
        """Measure one combination of the values, ``h @ values = z`` (``h`` (3,), variance ``var``),
        gated on the combined estimate as :meth:`update`; the values orthogonal to ``h`` are
        corrected only through their covariance with it. Not for angles. Returns (accepted,
        squared distance)."""
        mu, Ps = self.mu, self.Ps
        NU = z - self.X[:, 0:3] @ h  # (n,) innovation of each model
        PHt = Ps[:, :, 0:3] @ h  # (n, 9) = P H^T
        Ss = PHt[:, 0:3] @ h + var  # (n,) innovation variance of each model
        nu = float(mu @ NU)
        dev = NU - nu
        S = float(mu @ Ss + mu @ (dev * dev))
        d2 = nu * nu / S if S > 0.0 else math.inf
        if not math.isfinite(d2) or (gate is not None and d2 > gate):
            return False, d2
        if not bool((Ss > 0.0).all()):
            return False, math.inf
        y = NU / Ss
        self.X = self.X + PHt * y[:, None]
        Ps = Ps - (PHt[:, :, None] * PHt[:, None, :]) / Ss[:, None, None]
        self.Ps = 0.5 * (Ps + Ps.transpose(0, 2, 1))
        if len(mu) > 1:
            self._bayes((NU * y + np.log(Ss)).tolist())  # -2 log L
        self._changed()
        return True, d2

    def reseed(self, z: NDArray[np.float64], R: NDArray[np.float64], rate_var: float) -> None:
        """Restart the values of every model at ``z`` (3,) with covariance ``R`` (3, 3), keeping the
        rates and accelerations with ``rate_var`` added to the rates' variance and their correlation
        with the old values dropped (a prediction that every measurement disagreed with; not for
        angles)."""
        X, Ps = self.X.copy(), self.Ps.copy()
        X[:, 0:3] = z
        Ps[:, 0:3, :] = 0.0
        Ps[:, :, 0:3] = 0.0
        Ps[:, 0:3, 0:3] = R
        Ps[:, 3:6, 3:6] += rate_var * np.eye(3)
        self.X, self.Ps = X, 0.5 * (Ps + Ps.transpose(0, 2, 1))
        self._changed()

    def finite(self) -> bool:
        return bool(np.isfinite(self.X).all() and np.isfinite(self.Ps).all() and np.isfinite(self.mu).all())

    def value_sigma(self) -> float:
        """Largest 1-sigma of the (combined) values."""
        return math.sqrt(max(largest_eigenvalue(self.value_cov), 0.0))


__all__ = [
    "Imm",
    "largest_eigenvalue",
    "wrap_angles",
]
