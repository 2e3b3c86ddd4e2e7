"""The landing evaluation: a short run on the static deck lands, from the drone's own sensing."""

from __future__ import annotations

from ihrcf_env.core.metrics import EpisodeResult, summarize_landings
from ihrcf_env.experiments.landing import evaluate


def test_short_run_lands() -> None:
    seen: list[EpisodeResult] = []
    results = evaluate("static", 1, max_seconds=8.0, on_episode=seen.append)
    assert seen == results and len(results) == 1
    r = results[0]
    assert r.outcome == "success", r
    assert r.profile == "static" and r.seed == 0 and r.speed is not None and r.tilt is not None
    assert r.commit_time is not None and r.commit_time <= r.time
    s = summarize_landings(results)
    assert s.successes == 1 and s.episodes == 1
