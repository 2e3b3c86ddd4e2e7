"""The benchmark's split of the projected wrapped step (figures are printed by the benchmark CLI;
here only that the split is complete and consistent)."""

from __future__ import annotations

import pytest

from ihrcf_env.experiments.speed import projected_step_costs


def test_projected_step_split_covers_the_whole_step() -> None:
    costs = projected_step_costs(steps=20)
    assert list(costs) == ["env", "ihrcf", "atda", "fused", "wrapper", "total"]
    parts = [v for k, v in costs.items() if k != "total"]
    assert all(v > 0 for v in parts[:4])  # every part does work on every step
    assert sum(parts) == pytest.approx(costs["total"], rel=1e-9)
    assert costs["wrapper"] < costs["total"]
