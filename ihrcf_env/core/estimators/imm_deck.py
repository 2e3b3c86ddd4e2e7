"""The fused filter's narrow-band deck model (``FusedParams.deck_model="oscillator"``).

:class:`DeckImm` is an :class:`~ihrcf_env.core.estimators.imm.Imm` whose state carries, besides
each axis's value, rate and slowly drifting acceleration ``b``, the deck's own oscillation on that
axis: a displacement ``h`` and its rate ``g`` of a damped oscillator (natural period ``T``, damping
ratio ``zeta``) driven by white noise. The value's acceleration is ``b + h''`` (plus the known
input), so a deck that sways at the ship's frequencies is followed by the oscillator instead of
lagging behind a random walk of the acceleration. Per axis, ``s = [value, rate, b, h, g]``::

    value' = rate
    rate'  = b - w^2 h - 2 zeta w g + n_h + n_rate        (w = 2 pi / T)
    b'     = n_b                                          (the model's drift)
    h'     = g
    g'     = -w^2 h - 2 zeta w g + n_h

with ``n_h`` of spectral density ``4 zeta sigma_a^2 / w`` (the stationary acceleration of the
oscillator then has the standard deviation ``sigma_a``). The models of the interacting multiple
models are the kinematic ones (no oscillator: ``h`` and ``g`` do not drive the value) and one
oscillator per period of a bank, so the likelihoods choose the deck's band as the episode runs;
:meth:`DeckImm.set_oscillators` replaces the bank's periods and levels (for example with the
dynamics identified by the deck-motion forecaster, :func:`~ihrcf_env.core.forecast.dominant_period`).
The state has a fixed size (15) and every step a fixed amount of work: the discrete transitions
(matrix exponential and Van Loan's process noise) are computed once per step length and bank.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from ihrcf_env.core.estimators.imm import Imm

__all__ = ["ORDER", "DeckImm", "oscillator_transition"]

#: States per axis: value, rate, drifting acceleration, oscillator displacement and rate.
ORDER = 5


def oscillator_transition(
    dt: float,
    period: float,
    zeta: float,
    coupled: bool,
    accel_sigma: NDArray[np.float64],
    drift: NDArray[np.float64],
    q_white: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The (15, 15) transition ``F`` and process noise ``Q`` over ``dt`` s of one model, in the state
    order ``[values (3), rates (3), b (3), h (3), g (3)]``: the oscillator of ``period`` s and
    damping ``zeta`` with stationary acceleration ``accel_sigma`` (3,) per axis, driving the value
    when ``coupled``; ``drift`` (3,) the density of ``b``'s random walk, ``q_white`` (3,) the
    density of the rates' white noise."""
    w = 2.0 * math.pi / period
    c = 1.0 if coupled else 0.0
    A = np.zeros((ORDER, ORDER))
    A[0, 1] = 1.0
    A[1, 2] = 1.0
    A[1, 3], A[1, 4] = -c * w * w, -c * 2.0 * zeta * w
    A[3, 4] = 1.0
    A[4, 3], A[4, 4] = -w * w, -2.0 * zeta * w
    F = np.zeros((3 * ORDER, 3 * ORDER))
    Q = np.zeros((3 * ORDER, 3 * ORDER))
    for axis in range(3):
        qh = 4.0 * zeta * float(accel_sigma[axis]) ** 2 / w if coupled else 0.0
        Qc = np.zeros((ORDER, ORDER))
        Qc[1, 1] = float(q_white[axis]) ** 2 + c * qh
        Qc[1, 4] = Qc[4, 1] = c * qh
        Qc[4, 4] = qh
        Qc[2, 2] = float(drift[axis]) ** 2
        M = np.zeros((2 * ORDER, 2 * ORDER))
        M[:ORDER, :ORDER] = -A * dt
        M[:ORDER, ORDER:] = Qc * dt
        M[ORDER:, ORDER:] = A.T * dt
        E = expm(M)
        Fa = E[ORDER:, ORDER:].T
        Qa = Fa @ E[:ORDER, ORDER:]
        idx = np.arange(ORDER) * 3 + axis
        F[np.ix_(idx, idx)] = Fa
        Q[np.ix_(idx, idx)] = 0.5 * (Qa + Qa.T)
    return F, Q


class DeckImm(Imm):
    """:class:`Imm` with the deck's oscillation in its state (module docstring): the models are the
    kinematic ``drifts`` (one (3,) density of ``b``'s random walk each), then one oscillator per
    ``periods`` (s) with the drift ``oscillator_drift`` (3,); ``accel_sigma`` (3,) the oscillators'
    stationary acceleration per axis, ``zeta`` their damping ratio. Other arguments as
    :class:`Imm`."""

    def __init__(
        self,
        sigmas: tuple[float, float, float],
        drifts: list[NDArray[np.float64]],
        q_white: NDArray[np.float64],
        switch_time: float,
        time: float,
        periods: tuple[float, ...],
        zeta: float,
        accel_sigma: NDArray[np.float64],
        oscillator_drift: NDArray[np.float64],
        angles: bool = False,
        q_value: NDArray[np.float64] | None = None,
    ) -> None:
        n_kin = len(drifts)
        super().__init__(
            sigmas,
            [*drifts, *([oscillator_drift] * len(periods))],
            q_white,
            switch_time,
            time,
            angles,
            q_value,
        )
        n = len(self.mu)
        self.n_kinematic = n_kin
        self.zeta = float(zeta)
        self.periods = np.asarray(periods, dtype=np.float64)
        self.accel_sigma = np.asarray(accel_sigma, dtype=np.float64)
        k = 3 * ORDER
        Ps = np.zeros((n, k, k))
        Ps[:, :9, :9] = self.Ps
        Ps[:, 9:, 9:] = self._oscillator_cov()
        self.X = np.zeros((n, k))
        self.Ps = Ps

    def _oscillator_cov(self) -> NDArray[np.float64]:
        """Stationary covariance (6, 6) of ``[h (3), g (3)]`` of the bank's middle period."""
        w = 2.0 * math.pi / float(np.median(self.periods)) if self.periods.size else 1.0
        a2 = self.accel_sigma**2
        return np.diag(np.concatenate([a2 / w**4, a2 / w**2]))

    def set_oscillators(self, periods: tuple[float, ...], accel_sigma: NDArray[np.float64]) -> None:
        """Replace the bank's periods (s; as many as before) and stationary accelerations (3,)."""
        new = np.asarray(periods, dtype=np.float64)
        if new.shape != self.periods.shape or not np.all(np.isfinite(new) & (new > 0)):
            raise ValueError(f"periods must be {self.periods.size} positive numbers (s), got {periods!r}")
        sig = np.asarray(accel_sigma, dtype=np.float64).reshape(-1)
        if sig.shape != (3,) or not np.all(np.isfinite(sig) & (sig >= 0)):
            raise ValueError(f"accel_sigma must be 3 numbers >= 0, got {accel_sigma!r}")
        self.periods, self.accel_sigma = new, sig
        self._model_cache.clear()

    def _model(self, dt: float) -> tuple[NDArray[np.float64], ...]:
        """(T, F^T per model (n, 15, 15), Q per model (n, 15, 15)) over ``dt`` s (rounded to the
        nanosecond, so that frame intervals equal but for rounding share one entry), cached."""
        dt = round(dt, 9)
        hit = self._model_cache.get(dt)
        if hit is not None:
            return hit
        n = len(self.mu)
        T = np.ones((1, 1))
        if n > 1:
            stay = math.exp(-dt / self.switch_time)
            T = np.full((n, n), (1.0 - stay) / (n - 1))
            np.fill_diagonal(T, stay)
        mid = float(np.median(self.periods)) if self.periods.size else 1.0
        Fs, Qs = [], []
        for i in range(n):
            osc = i >= self.n_kinematic
            period = float(self.periods[i - self.n_kinematic]) if osc else mid
            F, Q = oscillator_transition(
                dt, period, self.zeta, osc, self.accel_sigma, self.drifts[i], self.q_white
            )
            Q[0:3, 0:3] += self.q_value * dt
            Fs.append(F.T)
            Qs.append(Q)
        Ft, Qm = np.ascontiguousarray(np.stack(Fs)), np.stack(Qs)
        for m in (T, Ft, Qm):
            m.setflags(write=False)
        if len(self._model_cache) >= 8:
            self._model_cache.clear()
        self._model_cache[dt] = (T, Ft, Qm)
        return T, Ft, Qm
