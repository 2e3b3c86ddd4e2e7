"""The benchmark protocol's command line: --level, --option, the Wilson interval."""

from __future__ import annotations

import pytest

from ihrcf_env.cli.evaluate import main
from ihrcf_env.core.metrics import wilson_interval


def test_wilson_interval_known_values() -> None:
    lo, hi = wilson_interval(50, 100)
    assert lo == pytest.approx(0.4038, abs=1e-4) and hi == pytest.approx(0.5962, abs=1e-4)
    lo, hi = wilson_interval(0, 20)  # the interval of no success is not [0, 0]
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-4)
    lo, hi = wilson_interval(100, 100)
    assert hi == 1.0 and lo == pytest.approx(0.9630, abs=1e-4)
    with pytest.raises(ValueError):
        wilson_interval(3, 2)


def test_level_runs_the_test_seeds_of_v2(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(
        [
            "--policy",
            "blind:0.3",
            "--level",
            "calm",
            "--episodes",
            "1",
            "--camera-model",
            "projected",
            "--option",
            "horizon_s=30",
            "--max-steps",
            "40",
            "--quiet",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "ihrcf_env/DeckLanding-v2" in out and "seeds 100000..100000" in out and "level=calm" in out
    assert "Wilson interval" in out


@pytest.mark.parametrize(
    ("argv", "text"),
    [
        (["--level", "stormy"], "--level"),
        (["--level", "calm", "--env-id", "ihrcf_env/DeckLanding-v1"], "--level"),
        (["--option", "novalue"], "--option"),
    ],
)
def test_bad_protocol_arguments_are_named(
    argv: list[str], text: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--policy", "blind:0.3", *argv])
    assert e.value.code == 2 and text in capsys.readouterr().err


def test_the_forecast_landing_runs_with_its_forecast_block(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(
        ["--policy", "scripted-forecast", "--level", "moderate", "--episodes", "1", "--camera-model",
         "projected", "--max-steps", "30", "--quiet"]
    )  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0 and "scripted-forecast" in out and "deck_forecast" in out


def test_the_forecast_landing_keeps_the_fused_estimate(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--policy", "scripted-forecast", "--level", "calm", "--option", 'estimators=["ihrcf"]'])
    assert e.value.code == 2 and "estimators" in capsys.readouterr().err
