"""The deck-motion forecaster for one environment: the port of
:class:`ihrcf_env.core.forecast.DeckForecaster` (the model, frames and units are its own; see
``docs/forecast.md``).

Configuration is host-side (:func:`forecast_params`: Python values and numpy constants closed over
at trace time); the forecaster's state is a :class:`ForecastState` pytree (:func:`forecast_init`),
one sample is :func:`forecast_update` and the outputs are :func:`forecast_out`. Every branch of the
reference runs on every call and is selected with ``jnp.where``:

* the grid cells are a ring of ``cells`` slots (the reference's arrays), the current cell's
  accumulators beside them;
* closing a cell measures it, then takes the cells skipped (at most ``max_gap_cells``) as
  prediction steps of the companion model in a bounded loop, where the reference takes the bits
  of the step count; both give ``F^m P F^mT + sum_j F^j Q F^jT``;
* the refit is computed on every cell close and kept only on the reference's schedule (a cell
  index that is a multiple of the refit period) when the window holds enough samples: the
  Savitzky-Golay smoothing, the interpolation of gaps and the rows left out by the same rules;
  the ridge least squares by a Cholesky factorisation of the fixed-size normal equations (the
  reference solves the same equations by LU); the spectral radius of the AR model (the
  reference's ``eigvals``) by bisection on the Schur-Cohn stability test of the scaled
  polynomial; the stationary covariance by the reference's ten doublings of the Lyapunov sum.

Nothing here calls ``jnp.linalg``; the long loops (prediction steps, bisection, impulse response)
run under ``lax.scan`` or a bounded ``lax.while_loop``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.scipy.special import erf
from scipy.signal import savgol_filter

from ihrcf_env.core import forecast as ref
from ihrcf_env.core.forecast import ForecastOptions, forecast_options
from ihrcf_env.core.quiescence import QuiescenceThresholds

__all__ = [
    "ForecastOutput",
    "ForecastParams",
    "ForecastState",
    "forecast_init",
    "forecast_out",
    "forecast_params",
    "forecast_update",
]

_SENTINEL = -(1 << 30)  # cell id of an empty slot
_BISECTIONS = 64  # bisection steps of the spectral radius


@dataclass(frozen=True)
class ForecastParams:
    """Host-side constants of one forecaster configuration (:func:`forecast_params`)."""

    options: ForecastOptions
    dt: float
    cells: int
    order: int
    refit_cells: int
    max_gap_cells: int
    n_steps: int
    min_cells: int
    horizons: np.ndarray
    quiet_offsets: np.ndarray
    vertical_speed: float
    tilt_half: float
    noise_var: np.ndarray | None
    sg_edge: np.ndarray  # (7, 7) Savitzky-Golay map of a window-long signal (edges and centre row)
    lag_index: np.ndarray  # (cells - order, order) cell index of each lag of each row


class ForecastState(NamedTuple):
    """The forecaster's state (:class:`~ihrcf_env.core.forecast.DeckForecaster`'s attributes):
    the ring of closed cells (``sums``, ``counts``, ``offsets`` (cells, 3), their cell ``ids``),
    the current ``cell`` and its accumulators, the latest sample's time ``t_last`` and values
    ``last``, the Kalman state ``x`` (3, order) and ``P`` (3, order, order) about the window mean
    ``mu``, the fitted model (AR coefficients ``ar`` (3, order), process variance ``q``, noise of a
    cell ``r_cell`` with ``mean_count`` samples, stationary covariance ``P0``, impulse response
    rows ``G`` (3, n_steps, order) and the process variances ``pv``, ``pv_rate`` along them) and
    whether it is ``fitted``."""

    sums: Array
    counts: Array
    offsets: Array
    ids: Array
    cell: Array
    started: Array
    acc: Array
    acc_n: Array
    acc_dt: Array
    t_last: Array
    last: Array
    x: Array
    P: Array
    mu: Array
    ar: Array
    q: Array
    r_cell: Array
    mean_count: Array
    P0: Array
    G: Array
    pv: Array
    pv_rate: Array
    fitted: Array


class ForecastOutput(NamedTuple):
    """:func:`forecast_out`: ``mean`` and ``std`` (H, 4) of :data:`~ihrcf_env.core.forecast.OUTPUTS`
    (heave m, heave rate m/s, roll rad, pitch rad; before the first fit the latest values and the
    spread of the samples, as :meth:`~ihrcf_env.core.forecast.DeckForecaster.forecast`), the
    ``quiet`` probability (0 before the first fit) and ``valid`` (the model is fitted)."""

    mean: Array
    std: Array
    quiet: Array
    valid: Array


def forecast_params(
    options: ForecastOptions | dict[str, Any] | None = None,
    thresholds: QuiescenceThresholds | None = None,
) -> ForecastParams:
    """The constants of a forecaster with ``options`` (validated as the reference does) whose
    quiescence probability uses ``thresholds`` (model scale; default
    ``QuiescenceThresholds()``) at the options' ``quiet_lead``."""
    o = forecast_options(options)
    th = thresholds if thresholds is not None else QuiescenceThresholds()
    dt = o.sample_period
    p = o.order
    n = o.cells
    gap_cells = max(1, int(math.ceil(o.max_gap / dt)))
    n_bits = int(math.ceil(math.log2(gap_cells + 1)))
    horizons = np.asarray(o.horizons, dtype=np.float64)
    reach = max(float(horizons.max()), o.quiet_lead + 10.0 * dt)
    sg = savgol_filter(np.eye(ref._SG_LENGTH), ref._SG_LENGTH, ref._SG_ORDER, axis=0)
    k = np.arange(n - p)[:, None]
    i = np.arange(p)[None, :]
    return ForecastParams(
        options=o,
        dt=dt,
        cells=n,
        order=p,
        refit_cells=max(1, int(round(o.refit_period / dt))),
        max_gap_cells=(1 << n_bits) - 1,
        n_steps=int(math.ceil(reach / dt)) + 8,
        min_cells=max(4 * p, min(n, int(round(o.min_span / dt)))),
        horizons=horizons,
        quiet_offsets=o.quiet_lead + np.linspace(0.0, th.min_duration, ref.QUIET_POINTS),
        vertical_speed=float(th.vertical_speed),
        tilt_half=float(th.tilt) * math.sqrt(math.pi) / 2.0,
        noise_var=None if o.noise_std is None else np.asarray(o.noise_std, dtype=np.float64) ** 2,
        sg_edge=sg,
        lag_index=(p - 1 - i + k).astype(np.int64),
    )


def forecast_init(prm: ForecastParams, dtype: Any = None) -> ForecastState:
    """The state of a forecaster that has seen no sample (the reference's ``reset``)."""
    f = jnp.zeros((), dtype if dtype is not None else jnp.result_type(float)).dtype
    n, p, s = prm.cells, prm.order, prm.n_steps
    eye = jnp.broadcast_to(jnp.eye(p, dtype=f), (3, p, p))
    z3 = jnp.zeros(3, f)
    return ForecastState(
        sums=jnp.zeros((n, 3), f),
        counts=jnp.zeros((n, 3), f),
        offsets=jnp.zeros((n, 3), f),
        ids=jnp.full(n, _SENTINEL, jnp.int_),
        cell=jnp.asarray(_SENTINEL, jnp.int_),
        started=jnp.asarray(False),
        acc=z3,
        acc_n=z3,
        acc_dt=z3,
        t_last=jnp.asarray(-jnp.inf, f),
        last=z3,
        x=jnp.zeros((3, p), f),
        P=jnp.zeros((3, p, p), f),
        mu=z3,
        ar=jnp.zeros((3, p), f),
        q=z3,
        r_cell=jnp.ones(3, f),
        mean_count=jnp.ones(3, f),
        P0=eye,
        G=jnp.zeros((3, s, p), f),
        pv=jnp.zeros((3, s), f),
        pv_rate=jnp.zeros((3, s), f),
        fitted=jnp.asarray(False),
    )


def _cumsum(x: Array, axis: int) -> Array:
    """Cumulative sum by an associative scan (XLA's cumulative reductions are quadratic on CPU)."""
    return jax.lax.associative_scan(jnp.add, x, axis=axis)


def _cummax(x: Array, axis: int) -> Array:
    return jax.lax.associative_scan(jnp.maximum, x, axis=axis)


def _cummin_reverse(x: Array, axis: int) -> Array:
    return jax.lax.associative_scan(jnp.minimum, x, axis=axis, reverse=True)


def _where(c: Array, a: Any, b: Any) -> Any:
    """``a`` where the scalar ``c`` else ``b``, leaf by leaf."""
    return jax.tree.map(lambda u, v: jnp.where(c, u, v), a, b)


# -- the Kalman filter ----------------------------------------------------------------------------


def _measure(
    prm: ForecastParams, st: ForecastState, x: Array, P: Array, total: Array, n: Array, offset: Array
) -> tuple[Array, Array]:
    """Kalman update of the (3, p) state with the cell means (skipped where n == 0) at their mean
    time ``offset / n`` from the cell centre."""
    has = n > 0
    nn = jnp.maximum(n, 1.0)
    mean = total / nn
    r = st.r_cell * st.mean_count / nn
    lead = offset / nn / prm.dt
    h = jnp.zeros_like(x).at[:, 0].set(1.0 + lead).at[:, 1].set(-lead)
    ph = jnp.einsum("cij,cj->ci", P, h)
    s = jnp.sum(h * ph, axis=1) + r
    k = jnp.where(has[:, None], ph / s[:, None], 0.0)
    innov = jnp.where(has, mean - st.mu - jnp.sum(h * x, axis=1), 0.0)
    x = x + k * innov[:, None]
    P = P - k[:, :, None] * ph[:, None, :]
    return x, 0.5 * (P + jnp.swapaxes(P, 1, 2))


def _companion_x(a: Array, x: Array) -> Array:
    """``F x`` for the companion matrices of the AR coefficients ``a`` (3, p), ``x`` (3, p)."""
    return jnp.concatenate([jnp.sum(a * x, axis=1, keepdims=True), x[:, :-1]], axis=1)


def _companion_sandwich(a: Array, P: Array) -> Array:
    """``F P F^T`` (3, p, p) for the companion matrices of ``a``."""
    FP = jnp.concatenate([jnp.einsum("cj,cjk->ck", a, P)[:, None, :], P[:, :-1, :]], axis=1)
    return jnp.concatenate([jnp.einsum("cij,cj->ci", FP, a)[:, :, None], FP[:, :, :-1]], axis=2)


def _propagate(
    prm: ForecastParams, st: ForecastState, x: Array, P: Array, steps: Array
) -> tuple[Array, Array]:
    """``steps`` (0 .. max_gap_cells) prediction steps of the companion model. A bounded
    ``while_loop``: under ``vmap`` it runs the batch's largest count, the rows already done
    held by a mask."""

    def cond(carry: tuple[Array, Array, Array]) -> Array:
        return carry[0] < steps

    def body(carry: tuple[Array, Array, Array]) -> tuple[Array, Array, Array]:
        k, xc, Pc = carry
        xn = _companion_x(st.ar, xc)
        Pn = _companion_sandwich(st.ar, Pc).at[:, 0, 0].add(st.q)
        return k + 1, xn, Pn

    _, x, P = jax.lax.while_loop(cond, body, (jnp.zeros_like(steps), x, P))
    return x, P


# -- the fit --------------------------------------------------------------------------------------


def _savgol(prm: ForecastParams, z: Array) -> Array:
    """``savgol_filter(z, 7, 3, axis=0)`` (mode ``interp``) of (n, 3) cells."""
    S = jnp.asarray(prm.sg_edge, z.dtype)
    L = S.shape[0]
    half = L // 2
    n = z.shape[0]
    w = S[half]
    mid = sum(w[j] * z[j : n - L + 1 + j] for j in range(L))
    lo = S[:half] @ z[:L]
    hi = S[half + 1 :] @ z[n - L :]
    return jnp.concatenate([lo, mid, hi], axis=0)


def _interp(good: Array, vals: Array) -> Array:
    """Per channel, ``np.interp`` of the cells holding samples (values ``vals``) over all cells."""
    n = vals.shape[0]
    idx = jnp.broadcast_to(jnp.arange(n)[:, None], vals.shape)
    prev = _cummax(jnp.where(good, idx, -1), axis=0)
    nxt = _cummin_reverse(jnp.where(good, idx, n), axis=0)
    zp = jnp.take_along_axis(vals, jnp.clip(prev, 0, n - 1), axis=0)
    zn = jnp.take_along_axis(vals, jnp.clip(nxt, 0, n - 1), axis=0)
    inside = (prev >= 0) & (nxt < n)
    span = jnp.where(inside, nxt - prev, 1).astype(vals.dtype)
    slope = (zn - zp) / span
    mid = slope * (idx - prev).astype(vals.dtype) + zp
    out = jnp.where(inside, mid, jnp.where(prev < 0, zn, zp))
    return jnp.where(good, vals, out)


def _gradient(z: Array, dt: float) -> Array:
    """``np.gradient(z, dt, axis=0)`` (first-order edges)."""
    first = (z[1:2] - z[0:1]) / dt
    mid = (z[2:] - z[:-2]) / (2.0 * dt)
    last = (z[-1:] - z[-2:-1]) / dt
    return jnp.concatenate([first, mid, last], axis=0)


def _cholesky_solve(A: Array, b: Array) -> Array:
    """Solve ``A x = b`` for SPD ``A`` (3, p, p), ``b`` (3, p) by a Cholesky factorisation."""
    p = A.shape[-1]
    cols = jnp.arange(p)

    def factor(L: Array, j: Array) -> tuple[Array, None]:
        v = A[:, :, j] - jnp.einsum("cik,ck->ci", L, L[:, j, :])
        d = jnp.sqrt(jnp.maximum(jnp.take(v, j, axis=1), 1e-300))
        col = jnp.where(cols[None, :] >= j, v / d[:, None], 0.0)
        return L.at[:, :, j].set(col), None

    L, _ = jax.lax.scan(factor, jnp.zeros_like(A), cols)

    def forward(y: Array, i: Array) -> tuple[Array, None]:
        yi = (b[:, i] - jnp.sum(L[:, i, :] * y, axis=1)) / L[:, i, i]
        return y.at[:, i].set(yi), None

    y, _ = jax.lax.scan(forward, jnp.zeros_like(b), cols)

    def backward(xv: Array, i: Array) -> tuple[Array, None]:
        xi = (y[:, i] - jnp.sum(L[:, :, i] * xv, axis=1)) / L[:, i, i]
        return xv.at[:, i].set(xi), None

    xs, _ = jax.lax.scan(backward, jnp.zeros_like(b), cols[::-1])
    return xs


def _stable(a: Array, r: Array) -> Array:
    """Whether every root of ``z^p - a_1 z^(p-1) - ... - a_p`` (``a`` (3, p)) has a modulus
    below ``r`` (3,): the Schur-Cohn test (the step-down recursion of the scaled polynomial)."""
    p = a.shape[1]
    powers = jnp.cumprod(jnp.broadcast_to(r[:, None], a.shape), axis=1)
    c = -a / powers  # c_1 .. c_p of the monic polynomial in z / r
    ok = jnp.ones(a.shape[0], dtype=bool)
    idx = np.arange(p)
    for m in range(p, 1, -1):
        k = c[:, m - 1]
        ok = ok & (jnp.abs(k) < 1.0)
        k = jnp.where(ok, k, 0.0)
        rev = c[:, np.clip(m - 2 - idx, 0, p - 1)]
        c = jnp.where(idx < m - 1, (c - k[:, None] * rev) / (1.0 - k * k)[:, None], c)
    return ok & (jnp.abs(c[:, 0]) < 1.0)


def _spectral_radius(a: Array) -> Array:
    """Largest root modulus (3,) of the AR polynomials (the companion matrices' spectral radius)
    by bisection between 0 and Cauchy's bound ``1 + max |a|``."""
    hi = 1.0 + jnp.max(jnp.abs(a), axis=1)
    lo = jnp.zeros_like(hi)

    def body(carry: tuple[Array, Array], _: Any) -> tuple[tuple[Array, Array], None]:
        lo_c, hi_c = carry
        mid = 0.5 * (lo_c + hi_c)
        inside = _stable(a, mid)
        return (jnp.where(inside, lo_c, mid), jnp.where(inside, mid, hi_c)), None

    (lo, hi), _ = jax.lax.scan(body, (lo, hi), None, length=_BISECTIONS)
    return 0.5 * (lo + hi)


def _impulse(a: Array, steps: int) -> Array:
    """Rows ``e_0^T F^j`` (3, steps, p), j = 0 .. steps - 1, of the companion matrices of ``a``."""
    p = a.shape[1]
    g0 = jnp.zeros_like(a).at[:, 0].set(1.0)

    def body(g: Array, _: Any) -> tuple[Array, Array]:
        nxt = g[:, :1] * a + jnp.concatenate([g[:, 1:], jnp.zeros_like(g[:, :1])], axis=1)
        return nxt, g

    _, rows = jax.lax.scan(body, g0, None, length=steps)
    del p
    return jnp.swapaxes(rows, 0, 1)


def _stationary(a: Array, q: Array, p: int) -> Array:
    """``sum_{j < 1024} F^j Q F^jT`` (3, p, p), ``Q = q e_0 e_0^T``: the reference's ten doublings
    of the Lyapunov sum (straight-line products, no loop)."""
    F = jnp.zeros(a.shape + (p,), a.dtype).at[:, 0, :].set(a)
    F = F.at[:, jnp.arange(1, p), jnp.arange(p - 1)].set(1.0)
    P0 = jnp.zeros_like(F).at[:, 0, 0].set(q)
    Fk = F
    for _ in range(10):
        P0 = P0 + Fk @ P0 @ jnp.swapaxes(Fk, 1, 2)
        Fk = Fk @ Fk
    return P0


def _refit(prm: ForecastParams, st: ForecastState) -> tuple[ForecastState, Array]:
    """The reference's ``_refit`` at the current cell: the refitted state and whether the window
    allowed a fit."""
    n, p, dt = prm.cells, prm.order, prm.dt
    fdt = st.sums.dtype
    ids = st.cell - n + jnp.arange(n)
    slot = jnp.mod(ids, n)
    ok = st.ids[slot] == ids
    cnt = jnp.where(ok[:, None], st.counts[slot], 0.0)
    tot = jnp.where(ok[:, None], st.sums[slot], 0.0)
    lag = jnp.where(ok[:, None], st.offsets[slot], 0.0) / jnp.maximum(cnt, 1.0)
    good = cnt > 0
    any_good = jnp.any(good, axis=0)
    first = jnp.where(any_good, jnp.argmax(good, axis=0), n)
    span = n - first
    n_good = jnp.sum(good, axis=0)
    fits = ~(jnp.any(span < prm.min_cells) | jnp.any(n_good < ref._MIN_FILL * span))
    z = _interp(good, tot / jnp.maximum(cnt, 1.0))
    z = z - lag * _gradient(z, dt)
    cells = jnp.arange(n)[:, None]
    in_span = cells >= first[None, :]
    mu = jnp.sum(jnp.where(in_span, z, 0.0), axis=0) / jnp.maximum(n - first, 1)
    z = jnp.where(in_span, z - mu, 0.0)
    smooth = _savgol(prm, z)
    L = ref._SG_LENGTH
    c0 = float(prm.sg_edge[L // 2, L // 2])
    inner = good & (cells >= first[None, :] + L) & (cells < n - L)
    resid = jnp.where(inner, z - smooth, 0.0)
    r_cell = jnp.sum(resid**2, axis=0) / jnp.maximum(jnp.sum(inner, axis=0), 1) / max(1.0 - c0, 1e-3)
    mean_count = jnp.sum(cnt, axis=0) / jnp.maximum(n_good, 1)
    if prm.noise_var is not None:
        r_cell = jnp.asarray(prm.noise_var, fdt) / mean_count
    r_cell = jnp.maximum(r_cell, ref._NOISE_FLOOR)
    A = smooth[jnp.asarray(prm.lag_index)]  # (n - p, p, 3)
    target = smooth[p:]
    k = jnp.arange(n - p)[:, None]
    rows = k >= first[None, :] + L
    idx = jnp.broadcast_to(cells, (n, 3))
    prev = _cummax(jnp.where(good, idx, -1), axis=0)
    nxt = _cummin_reverse(jnp.where(good, idx, n), axis=0)
    hole = ~good & (nxt - prev - 1 > ref._MAX_BRIDGE)
    holes = jnp.concatenate([jnp.zeros((1, 3), jnp.int_), _cumsum(hole.astype(jnp.int_), axis=0)], axis=0)
    lo = np.clip(np.arange(n - p) - L, 0, n)
    hi = np.clip(np.arange(n - p) + p + 1 + L, 0, n)
    rows = rows & (holes[hi] - holes[lo] == 0)
    w = rows.astype(fdt)
    Am = A * w[:, None, :]
    b = target * w
    AtA = jnp.einsum("kic,kjc->cij", Am, Am)
    Atb = jnp.einsum("kic,kc->ci", Am, b)
    ridge = ref._RIDGE * jnp.trace(AtA, axis1=1, axis2=2) / p + 1e-30
    a = _cholesky_solve(AtA + ridge[:, None, None] * jnp.eye(p, dtype=fdt), Atb)
    radius = _spectral_radius(a)
    pull = (ref._MAX_RADIUS / jnp.maximum(radius, 1e-300))[:, None] ** jnp.arange(1, p + 1)[None, :]
    a = jnp.where((radius > ref._MAX_RADIUS)[:, None], a * pull, a)
    m = jnp.maximum(jnp.sum(rows, axis=0), 1)
    pred = jnp.einsum("kic,ci->kc", Am, a)
    resid_var = jnp.sum((b - pred) ** 2, axis=0) / m
    energy = jnp.sum(smooth**2, axis=0) / jnp.maximum(n - first, 1)
    q = jnp.maximum(jnp.maximum(resid_var, 1e-3 * energy), 1e-14)
    P0 = _stationary(a, q, p)
    G = _impulse(a, prm.n_steps)
    g = G[:, :, 0]
    pv = jnp.concatenate([jnp.zeros((3, 1), fdt), _cumsum(q[:, None] * g**2, axis=1)[:, :-1]], axis=1)

    def shift(j: int) -> Array:
        return jnp.concatenate([jnp.zeros((3, j), fdt), g[:, : g.shape[1] - j]], axis=1)

    coef = (-g + 8.0 * shift(1) - 8.0 * shift(3) + shift(4)) / (12.0 * dt)
    pv_rate = _cumsum(q[:, None] * coef**2, axis=1)
    x = jnp.where(st.fitted, st.x - (mu - st.mu)[:, None], smooth[::-1][:p].T)
    P_first = jnp.eye(p, dtype=fdt)[None] * (r_cell * mean_count)[:, None, None]
    P = jnp.where(st.fitted, st.P, P_first)
    new = st._replace(
        x=x,
        P=P,
        mu=mu,
        ar=a,
        q=q,
        r_cell=r_cell,
        mean_count=mean_count,
        P0=P0,
        G=G,
        pv=pv,
        pv_rate=pv_rate,
        fitted=jnp.asarray(True),
    )
    return new, fits


# -- one sample -----------------------------------------------------------------------------------


def _close(prm: ForecastParams, st: ForecastState, cell: Array) -> ForecastState:
    """Close the current cell (store and measure it), step the filter to ``cell`` and refit on
    the schedule."""
    slot = jnp.mod(st.cell, prm.cells)
    st = st._replace(
        sums=st.sums.at[slot].set(st.acc),
        counts=st.counts.at[slot].set(st.acc_n),
        offsets=st.offsets.at[slot].set(st.acc_dt),
        ids=st.ids.at[slot].set(st.cell),
    )
    x, P = _measure(prm, st, st.x, st.P, st.acc, st.acc_n, st.acc_dt)
    m = cell - st.cell
    x, P = _propagate(prm, st, x, P, jnp.minimum(m, prm.max_gap_cells))
    reset = m > prm.max_gap_cells
    x = jnp.where(reset, 0.0, x)
    P = jnp.where(reset, st.P0, P)
    x = jnp.where(st.fitted, x, st.x)
    P = jnp.where(st.fitted, P, st.P)
    zero = jnp.zeros_like(st.acc)
    st = st._replace(x=x, P=P, acc=zero, acc_n=zero, acc_dt=zero, cell=cell)
    refitted, fits = _refit(prm, st)
    due = (jnp.mod(cell, prm.refit_cells) == 0) & fits
    return _where(due, refitted, st)


def forecast_update(
    prm: ForecastParams, st: ForecastState, t: Array, sample: Array, valid: Array
) -> ForecastState:
    """Take one sample at time ``t`` (s): ``sample`` (heave m, roll rad, pitch rad) (3,); an
    invalid sample or a non-finite channel only advances the clock, a sample older than the
    current grid cell is ignored (the reference's ``update``)."""
    t = jnp.asarray(t)
    y = jnp.asarray(sample, st.acc.dtype)
    # the cell index of a true division (as the reference's): a constant divisor could be turned
    # into a multiplication by its reciprocal, which rounds differently at the cells' edges
    dt = jax.lax.optimization_barrier(jnp.asarray(prm.dt, t.dtype))
    cell = jnp.floor(t / dt).astype(jnp.int_)
    cur = jnp.where(st.started, st.cell, cell)
    st = st._replace(cell=cur, started=jnp.asarray(True))
    ignore = cell < cur
    st = _where(cell > cur, _close(prm, st, cell), st)
    mask = jnp.isfinite(y) & jnp.asarray(valid, bool) & ~ignore
    ym = jnp.where(mask, y, 0.0)
    centre = (cell.astype(st.acc.dtype) + 0.5) * prm.dt
    return st._replace(
        acc=st.acc + ym,
        acc_n=st.acc_n + mask,
        acc_dt=st.acc_dt + mask * (t - centre),
        last=jnp.where(mask, ym, st.last),
        t_last=jnp.where(ignore, st.t_last, jnp.maximum(st.t_last, t)),
    )


# -- outputs --------------------------------------------------------------------------------------


#: Added to the grid position in :func:`_predict` (grid steps).
_GRID_NUDGE = 1e-9


def _predict(prm: ForecastParams, st: ForecastState, offsets: np.ndarray) -> tuple[Array, Array]:
    """Mean and std (len, 4) of the outputs at ``offsets`` s after the latest sample."""
    x, P = _measure(prm, st, st.x, st.P, st.acc, st.acc_n, st.acc_dt)
    dt = prm.dt
    t_last = jnp.where(st.fitted, st.t_last, 0.0)
    t_center = (st.cell.astype(x.dtype) + 0.5) * dt
    j = jnp.clip((t_last + jnp.asarray(offsets, x.dtype) - t_center) / dt, 2.0, prm.n_steps - 4.0)
    # sample times and cell centres lie on a common grid, so the position often falls exactly on a
    # grid step, where XLA's CPU code (which may round the products differently in each fused
    # consumer) can floor it to either side; flooring a nudged position keeps every consumer on the
    # same side, and the weight (within rounding of 0 or 1 there) stays the unnudged one
    floor = jnp.floor(jnp.minimum(j + _GRID_NUDGE, prm.n_steps - 4.0))
    w = (j - floor)[:, None]
    j0 = floor.astype(jnp.int_)
    G = st.G

    def moments(rows: Array, proc: Array) -> tuple[Array, Array]:
        mean = jnp.einsum("ckp,cp->kc", rows, x)
        var = jnp.sum(jnp.einsum("ckp,cpq->ckq", rows, P) * rows, axis=2) + proc
        return mean, var.T

    out = []
    for k in (j0, j0 + 1):
        m, v = moments(G[:, k], st.pv[:, k])
        stencil = (G[:, k - 2] - 8.0 * G[:, k - 1] + 8.0 * G[:, k + 1] - G[:, k + 2]) / (12.0 * dt)
        r, rv = moments(stencil, st.pv_rate[:, k + 1])
        out.append((m + st.mu, v, r, rv))
    m, v, rm, rv = ((1.0 - w) * a + w * b for a, b in zip(out[0], out[1], strict=True))
    mean = jnp.stack([m[:, 0], rm[:, 0], m[:, 1], m[:, 2]], axis=1)
    var = jnp.stack([v[:, 0], rv[:, 0], v[:, 1], v[:, 2]], axis=1)
    return mean, jnp.sqrt(jnp.maximum(var, 0.0))


def _gauss_inside(mean: Array, std: Array, half: float) -> Array:
    s = jnp.maximum(std, 1e-12) * math.sqrt(2.0)
    return jnp.clip(0.5 * (erf((half - mean) / s) - erf((-half - mean) / s)), 0.0, 1.0)


def forecast_out(prm: ForecastParams, st: ForecastState) -> ForecastOutput:
    """The forecast at the options' horizons after the latest sample and the quiescence
    probability at ``quiet_lead`` (the reference's ``forecast`` and ``quiet_probability``)."""
    h = prm.horizons.size
    mean, std = _predict(prm, st, prm.horizons)
    qm, qs = _predict(prm, st, prm.quiet_offsets)
    prob = (
        _gauss_inside(qm[:, 1], qs[:, 1], prm.vertical_speed)
        * _gauss_inside(qm[:, 2], qs[:, 2], prm.tilt_half)
        * _gauss_inside(qm[:, 3], qs[:, 3], prm.tilt_half)
    )
    quiet = jnp.where(st.fitted, jnp.min(prob), 0.0)
    # before the first fit: the latest values and the spread of the cell means so far
    has = st.counts > 0
    k = jnp.sum(has, axis=0)
    cm_all = jnp.sum(st.sums, axis=0) / jnp.maximum(jnp.sum(st.counts, axis=0), 1.0)
    cm = st.sums / jnp.maximum(st.counts, 1.0)
    var = jnp.sum(jnp.where(has, (cm - cm_all) ** 2, 0.0), axis=0) / jnp.maximum(k - 1, 1)
    spread = jnp.where(k >= 2, jnp.sqrt(var), 1.0)
    mean0 = jnp.broadcast_to(jnp.stack([st.last[0], 0.0 * st.last[0], st.last[1], st.last[2]]), (h, 4))
    std0 = jnp.broadcast_to(jnp.stack([spread[0], spread[0] / prm.dt, spread[1], spread[2]]), (h, 4))
    return ForecastOutput(
        mean=jnp.where(st.fitted, mean, mean0),
        std=jnp.where(st.fitted, std, std0),
        quiet=quiet,
        valid=st.fitted,
    )
