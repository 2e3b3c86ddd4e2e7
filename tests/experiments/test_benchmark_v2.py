"""The DeckLanding-v2 benchmark page: its rows, its arguments and one real row."""

from __future__ import annotations

from pathlib import Path

import pytest

from ihrcf_env.config.levels import LEVELS
from ihrcf_env.experiments.benchmark_v2 import Job, main, plan, run_job


def test_plan_runs_every_level_and_the_rendered_camera_on_moderate() -> None:
    jobs = plan(100, None, ["moderate"])
    assert {j.level for j in jobs} == set(LEVELS)
    projected = [(j.level, j.policy) for j in jobs if j.camera_model == "projected"]
    assert projected == [(lvl, p) for lvl in LEVELS for p in ("blind:0.3", "scripted")]
    rendered = [(j.level, j.policy) for j in jobs if j.camera_model == "rendered"]
    assert rendered == [("moderate", "scripted")]  # blind does not look: one camera is enough
    with_policy = plan(100, "out/best.zip", ["moderate"])
    assert ("moderate", "out/best.zip", "rendered") in {
        (j.level, j.policy, j.camera_model) for j in with_policy
    }
    assert all(j.episodes == 100 for j in with_policy)
    two = plan(100, ["a.zip", "b.npz"], ["moderate"])
    moderate = [(j.policy, j.camera_model) for j in two if j.level == "moderate"]
    assert moderate == [
        (p, c)
        for c in ("projected", "rendered")
        for p in ("blind:0.3", "scripted", "a.zip", "b.npz")
        if not (p == "blind:0.3" and c == "rendered")
    ]


def test_one_row_runs_the_test_seeds() -> None:
    row = run_job(Job("calm", "blind:0.3", "projected", 1))
    assert row.episodes == 1 and row.camera_model == "projected"
    assert row.successes + sum(row.failures.values()) == 1


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["--episodes", "0"], "--episodes"),
        (["--episodes", "101"], "--episodes"),
        (["--jobs", "0"], "--jobs"),
        (["--policy", "no/such.zip"], "--policy"),
        (["--both-cameras", "stormy"], "--both-cameras"),
    ],
)
def test_bad_arguments_are_named(
    argv: list[str], name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        main([*argv, "--out", str(tmp_path / "b.md")])
    assert e.value.code == 2 and name in capsys.readouterr().err
    assert not (tmp_path / "b.md").exists()


def test_the_cache_reuses_a_finished_row(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from ihrcf_env.experiments import benchmark_v2

    job = Job("calm", "blind:0.3", "projected", 1)
    first, hit = benchmark_v2.run_cached(job, str(tmp_path))
    assert not hit
    assert len(list(tmp_path.glob("*.json"))) == 1

    def fail(job: Job) -> None:
        raise AssertionError("ran again")

    monkeypatch.setattr(benchmark_v2, "run_job", fail)
    again, hit = benchmark_v2.run_cached(job, str(tmp_path))
    assert hit and repr(again) == repr(first)  # (NaN != NaN: compare the text)
    other = Job("calm", "blind:0.3", "projected", 2)
    with pytest.raises(AssertionError, match="ran again"):  # another row is not in the cache
        benchmark_v2.run_cached(other, str(tmp_path))
