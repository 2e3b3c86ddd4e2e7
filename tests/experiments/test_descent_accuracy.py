"""The descent-accuracy experiment: the shadow filters, the per-band statistics and the command."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.core.estimators import PoseEstimate
from ihrcf_env.experiments import descent_accuracy as da


@pytest.fixture(scope="module")
def moderate() -> da.DescentAccuracy:
    variants = {
        "copy": lambda p: p,  # the env's parameters, any name: must equal the env's fused filter
        "fused+deck": lambda p: dataclasses.replace(p, deck_model="oscillator"),
    }
    return da.descent_accuracy("moderate", [1000], variants=variants)


def test_a_shadow_with_the_env_parameters_equals_the_env_filter(moderate: da.DescentAccuracy) -> None:
    assert moderate.outcomes.total() == 1 and not moderate.static
    for a, b in zip(moderate.stats["fused"], moderate.stats["copy"], strict=True):
        assert dataclasses.astuple(a) == dataclasses.astuple(b)
    assert moderate.reasons["fused"] == moderate.reasons["copy"]


def test_every_band_below_two_metres_is_scored(moderate: da.DescentAccuracy) -> None:
    for name in ("atda", "fused", "fused+deck"):
        stats = moderate.stats[name]
        assert stats[1].frames > 10 and stats[2].frames > 10, name
        lat, depth, angle, valid = stats[2].summary()
        assert 0 < lat < 50 and 0 < depth < 50 and 0 < angle < 5 and 0 < valid <= 100, (name, stats[2])
    # the narrow-band deck model is closer to the truth between 0.45 and 2 m than the default
    for band in (1, 2):
        assert moderate.stats["fused+deck"][band].summary()[1] < moderate.stats["fused"][band].summary()[1]


def test_band_stats_add_and_summary() -> None:
    s = da.BandStats()
    assert all(math.isnan(x) for x in s.summary())
    s.add(PoseEstimate.invalid("x"), np.zeros(3), np.array([0.0, 0.0, 1.0]))
    R = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(0.1), -math.sin(0.1)], [0.0, math.sin(0.1), math.cos(0.1)]])
    s.add(
        PoseEstimate.from_body_pose(R, [0.003, 0.004, 1.01], 0.0),
        np.array([0.0, 0.0, 1.0]),
        np.array([0.0, 0.0, 1.0]),
    )
    lat, depth, angle, valid = s.summary()
    assert lat == pytest.approx(5.0) and depth == pytest.approx(10.0)
    assert angle == pytest.approx(math.degrees(0.1)) and valid == pytest.approx(50.0)
    assert da._band(0.2) == 0 and da._band(0.45) == 1 and da._band(3.9) == 3 and da._band(4.5) is None


def test_command_writes_the_tables(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def fake(
        level: str, seeds: list[int], static: bool = False, camera_model: str = "projected"
    ) -> da.DescentAccuracy:
        calls.append((level, tuple(seeds), static, camera_model))
        out = da.DescentAccuracy(level, static)
        out.stats = {"fused": [da.BandStats(4, 2, 0.004, 0.002, 0.02) for _ in da.BANDS]}
        out.reasons = {"fused": da.Counter({"converging": 2})}
        return out

    monkeypatch.setattr(da, "descent_accuracy", fake)
    md = tmp_path / "t.md"
    assert da.main(["--levels", "calm", "--seeds", "2", "--markdown", str(md)]) == 0
    assert calls == [("calm", (1000, 1001), False, "projected"), ("calm", (1000, 1001), True, "projected")]
    text = md.read_text()
    assert "| calm | 1-2 | fused | 2.0 / 2.0 | 1.0 / 1.0 | 0.57 / 0.57 | 50 / 50 | 4 / 4 |" in text
    assert "converging (2)" in text
    with pytest.raises(SystemExit):
        da.main(["--seeds", "0"])
