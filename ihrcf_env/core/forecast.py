"""Online deck-motion forecast: heave, heave rate, roll and pitch seconds ahead (pure numpy).

**Input.** A stream of samples ``(t, [heave, roll, pitch], valid)`` at the camera rate (irregular
times, lost or invalid frames allowed): ``t`` in s, ``heave`` the deck height in m along the upward
vertical (any fixed reference: the forecaster removes the window mean), ``roll`` and ``pitch`` in rad,
the small rotations of the deck normal about the x and y axes of a **level, gravity-aligned frame of
fixed heading** (for example the drone's level frame, z up, x along its heading). The samples are
estimates (the fused filter's), never the truth: their noise is part of the model.

**Model.** Per channel, on a uniform grid of step ``sample_period``: the samples are averaged in
each grid cell; an autoregressive model AR(``order``) is fitted by least squares over the last
``window`` s of cells (Savitzky-Golay smoothed, so the fit is not dominated by the measurement
noise), every ``refit_period`` s; the AR model is the companion-form model of a Kalman filter
whose measurement noise is fitted from the same window (the scatter of the cells about their
smoothed values) and scaled by the number of samples in each cell. The forecast at a horizon is
the filter's prediction, its standard deviation that of the propagated covariance; the heave rate
is the central difference of the predicted heave. Lost cells are prediction-only steps (taken in
at most ``ceil(log2(max_gap_cells + 1))`` squaring steps, a fixed count); a gap longer than
``max_gap`` s resets the state to the stationary one.

**Quiescence.** :meth:`DeckForecaster.quiet_probability` is the probability that the window
``[now + lead, now + lead + min_duration]`` is quiet under
:class:`~ihrcf_env.core.quiescence.QuiescenceThresholds` (at the model's scale: use
``QuiescenceThresholds().scaled(length_scale)``): at ``QUIET_POINTS`` times of the window the
probabilities that ``|heave rate| < vertical_speed`` and that the tilt is below ``tilt`` (roll and
pitch each inside the square of the tilt disc's area, taken independent) are multiplied, and the
smallest over the window is returned (an upper bound of the joint probability, exact for a window
of one point). Far beyond the forecastable horizon it falls to the record's climatology.

**Port.** The state has a fixed size and the per-sample update a fixed iteration count (no loop
depends on the data); the refit, on a fixed schedule of grid cells, solves fixed-size least squares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import savgol_filter
from scipy.special import erf

from ihrcf_env.core.checks import check_int, check_real, check_reals, from_fields, set_field
from ihrcf_env.core.quiescence import QuiescenceThresholds

__all__ = [
    "CHANNELS",
    "OUTPUTS",
    "QUIET_POINTS",
    "DeckForecast",
    "DeckForecaster",
    "ForecastOptions",
    "forecast_options",
]

#: The input channels, in the order of a sample.
CHANNELS = ("heave", "roll", "pitch")
#: The forecast outputs, in the order of the columns of :attr:`DeckForecast.mean`.
OUTPUTS = ("heave", "heave_rate", "roll", "pitch")
#: Number of times of the quiescence window at which the probability is evaluated.
QUIET_POINTS = 5

_SG_LENGTH = 7  # Savitzky-Golay window (cells) and polynomial order of the fit's smoothing
_SG_ORDER = 3
_MIN_FILL = 0.5  # fraction of the cells since the first sample of the window holding samples
_MAX_BRIDGE = 5  # cells of missing samples bridged by interpolation in a fit
_MIN_SPAN = 10.0  # default s of samples before a fit (at most the window, at least 4 orders of cells)
_MAX_RADIUS = 0.999  # largest modulus of a pole of the fitted AR model
_NOISE_FLOOR = 1e-12
_RIDGE = 1e-4  # ridge of the least squares, relative to the mean energy of a lag


@dataclass(frozen=True)
class ForecastOptions:
    """Options of :class:`DeckForecaster`.

    ``horizons`` (s, each in [``sample_period``, ``window`` / 2]) of the forecast; ``window`` (s)
    of samples the model is fitted on; ``order`` of the autoregressive model (in
    [2, window / sample_period / 4]); ``sample_period`` (s) of the model's grid;
    ``refit_period`` (s, in [sample_period, window]) between fits; ``max_gap`` (s) of missing
    samples bridged by prediction before the state is reset; ``noise_std`` (heave m, roll rad,
    pitch rad) of one sample, or None to fit it from the window; ``quiet_lead`` (s) from now to
    the start of the quiescence window; ``min_span`` (s, in [``sample_period``, ``window``]) of
    samples before the first fit (at least four model orders of cells are needed in any case).
    """

    horizons: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0, 3.0)
    window: float = 40.0
    order: int = 24
    sample_period: float = 0.1
    refit_period: float = 1.0
    max_gap: float = 3.0
    noise_std: tuple[float, float, float] | None = None
    quiet_lead: float = 1.0
    min_span: float = _MIN_SPAN

    def __post_init__(self) -> None:
        name = "forecast"
        dt = check_real(f"{name}.sample_period", self.sample_period, "s", low=0.005, high=1.0)
        set_field(self, "sample_period", dt)
        w = check_real(f"{name}.window", self.window, "s", low=20 * dt, high=600.0)
        set_field(self, "window", w)
        cells = int(round(w / dt))
        set_field(self, "order", check_int(f"{name}.order", self.order, low=2, high=max(2, cells // 4)))
        h = self.horizons
        if isinstance(h, str) or not isinstance(h, tuple | list | np.ndarray) or len(h) == 0 or len(h) > 32:
            raise TypeError(f"{name}.horizons must be 1 to 32 real numbers (s), got {h!r}")
        hs = check_reals(f"{name}.horizons", h, len(h), "s", low=dt, high=w / 2)
        set_field(self, "horizons", hs)
        rp = check_real(f"{name}.refit_period", self.refit_period, "s", low=dt, high=w)
        set_field(self, "refit_period", rp)
        set_field(self, "max_gap", check_real(f"{name}.max_gap", self.max_gap, "s", low=dt, high=w))
        if self.noise_std is not None:
            ns = check_reals(f"{name}.noise_std", self.noise_std, 3, "m, rad, rad", low=0.0, high=1.0)
            set_field(self, "noise_std", ns)
        lead = check_real(f"{name}.quiet_lead", self.quiet_lead, "s", low=0.0, high=w / 2)
        set_field(self, "quiet_lead", lead)
        set_field(self, "min_span", check_real(f"{name}.min_span", self.min_span, "s", low=dt, high=w))

    @property
    def cells(self) -> int:
        """Grid cells in the window."""
        return int(round(self.window / self.sample_period))


@dataclass(frozen=True)
class DeckForecast:
    """A forecast: ``horizons`` (H,) s; ``mean`` and ``std`` (H, 4) of :data:`OUTPUTS` (heave m,
    heave rate m/s, roll rad, pitch rad); ``ready`` False until the first fit (then the mean is
    the latest value and the std the spread of the samples so far)."""

    horizons: NDArray[np.float64]
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    ready: bool


def _gauss_inside(mean: NDArray[np.float64], std: NDArray[np.float64], half: float) -> NDArray[np.float64]:
    """P(|X| < half) for X ~ N(mean, std^2)."""
    s = np.maximum(std, 1e-12) * math.sqrt(2.0)
    return np.clip(0.5 * (erf((half - mean) / s) - erf((-half - mean) / s)), 0.0, 1.0)


class DeckForecaster:
    """The online forecaster (see the module docstring). Feed :meth:`update` each sample in time
    order; read :meth:`forecast` and :meth:`quiet_probability` at any time."""

    def __init__(self, options: ForecastOptions | Mapping[str, Any] | None = None) -> None:
        self.options = forecast_options(options)
        o = self.options
        self.dt = o.sample_period
        self.n_cells = o.cells
        self.p = o.order
        self.refit_cells = max(1, int(round(o.refit_period / o.sample_period)))
        gap_cells = max(1, int(math.ceil(o.max_gap / o.sample_period)))
        self.n_bits = int(math.ceil(math.log2(gap_cells + 1)))
        self.max_gap_cells = (1 << self.n_bits) - 1
        self.horizons = np.asarray(o.horizons, dtype=np.float64)
        reach = max(float(self.horizons.max()), o.quiet_lead + 10.0 * self.dt)
        self.n_steps = int(math.ceil(reach / self.dt)) + 8
        self.reset()

    def reset(self) -> None:
        """Forget every sample and the fitted model."""
        p, n = self.p, self.n_cells
        self.sums = np.zeros((n, 3))
        self.counts = np.zeros((n, 3))
        self.offsets = np.zeros((n, 3))  # sums of (sample time - cell centre), s
        self.ids = np.full(n, -(1 << 40), dtype=np.int64)
        self.cell = -(1 << 40)  # current grid cell
        self.started = False
        self.acc = np.zeros(3)
        self.acc_n = np.zeros(3)
        self.acc_dt = np.zeros(3)
        self.t_last = -math.inf
        self.last = np.zeros(3)
        self.seen = np.zeros(3)
        self.x = np.zeros((3, p))
        self.P = np.zeros((3, p, p))
        self.mu = np.zeros(3)
        self.q = np.zeros(3)
        self.r_cell = np.ones(3)  # noise variance of a cell holding mean_count samples
        self.mean_count = np.ones(3)
        self.F = np.tile(np.eye(p), (3, 1, 1))
        self.P0 = np.tile(np.eye(p), (3, 1, 1))
        self.pow_F = np.tile(np.eye(p), (3, self.n_bits, 1, 1))
        self.pow_Q = np.zeros((3, self.n_bits, p, p))
        self.G = np.zeros((3, self.n_steps, p))
        self.pv = np.zeros((3, self.n_steps))
        self.pv_rate = np.zeros((3, self.n_steps))
        self.moments = (np.zeros(3), np.zeros(3))  # the fit's m0 (variance) and m2 (rate variance)
        self.fitted = False

    # -- per sample -------------------------------------------------------------------------

    def update(self, t: float, sample: ArrayLike, valid: bool = True) -> None:
        """Take one sample at time ``t`` (s): ``sample`` (heave m, roll rad, pitch rad); an
        invalid sample, a non-finite channel or a sample older than the current grid cell only
        advances the clock."""
        tt = check_real("t", t, "s")
        y = np.asarray(sample, dtype=np.float64).reshape(-1)
        if y.shape != (3,):
            raise ValueError(f"sample must be (heave, roll, pitch), got shape {y.shape}")
        cell = int(math.floor(tt / self.dt))
        if not self.started:
            self.cell, self.started = cell, True
        if cell < self.cell:  # older than the current cell: ignored
            return
        if cell > self.cell:
            self._close(cell)
        mask = np.isfinite(y) & bool(valid)
        ym = np.where(mask, y, 0.0)
        self.acc += ym
        self.acc_n += mask
        self.acc_dt += mask * (tt - (cell + 0.5) * self.dt)
        self.last = np.where(mask, ym, self.last)
        self.seen += mask
        self.t_last = max(self.t_last, tt)

    def _measure(
        self,
        x: NDArray[np.float64],
        P: NDArray[np.float64],
        total: NDArray[np.float64],
        n: NDArray[np.float64],
        offset: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Kalman update of the (3, p) state with the cell means (skipped where n == 0), taken at
        their samples' mean time ``offset / n`` from the cell centre (to first order, with the
        rate of the state's last two cells)."""
        has = n > 0
        nn = np.maximum(n, 1.0)
        mean = total / nn
        r = self.r_cell * self.mean_count / nn
        lead = offset / nn / self.dt
        h = np.zeros_like(x)
        h[:, 0], h[:, 1] = 1.0 + lead, -lead
        ph = np.einsum("cij,cj->ci", P, h)
        s = np.sum(h * ph, axis=1) + r
        k = np.where(has[:, None], ph / s[:, None], 0.0)
        innov = np.where(has, mean - self.mu - np.sum(h * x, axis=1), 0.0)
        x = x + k * innov[:, None]
        P = P - k[:, :, None] * ph[:, None, :]
        return x, 0.5 * (P + np.swapaxes(P, 1, 2))

    def _close(self, cell: int) -> None:
        """Close the current cell (store it, measure it) and step the filter to ``cell``."""
        slot = self.cell % self.n_cells
        self.sums[slot], self.counts[slot], self.ids[slot] = self.acc, self.acc_n, self.cell
        self.offsets[slot] = self.acc_dt
        if self.fitted:
            self.x, self.P = self._measure(self.x, self.P, self.acc, self.acc_n, self.acc_dt)
            m = cell - self.cell
            steps = min(m, self.max_gap_cells)
            for b in range(self.n_bits):  # fixed count: the bits of the step count
                if (steps >> b) & 1:
                    Fb = self.pow_F[:, b]
                    self.x = np.einsum("cij,cj->ci", Fb, self.x)
                    self.P = Fb @ self.P @ np.swapaxes(Fb, 1, 2) + self.pow_Q[:, b]
            if m > self.max_gap_cells:
                self.x, self.P = np.zeros_like(self.x), self.P0.copy()
        self.acc, self.acc_n, self.acc_dt = np.zeros(3), np.zeros(3), np.zeros(3)
        self.cell = cell
        if cell % self.refit_cells == 0:
            self._refit()

    # -- fit (fixed schedule) -----------------------------------------------------------------

    def _window(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64], NDArray[np.int64]] | None:
        """The window's cell means (n, 3), gaps filled linearly; which cells hold samples; counts;
        the first cell holding a sample per channel (the window's span starts there)."""
        n = self.n_cells
        ids = self.cell - n + np.arange(n)
        slot = ids % n
        ok = self.ids[slot] == ids
        cnt = np.where(ok[:, None], self.counts[slot], 0.0)
        tot = np.where(ok[:, None], self.sums[slot], 0.0)
        lag = np.where(ok[:, None], self.offsets[slot], 0.0) / np.maximum(cnt, 1.0)
        good = cnt > 0
        first = np.where(good.any(axis=0), np.argmax(good, axis=0), n)
        span = n - first
        min_cells = max(4 * self.p, min(n, int(round(self.options.min_span / self.dt))))
        if np.any(span < min_cells) or np.any(good.sum(axis=0) < _MIN_FILL * span):
            return None
        z = np.empty((n, 3))
        grid = np.arange(n, dtype=np.float64)
        for c in range(3):
            g = good[:, c]
            z[:, c] = np.interp(grid, grid[g], tot[g, c] / cnt[g, c])
        z = z - lag * np.gradient(z, self.dt, axis=0)  # each mean moved to its cell's centre
        return z, good, cnt, first

    def _refit(self) -> None:
        w = self._window()
        if w is None:
            return
        z, good, cnt, first = w
        p, n = self.p, z.shape[0]
        cells = np.arange(n)[:, None]
        span = cells >= first[None, :]  # (n, 3) cells since the first sample
        mu = np.sum(np.where(span, z, 0.0), axis=0) / (n - first)
        z = np.where(span, z - mu, 0.0)
        smooth = savgol_filter(z, _SG_LENGTH, _SG_ORDER, axis=0)
        inside = span[1:] & span[:-1] & (cells[1:] >= first[None, :] + _SG_LENGTH)  # (n - 1, 3)
        m = np.maximum(inside.sum(axis=0), 1)
        moments = (
            np.sum(np.where(inside, smooth[1:] ** 2, 0.0), axis=0) / m,
            np.sum(np.where(inside, np.diff(smooth, axis=0) ** 2, 0.0), axis=0) / m / (self.dt * self.dt),
        )
        # noise of one cell: the scatter about the smoothed values of the cells holding samples
        c0 = savgol_filter(np.eye(_SG_LENGTH)[_SG_LENGTH // 2], _SG_LENGTH, _SG_ORDER)[_SG_LENGTH // 2]
        inner = good & (cells >= first[None, :] + _SG_LENGTH) & (cells < n - _SG_LENGTH)
        resid = np.where(inner, z - smooth, 0.0)
        r_cell = np.sum(resid**2, axis=0) / np.maximum(inner.sum(axis=0), 1) / max(1.0 - c0, 1e-3)
        mean_count = cnt.sum(axis=0) / np.maximum(good.sum(axis=0), 1)
        if self.options.noise_std is not None:
            r_cell = np.asarray(self.options.noise_std) ** 2 / mean_count
        r_cell = np.maximum(r_cell, _NOISE_FLOOR)
        lag = np.stack([smooth[p - 1 - i : n - 1 - i] for i in range(p)], axis=1)  # (n - p, p, 3)
        target = smooth[p:]
        rows = np.arange(n - p)[:, None] >= first[None, :] + _SG_LENGTH  # (n - p, 3) lags in the span
        # rows reaching into a long gap (more than _MAX_BRIDGE cells without samples) are left out
        idx = np.broadcast_to(cells, (n, 3))
        prev = np.maximum.accumulate(np.where(good, idx, -1), axis=0)
        nxt = np.minimum.accumulate(np.where(good, idx, n)[::-1], axis=0)[::-1]
        hole = ~good & (nxt - prev - 1 > _MAX_BRIDGE)
        holes = np.concatenate([np.zeros((1, 3)), np.cumsum(hole, axis=0)])  # (n + 1, 3)
        lo = np.clip(np.arange(n - p) - _SG_LENGTH, 0, n)
        hi = np.clip(np.arange(n - p) + p + 1 + _SG_LENGTH, 0, n)
        rows &= holes[hi] - holes[lo] == 0
        F = np.zeros((3, p, p))
        F[:, 1:, :-1] = np.eye(p - 1)
        q = np.zeros(3)
        for c in range(3):
            A = lag[:, :, c] * rows[:, c, None]
            b = target[:, c] * rows[:, c]
            AtA = A.T @ A
            ridge = _RIDGE * np.trace(AtA) / p + 1e-30
            a = np.linalg.solve(AtA + ridge * np.eye(p), A.T @ b)
            F[c, 0] = a
            radius = float(np.max(np.abs(np.linalg.eigvals(F[c]))))
            if radius > _MAX_RADIUS:
                F[c, 0] = a * (_MAX_RADIUS / radius) ** np.arange(1, p + 1)
            m = max(int(rows[:, c].sum()), 1)
            resid_var = float(np.sum((b - A @ F[c, 0]) ** 2)) / m
            energy = float(np.sum(smooth[:, c] ** 2)) / max(n - int(first[c]), 1)
            q[c] = max(resid_var, 1e-3 * energy, 1e-14)
        Q = np.zeros((3, p, p))
        Q[:, 0, 0] = q
        # stationary covariance (a fixed number of doublings of the Lyapunov sum)
        P0, Fk = Q.copy(), F.copy()
        for _ in range(10):
            P0 = P0 + Fk @ P0 @ np.swapaxes(Fk, 1, 2)
            Fk = Fk @ Fk
        pow_F = np.empty((3, self.n_bits, p, p))
        pow_Q = np.empty((3, self.n_bits, p, p))
        Fb, Qb = F.copy(), Q.copy()
        for b in range(self.n_bits):
            pow_F[:, b], pow_Q[:, b] = Fb, Qb
            Qb = Qb + Fb @ Qb @ np.swapaxes(Fb, 1, 2)
            Fb = Fb @ Fb
        G = np.zeros((3, self.n_steps, p))
        G[:, 0, 0] = 1.0
        for j in range(1, self.n_steps):
            G[:, j] = np.einsum("ci,cij->cj", G[:, j - 1], F)
        g = G[:, :, 0]  # impulse response
        self.pv = np.concatenate([np.zeros((3, 1)), np.cumsum(q[:, None] * g**2, axis=1)[:, :-1]], axis=1)

        # rate: the five-point central difference (1, -8, 8, -1) / (12 dt) at steps j - 2 .. j + 2;
        # its process part weighs the impulse response by the stencil shifted along it
        def shift(k: int) -> NDArray[np.float64]:
            return np.concatenate([np.zeros((3, k)), g[:, : g.shape[1] - k]], axis=1)

        coef = (-g + 8.0 * shift(1) - 8.0 * shift(3) + shift(4)) / (12.0 * self.dt)
        self.pv_rate = np.cumsum(q[:, None] * coef**2, axis=1)
        if self.fitted:
            self.x = self.x - (mu - self.mu)[:, None]
        else:
            self.x = np.ascontiguousarray(smooth[::-1][:p].T)
            self.P = np.tile(np.eye(p), (3, 1, 1)) * (r_cell * mean_count)[:, None, None]
        self.mu, self.F, self.q, self.P0 = mu, F, q, P0
        self.moments = moments
        self.r_cell, self.mean_count = r_cell, mean_count
        self.pow_F, self.pow_Q, self.G = pow_F, pow_Q, G
        self.fitted = True

    # -- outputs ------------------------------------------------------------------------------

    def _predict(self, offsets: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Mean and std (len, 4) of :data:`OUTPUTS` at ``offsets`` s after the latest sample."""
        x, P = self._measure(self.x, self.P, self.acc, self.acc_n, self.acc_dt)
        t_center = (self.cell + 0.5) * self.dt
        j = np.clip((self.t_last + offsets - t_center) / self.dt, 2.0, self.n_steps - 4.0)
        j0 = np.floor(j).astype(np.int64)
        w = (j - j0)[:, None]
        G = self.G

        def moments(rows: NDArray[np.float64], proc: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
            mean = (rows @ x[:, :, None])[:, :, 0].T
            return mean, (np.sum((rows @ P) * rows, axis=2) + proc).T

        out = []
        for k in (j0, j0 + 1):  # the two grid steps around each offset
            m, v = moments(G[:, k], self.pv[:, k])
            stencil = (G[:, k - 2] - 8.0 * G[:, k - 1] + 8.0 * G[:, k + 1] - G[:, k + 2]) / (12.0 * self.dt)
            r, rv = moments(stencil, self.pv_rate[:, k + 1])
            out.append((m + self.mu, v, r, rv))
        m, v, rm, rv = ((1.0 - w) * a + w * b for a, b in zip(out[0], out[1], strict=True))
        mean = np.column_stack([m[:, 0], rm[:, 0], m[:, 1], m[:, 2]])
        var = np.column_stack([v[:, 0], rv[:, 0], v[:, 1], v[:, 2]])
        return mean, np.sqrt(np.maximum(var, 0.0))

    def forecast(self) -> DeckForecast:
        """The forecast at :attr:`ForecastOptions.horizons` after the latest sample."""
        h = self.horizons
        if self.fitted:
            mean, std = self._predict(h)
            return DeckForecast(h.copy(), mean, std, True)
        spread = self._spread()
        mean = np.tile([self.last[0], 0.0, self.last[1], self.last[2]], (h.size, 1))
        std = np.tile([spread[0], spread[0] / self.dt, spread[1], spread[2]], (h.size, 1))
        return DeckForecast(h.copy(), mean, std, False)

    def _spread(self) -> NDArray[np.float64]:
        """Standard deviation of the cell means so far (1 where fewer than two cells)."""
        n = self.counts > 0
        k = n.sum(axis=0)
        mean = self.sums.sum(axis=0) / np.maximum(self.counts.sum(axis=0), 1.0)
        cm = self.sums / np.maximum(self.counts, 1.0)
        var = np.sum(np.where(n, (cm - mean) ** 2, 0.0), axis=0) / np.maximum(k - 1, 1)
        return np.where(k >= 2, np.sqrt(var), 1.0)

    def quiet_probability(self, thresholds: QuiescenceThresholds, lead: float | None = None) -> float:
        """Probability (0-1) that ``[now + lead, now + lead + min_duration]`` is quiet under
        ``thresholds`` (model scale); ``lead`` (s) defaults to :attr:`ForecastOptions.quiet_lead`.
        0 before the first fit."""
        if not self.fitted:
            return 0.0
        ld = self.options.quiet_lead if lead is None else check_real("lead", lead, "s", low=0.0, high=60.0)
        offsets = ld + np.linspace(0.0, thresholds.min_duration, QUIET_POINTS)
        mean, std = self._predict(offsets)
        half = thresholds.tilt * math.sqrt(math.pi) / 2.0  # square of the tilt disc's area
        prob = (
            _gauss_inside(mean[:, 1], std[:, 1], thresholds.vertical_speed)
            * _gauss_inside(mean[:, 2], std[:, 2], half)
            * _gauss_inside(mean[:, 3], std[:, 3], half)
        )
        return float(np.min(prob))

    def oscillation(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The deck's oscillation per channel (heave, roll, pitch) over the last fit's window: the
        mean zero-crossing period (s), ``2 pi sqrt(m0 / m2)`` from the variance of the smoothed
        cells about the window mean (``m0``) and that of their first difference per second
        (``m2``), and the standard deviation ``sqrt(m0)`` (m, rad, rad); NaN before the first fit."""
        if not self.fitted:
            return np.full(3, np.nan), np.full(3, np.nan)
        m0, m2 = self.moments
        return 2.0 * np.pi * np.sqrt(m0 / np.maximum(m2, 1e-30)), np.sqrt(m0)

    def state_dict(self) -> dict[str, Any]:
        """The fitted model's coefficients per channel (for inspection)."""
        return {"ar": self.F[:, 0].copy(), "process_var": self.q.copy(), "noise_var_cell": self.r_cell.copy()}


def forecast_options(value: ForecastOptions | Mapping[str, Any] | None) -> ForecastOptions:
    """A :class:`ForecastOptions` from itself, a dict of its fields or None (the defaults)."""
    return from_fields("forecast", ForecastOptions, value if value is not None else {})
