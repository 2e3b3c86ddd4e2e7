"""The batched estimator pipeline (ihrcf_env.core.batch.pipeline) equals N DeckPoseEstimators."""

from __future__ import annotations

import numpy as np
import pytest
from test_batch_fused import STEPS, history
from test_fused import RIG, TAG, K, touch_pixels

from ihrcf_env.core.batch.pipeline import BatchDeckPoseEstimator, batchable
from ihrcf_env.core.estimators import DeckPoseEstimator, FusedParams, PoseEstimate
from ihrcf_env.core.estimators.registry import EstimatorConfig, build_estimators

TOL = 1e-9


def _diff(a: PoseEstimate, b: PoseEstimate) -> float:
    return max(
        float(np.abs(a.position - b.position).max()),
        float(np.abs(a.rotation - b.rotation).max()),
        float(np.abs(a.euler - b.euler).max()),
        abs(a.residual - b.residual),
    )


@pytest.mark.parametrize("names", [("ihrcf", "atda", "fused"), ("fused", "atda"), ("ihrcf",)])
def test_rows_equal_single_pipelines(names: tuple[str, ...]) -> None:
    n = 6
    config = EstimatorConfig(RIG, TAG, K, None, touch_pixels, fused=FusedParams(max_rejections=3))
    hist = [history(e) for e in range(n)]
    singles = [build_estimators(config, names) for _ in range(n)]
    batch = BatchDeckPoseEstimator(n, config, names)
    worst, valid, reasons = 0.0, {k: 0 for k in names}, set()
    for k in range(STEPS):
        resets = np.array([k in hist[e][1] for e in range(n)])
        for e in np.flatnonzero(resets):
            for s in singles[e].values():
                s.reset()
        batch.reset(resets)
        row = [hist[e][0][k] for e in range(n)]
        got = batch.update(row)
        for e in range(n):
            if row[e] is None:
                assert got[e] is None
                continue
            b = got[e]
            assert b is not None and list(b) == list(names)
            for name, single in singles[e].items():
                s = single.update(row[e])
                assert (s.valid, s.reason) == (b[name].valid, b[name].reason), (k, e, name)
                reasons.add(s.reason)
                valid[name] += s.valid
                worst = max(worst, _diff(s, b[name]))
    assert worst < TOL, worst
    assert all(v > n * STEPS * 0.3 for v in valid.values()), valid
    assert len(reasons) > 3


def test_batchable_only_the_built_in_estimators() -> None:
    config = EstimatorConfig(RIG, TAG, K, None, touch_pixels)
    est = DeckPoseEstimator(RIG, TAG, 0, K, None, touch_pixels)
    assert batchable(est.sources)
    assert batchable(build_estimators(config, ("atda",)))
    swapped = {"ihrcf": est.sources["atda"]}
    assert not batchable(swapped)
    assert not batchable({})
    with pytest.raises(ValueError, match="no batched form"):
        BatchDeckPoseEstimator(2, config, ("ihrcf", "mine"))
    batch = BatchDeckPoseEstimator(2, config, ("ihrcf",))
    with pytest.raises(ValueError, match="one per row"):
        batch.update([None])
    with pytest.raises(RuntimeError, match="fused"):
        batch.motion()
