"""The closed-loop camera-model comparison: its statistics on known inputs, and a real paired run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.experiments.closed_loop import ESTIMATORS, LoopRun, compare, fly, markdown


def _run(name: str, heights: dict[int, list[float]], valid: dict[int, list[bool]]) -> LoopRun:
    run = LoopRun(name)
    for s, h in heights.items():
        run.outcomes[s] = "success"
        run.heights[s] = np.array(h)
        run.valid[s] = {e: np.array(valid[s], dtype=bool) for e in ESTIMATORS}
    return run


def test_compare_statistics_on_known_runs() -> None:
    seeds = range(10)
    heights = {s: [0.7, 0.7, 0.7, 0.7, 1.2, 1.2] for s in seeds}
    a = _run("a", heights, {s: [True, True, False, False, True, True] for s in seeds})  # 0.6-0.8: 50 %
    b = _run("b", heights, {s: [True, True, True, False, True, s < 5] for s in seeds})  # 75 %; 1-1.5: 75 %
    rows = {(r.band, r.estimator): r for r in compare(a, b, bands=((0.6, 0.8), (1.0, 1.5), (2.0, 3.5)))}
    r = rows[((0.6, 0.8), "ihrcf")]
    assert (r.steps_a, r.steps_b) == (40, 40)
    assert (r.valid_a, r.valid_b, r.difference) == (0.5, 0.75, 0.25)
    assert r.interval == pytest.approx((0.25, 0.25))  # every seed differs by the same amount
    r = rows[((1.0, 1.5), "fused")]
    assert r.difference == pytest.approx(-0.25)
    lo, hi = r.interval  # the seeds disagree (b: 2/2 or 1/2): a real interval around -0.25
    assert -0.5 < lo < -0.25 < hi < 0.0
    r = rows[((2.0, 3.5), "atda")]  # no step in the band
    assert r.steps_a == r.steps_b == 0 and math.isnan(r.valid_a) and math.isnan(r.difference)
    assert "10 seeds; landed: a 10/10, b 10/10" in markdown(a, b, list(rows.values()))
    with pytest.raises(ValueError, match="no seed"):
        compare(a, _run("c", {99: [1.0]}, {99: [True]}))


def test_the_same_model_twice_agrees_exactly() -> None:
    # a real closed-loop run: the same seeds flown twice with the same camera model are identical
    # (seeded env, deterministic controller), so every difference and interval is exactly 0
    a = fly("projected", [3], max_episode_steps=120)
    b = fly("projected", [3], max_episode_steps=120)
    assert len(a.heights[3]) == len(b.heights[3]) > 50
    np.testing.assert_array_equal(a.heights[3], b.heights[3])
    rows = compare(a, b)
    assert sum(r.steps_a for r in rows if r.estimator == "fused") == len(a.heights[3])
    for r in rows:
        if r.steps_a:
            assert r.difference == 0.0 and r.interval == (0.0, 0.0)
