"""``python -m ihrcf_env.experiments.vector_stages``: the stage timers and their table."""

from __future__ import annotations

from pathlib import Path

import pytest

from ihrcf_env.experiments import vector_stages as vs
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.vector import env as vector


def test_timers_are_removed_after_the_run() -> None:
    compute, advance = vars(BatchedVelocityController)["compute"], vector.advance
    with vs.stage_timers():
        assert vars(BatchedVelocityController)["compute"] is not compute
        assert vector.advance is not advance
    assert vars(BatchedVelocityController)["compute"] is compute
    assert vector.advance is advance


def test_a_missing_target_is_named_and_nothing_stays_patched() -> None:
    compute = vars(BatchedVelocityController)["compute"]
    stages = (
        vs.Stage("a", vs.ARRAYS, ((BatchedVelocityController, "compute"),)),
        vs.Stage("b", vs.ARRAYS, ((BatchedVelocityController, "no_such_method"),)),
    )
    with (
        pytest.raises(AttributeError, match="BatchedVelocityController.no_such_method"),
        vs.stage_timers(stages),
    ):
        pass
    assert vars(BatchedVelocityController)["compute"] is compute


def test_own_time_excludes_the_timed_calls_inside() -> None:
    clock = vs._Clock()
    inner = clock.wrap("inner", lambda: sum(range(20000)))
    outer = clock.wrap("outer", lambda: inner() + inner())
    outer()
    assert clock.own["inner"] > 0 and clock.own["outer"] >= 0
    # the outer call's own time is a small part of the whole: most of it is the two inner calls
    assert clock.own["outer"] < clock.own["inner"]


def test_every_stage_target_exists_and_kinds_are_known() -> None:
    for stage in vs.STAGES:
        assert stage.kind in vs.KINDS
        for owner, name in stage.targets:
            assert name in vars(owner), f"{stage.label}: {owner.__name__}.{name}"


def test_the_table_of_a_small_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "stages.md"
    argv = ["--num-envs", "8", "--steps", "3", "--warmup", "1", "--single-steps", "5", "--markdown", str(out)]
    assert vs.main(argv) == 0
    text = capsys.readouterr().out
    assert "N = 8:" in text
    for label in (
        "physics: autopilot",
        "estimators: each env's (IHRCF, ATDA, fused filter)",
        "task: each env's step",
    ):
        assert f"| {label}" in text
    for kind in vs.KINDS:
        assert f"| {kind} |" in text
    assert out.read_text(encoding="utf-8").count("| stage | kind |") == 1


def test_breakdown_shares_add_up() -> None:
    b = vs.breakdown("ihrcf_env/DeckLanding-v1", 2, steps=3, warmup=1, single_steps=5, physics="numpy")
    timed = sum(b.stages.values())
    assert 0.0 < timed <= b.step_s * 1.05  # the stages' own times are parts of the step
    assert b.ratio > 0 and b.bound(vs.ARRAYS) >= b.ratio and b.bound(vs.PER_ENV) >= b.ratio
    # each env runs its own estimators
    assert b.stages["estimators: each env's (IHRCF, ATDA, fused filter)"] > 0


@pytest.mark.parametrize(
    ("argv", "name"),
    [(["--num-envs", "0"], "--num-envs"), (["--steps", "0"], "--steps"), (["--warmup", "-1"], "--warmup")],
)
def test_bad_arguments_are_refused_by_name(
    argv: list[str], name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        vs.main(argv)
    assert e.value.code == 2
    assert f"argument {name}" in capsys.readouterr().err
