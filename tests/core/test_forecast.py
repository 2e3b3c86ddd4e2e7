"""The online deck-motion forecaster: exact models, gaps, options, quiescence, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.forecast import (
    OUTPUTS,
    DeckForecaster,
    ForecastOptions,
    forecast_options,
)
from ihrcf_env.core.quiescence import QuiescenceThresholds


def feed(fc: DeckForecaster, t: np.ndarray, y: np.ndarray, valid: np.ndarray | None = None) -> None:
    for k in range(t.size):
        fc.update(float(t[k]), y[k], True if valid is None else bool(valid[k]))


def sines(t: np.ndarray, parts: list[tuple[float, float, float]]) -> np.ndarray:
    """(n, 3) heave, roll, pitch: each a sum of amplitude * sin(omega t + phase + channel)."""
    out = np.zeros((t.size, 3))
    for c in range(3):
        for amp, omega, phase in parts:
            out[:, c] += amp * (1.0 + 0.5 * c) * np.sin(omega * t + phase + c)
    return out


def truth_rate(t: np.ndarray, parts: list[tuple[float, float, float]]) -> np.ndarray:
    return sum(amp * omega * np.cos(omega * t + phase) for amp, omega, phase in parts)  # type: ignore[return-value]


@pytest.mark.parametrize(
    "parts",
    [[(0.02, 5.0, 0.3)], [(0.02, 4.2, 0.3), (0.012, 6.5, 1.1)]],
    ids=["one sine", "two sines"],
)
def test_sinusoids_forecast_converges_to_the_truth(parts: list[tuple[float, float, float]]) -> None:
    t = np.arange(0.0, 40.0, 1 / 30)
    fc = DeckForecaster()
    feed(fc, t, sines(t, parts))
    f = fc.forecast()
    assert f.ready
    tt = t[-1] + f.horizons
    truth = sines(tt, parts)
    amp = sum(a for a, _, _ in parts)
    np.testing.assert_allclose(f.mean[:, 0], truth[:, 0], atol=0.08 * amp)
    np.testing.assert_allclose(f.mean[:, 2], truth[:, 1], atol=0.08 * 1.5 * amp)
    np.testing.assert_allclose(f.mean[:, 3], truth[:, 2], atol=0.08 * 2.0 * amp)
    rate_amp = sum(a * w for a, w, _ in parts)
    np.testing.assert_allclose(f.mean[:, 1], truth_rate(tt, parts), atol=0.08 * rate_amp)
    assert np.all(f.std >= 0) and np.all(np.isfinite(f.std))


def test_ar_process_coefficients_recovered() -> None:
    """An AR(2) resonance sampled once per grid cell: the fitted AR(2) is the true one."""
    rng = np.random.default_rng(3)
    a1, a2 = 2 * 0.97 * math.cos(0.5), -(0.97**2)
    n = 3000
    x = np.zeros(n)
    for k in range(2, n):
        x[k] = a1 * x[k - 1] + a2 * x[k - 2] + rng.normal(0.0, 1e-3)
    t = (np.arange(n) + 0.5) * 0.1
    y = np.column_stack([x, 0.5 * x, -x])
    fc = DeckForecaster(ForecastOptions(order=2, window=200.0, horizons=(0.5, 1.0)))
    feed(fc, t, y)
    # the smoothing of the fit is tuned for oversampled motion: compare the resonance instead
    ar = fc.state_dict()["ar"]
    for c in range(3):
        poles = np.roots([1.0, -ar[c, 0], -ar[c, 1]])
        assert np.max(np.abs(np.angle(poles))) == pytest.approx(0.5, abs=0.05)
        assert np.max(np.abs(poles)) == pytest.approx(0.97, abs=0.03)


def test_invalid_and_missing_samples_are_skipped() -> None:
    parts = [(0.02, 5.0, 0.3)]
    t = np.arange(0.0, 40.0, 1 / 30)
    y = sines(t, parts)
    rng = np.random.default_rng(1)
    valid = rng.uniform(size=t.size) > 0.3
    valid[600:640] = False  # a burst of lost frames
    y_bad = y.copy()
    y_bad[~valid] = 1e3  # garbage in the invalid frames
    y_bad[5, 1] = np.nan  # a non-finite channel
    fc = DeckForecaster()
    feed(fc, t, y_bad, valid)
    f = fc.forecast()
    truth = sines(t[-1] + f.horizons, parts)
    np.testing.assert_allclose(f.mean[:, 0], truth[:, 0], atol=0.12 * 0.02)
    assert np.isfinite(f.mean).all() and np.isfinite(f.std).all()


def test_a_long_gap_resets_and_recovers() -> None:
    parts = [(0.02, 5.0, 0.3)]
    t = np.concatenate([np.arange(0.0, 30.0, 1 / 30), np.arange(40.0, 60.0, 1 / 30)])
    fc = DeckForecaster()
    feed(fc, t, sines(t, parts))
    f = fc.forecast()
    assert np.isfinite(f.mean).all()
    np.testing.assert_allclose(f.mean[:, 0], sines(t[-1] + f.horizons, parts)[:, 0], atol=0.1 * 0.02)


def test_not_ready_before_the_first_fit() -> None:
    fc = DeckForecaster()
    f = fc.forecast()
    assert not f.ready and np.isfinite(f.mean).all() and np.all(f.std > 0)
    fc.update(0.0, [0.01, 0.0, 0.0])
    fc.update(0.05, [0.01, 0.0, 0.0])
    f = fc.forecast()
    assert not f.ready and f.mean[0, 0] == pytest.approx(0.01)
    assert fc.quiet_probability(QuiescenceThresholds()) == 0.0
    assert f.mean.shape == (5, len(OUTPUTS))


def test_a_shorter_min_span_fits_sooner() -> None:
    """The first fit waits for ``min_span`` s of samples (and four model orders of cells)."""
    parts = [(0.02, 5.0, 0.3)]
    t = np.arange(0.0, 12.0, 1.0 / 30.0)
    y = sines(t, parts)

    def first_ready(fc: DeckForecaster) -> float:
        for k in range(t.size):
            fc.update(float(t[k]), y[k])
            if fc.forecast().ready:
                return float(t[k])
        return math.inf

    default = first_ready(DeckForecaster())
    short = first_ready(DeckForecaster(ForecastOptions(order=12, min_span=5.0)))
    assert 9.5 <= default <= 11.5 and 4.5 <= short <= 6.5


def test_forecast_beats_persistence_on_noisy_sines() -> None:
    parts = [(0.02, 4.2, 0.3), (0.012, 6.5, 1.1)]
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 50.0, 1 / 30)
    y = sines(t, parts) + rng.normal(0.0, [0.005, 0.005, 0.005], (t.size, 3))
    fc = DeckForecaster()
    err, per = [], []
    for k in range(t.size):
        fc.update(float(t[k]), y[k])
        if t[k] > 25.0 and k % 10 == 0:
            f = fc.forecast()
            tr = sines(t[k] + f.horizons, parts)[:, 0]
            err.append(f.mean[:, 0] - tr)
            per.append(y[k, 0] - tr)
    ratio = np.sqrt(np.mean(np.square(err), 0)) / np.sqrt(np.mean(np.square(per), 0))
    assert np.all(ratio < 0.4), ratio


def test_quiet_probability_flat_and_rough() -> None:
    th = QuiescenceThresholds().scaled(30.0)
    t = np.arange(0.0, 30.0, 1 / 30)
    rng = np.random.default_rng(2)
    flat = DeckForecaster()
    feed(flat, t, rng.normal(0.0, [5e-4, 2e-4, 2e-4], (t.size, 3)))
    rough = DeckForecaster()
    feed(rough, t, sines(t, [(0.03, 5.0, 0.0)]) + rng.normal(0.0, 1e-3, (t.size, 3)))
    p_flat = flat.quiet_probability(th)
    p_rough = rough.quiet_probability(th)
    assert 0.0 <= p_rough <= p_flat <= 1.0
    assert p_flat > 0.9 and p_rough < 0.05
    assert 0.0 <= rough.quiet_probability(th, lead=0.0) <= 1.0
    with pytest.raises(ValueError, match="lead"):
        rough.quiet_probability(th, lead=-1.0)


def test_deterministic() -> None:
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0.0, 30.0, 900))
    y = sines(t, [(0.02, 5.0, 0.3)]) + rng.normal(0.0, 0.002, (t.size, 3))
    out = []
    for _ in range(2):
        fc = DeckForecaster()
        feed(fc, t, y)
        f = fc.forecast()
        out.append((f.mean, f.std, fc.quiet_probability(QuiescenceThresholds().scaled(30.0))))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])
    assert out[0][2] == out[1][2]
    fc.reset()
    assert not fc.forecast().ready


def test_old_samples_ignored_and_bad_input_refused() -> None:
    fc = DeckForecaster()
    fc.update(1.0, [0.0, 0.0, 0.0])
    fc.update(0.5, [9.0, 9.0, 9.0])  # older than the current cell: ignored
    assert fc.forecast().mean[0, 0] == 0.0
    with pytest.raises(ValueError, match="sample"):
        fc.update(1.1, [0.0, 0.0])
    with pytest.raises(ValueError, match="t "):
        fc.update(math.nan, [0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    ("fields", "name"),
    [
        ({"horizons": ()}, "forecast.horizons"),
        ({"horizons": (0.25, 50.0)}, r"forecast.horizons\[1\]"),
        ({"horizons": (0.01,)}, r"forecast.horizons\[0\]"),
        ({"horizons": "1.0"}, "forecast.horizons"),
        ({"window": 0.5}, "forecast.window"),
        ({"window": math.inf}, "forecast.window"),
        ({"order": 1}, "forecast.order"),
        ({"order": 1000}, "forecast.order"),
        ({"order": 12.0}, "forecast.order"),
        ({"sample_period": 0.0}, "forecast.sample_period"),
        ({"sample_period": True}, "forecast.sample_period"),
        ({"refit_period": 0.01}, "forecast.refit_period"),
        ({"refit_period": 100.0}, "forecast.refit_period"),
        ({"max_gap": -1.0}, "forecast.max_gap"),
        ({"noise_std": (0.01, 0.01)}, "forecast.noise_std"),
        ({"noise_std": (0.01, -0.01, 0.0)}, r"forecast.noise_std\[1\]"),
        ({"quiet_lead": -0.1}, "forecast.quiet_lead"),
        ({"min_span": 0.0}, "forecast.min_span"),
        ({"min_span": 100.0}, "forecast.min_span"),
    ],
)
def test_options_refused_by_name(fields: dict[str, object], name: str) -> None:
    with pytest.raises((TypeError, ValueError), match=name):
        ForecastOptions(**fields)  # type: ignore[arg-type]


def test_options_from_a_dict() -> None:
    o = forecast_options({"order": 12, "horizons": [0.5, 1]})
    assert o.order == 12 and o.horizons == (0.5, 1.0)
    assert forecast_options(None) == ForecastOptions()
    with pytest.raises(ValueError, match="forecast has no parameter 'oder'"):
        forecast_options({"oder": 12})
    assert DeckForecaster({"order": 8}).p == 8
    with pytest.raises(TypeError, match="forecast must be a ForecastOptions"):
        DeckForecaster("fast")  # type: ignore[arg-type]


def test_fixed_noise_option() -> None:
    t = np.arange(0.0, 30.0, 1 / 30)
    fc = DeckForecaster(ForecastOptions(noise_std=(0.003, 0.001, 0.001)))
    feed(fc, t, sines(t, [(0.02, 5.0, 0.3)]))
    r = fc.state_dict()["noise_var_cell"] * fc.mean_count
    np.testing.assert_allclose(r, [0.003**2, 0.001**2, 0.001**2])


def test_oscillation_gives_the_zero_crossing_period_and_the_spread() -> None:
    fc = DeckForecaster()
    assert np.isnan(fc.oscillation()[0]).all() and np.isnan(fc.oscillation()[1]).all()
    t = np.arange(0.0, 40.0, 1 / 30)
    rng = np.random.default_rng(0)
    # a strong swell at 1.3 s and a weaker sea at 0.8 s, with noise
    parts = [(0.02, 2 * math.pi / 1.3, 0.3), (0.006, 2 * math.pi / 0.8, 1.0)]
    y = sines(t, parts) + rng.normal(0, 0.002, (t.size, 3))
    feed(fc, t, y)
    period, std = fc.oscillation()
    # the zero-crossing period of the two: 2 pi sqrt(m0 / m2)
    m0 = sum(a * a for a, _, _ in parts)
    m2 = sum((a * w) ** 2 for a, w, _ in parts)
    np.testing.assert_allclose(period, 2 * math.pi * math.sqrt(m0 / m2), rtol=0.05)
    spread = np.std(sines(t, parts), axis=0)
    np.testing.assert_allclose(std, spread, rtol=0.35)
