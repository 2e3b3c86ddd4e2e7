"""The forecast-quality experiment: bounds on a short seeded ship record, the command and its table."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.core.forecast import DeckForecast, DeckForecaster
from ihrcf_env.experiments import forecast_quality as fq

SHORT = fq.Sampling(duration=50.0, warmup=25.0, every=0.3)


def ratios(r: fq.LevelQuality, horizon: float) -> np.ndarray:
    j = list(r.horizons).index(horizon)
    return r.rms[j, [0, 2, 3]] / r.persist[j, [0, 2, 3]]


@pytest.fixture(scope="module")
def rough() -> fq.LevelQuality:
    return fq.evaluate("rough", [0], sampling=SHORT)


def test_rough_forecast_beats_persistence(rough: fq.LevelQuality) -> None:
    assert rough.n_forecasts > 40
    assert np.all(ratios(rough, 1.0) < 0.8), ratios(rough, 1.0)
    assert np.all(ratios(rough, 0.5) < 0.5), ratios(rough, 0.5)
    # calibrated to within a wide band (0.68 for a calibrated Gaussian forecast)
    assert np.all((rough.inside > 0.35) & (rough.inside < 0.97)), rough.inside
    # the heave rate forecast is better than knowing nothing (the truth's spread) at short horizons
    assert rough.rms[0, 1] < 0.7 * rough.persist[0, 1]
    assert rough.us_per_sample > 0 and rough.us_per_forecast > 0


def test_the_bounds_fail_for_a_persistence_forecast(monkeypatch: pytest.MonkeyPatch) -> None:
    real = DeckForecaster.forecast

    def persistence(self: DeckForecaster) -> DeckForecast:
        f = real(self)
        held = np.tile([self.last[0], 0.0, self.last[1], self.last[2]], (f.horizons.size, 1))
        return DeckForecast(f.horizons, held, f.std, f.ready)

    monkeypatch.setattr(DeckForecaster, "forecast", persistence)
    r = fq.evaluate("rough", [0], sampling=SHORT)
    assert not np.all(ratios(r, 1.0) < 0.8)
    np.testing.assert_allclose(ratios(r, 1.0), 1.0, atol=0.05)


def test_quiescence_scores_and_calm_is_mostly_quiet() -> None:
    calm = fq.evaluate("calm", [1], sampling=SHORT)
    assert calm.quiet_fraction > 0.5
    assert all(0.0 <= v <= 1.0 for v in (*calm.precision, *calm.recall))
    assert calm.recall[0] > 0.5
    assert calm.recall[1] >= calm.recall[0]  # a lower level calls more windows quiet


def test_deterministic(rough: fq.LevelQuality) -> None:
    again = fq.evaluate("rough", [0], sampling=SHORT)
    np.testing.assert_array_equal(again.rms, rough.rms)
    np.testing.assert_array_equal(again.inside, rough.inside)


def test_levels_and_bad_level() -> None:
    assert fq.level_sea("rough")[:2] == (5, 40.0)
    assert fq.level_sea("calm")[2] == 0.0
    with pytest.raises(ValueError, match="level must be one of"):
        fq.level_sea("storm")


def test_command_writes_the_tables(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fq.md"
    assert fq.main(["--levels", "moderate", "--seeds", "1", "--duration", "45", "--markdown", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert "| moderate | 1 |" in text and "precision" in text and "Calibration" in text
    assert text.strip() in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seeds", "0"], "--seeds"),
        (["--duration", "10"], "--duration"),
        (["--order", "1"], "forecast.order"),
        (["--window", "0.5"], "forecast.window"),
        (["--levels", "storm"], "--levels"),
    ],
)
def test_command_refuses_bad_arguments(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        fq.main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
