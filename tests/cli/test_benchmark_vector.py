"""``ihrcf-benchmark --vector``: the native vector env against the single env (a tiny run: the
table's structure and arithmetic, not the figures), and its arguments checked by name."""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from ihrcf_env.cli.benchmark import VECTOR_NS, build_parser, main
from ihrcf_env.experiments.vector_speed import PairedSpeed, VectorSpeed, markdown_table

ROW = re.compile(r"^\| (\d+) \| (\d+) \| ([0-9.]+) \| ([0-9.]+) \| ([0-9.]+) \| ([0-9.]+)-([0-9.]+) \|$")


@pytest.fixture
def affinity() -> Iterator[None]:
    """The CLI pins its process to one core: give the test process its cores back."""
    before = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    yield
    if before is not None:
        os.sched_setaffinity(0, before)


def test_vector_run_prints_one_row_per_n_and_processes(
    affinity: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    md = tmp_path / "vector.md"
    cores = min(2, len(os.sched_getaffinity(0))) if hasattr(os, "sched_getaffinity") else 2
    argv = ["--vector", "2", "--processes", "1", "2", "--steps", "6", "--vector-steps", "2", "--rounds", "2"]
    assert main([*argv, "--warmup", "1", "--markdown", str(md)]) == 0
    out = capsys.readouterr().out
    assert "Table" not in out and "ATDA" not in out  # the vector comparison only
    lines = md.read_text().splitlines()
    head = lines.index(
        "| N | processes | env-steps/s | per core | ratio to single (per core) | rounds' range |"
    )
    assert lines[head + 1] == "|---|---|---|---|---|---|"
    single = re.match(r"^\| single env \| 1 \| ([0-9.]+) \| ([0-9.]+) \| 1\.00 \| - \|$", lines[head + 2])
    assert single is not None and float(single[1]) > 0
    rows = [ROW.match(line) for line in lines[head + 3 :]]
    assert all(r is not None for r in rows) and len(rows) == 2
    got = [(int(r[1]), int(r[2])) for r in rows if r is not None]
    assert got == [(2, 1), (2, 2)]  # each N and number of processes
    for r, used in zip(rows, (1, cores), strict=True):
        assert r is not None
        sps, per_core, ratio, low, high = float(r[3]), float(r[4]), float(r[5]), float(r[6]), float(r[7])
        assert sps > 0
        assert per_core == pytest.approx(sps / used, abs=0.06)
        assert low - 0.005 <= ratio <= high + 0.005  # the median of the two rounds' ratios
    rounds = re.findall(r"^round (\d): single env ([0-9.]+) steps/s$", out, re.M)
    assert [k for k, _ in rounds] == ["1", "2"]
    assert float(single[1]) == pytest.approx(sum(float(v) for _, v in rounds) / 2, abs=0.06)
    assert "\n".join(lines[head:]) in out  # printed as written


def test_ratio_is_per_core_against_the_single_env() -> None:
    rows = [VectorSpeed(8, 1, 1, 300.0), VectorSpeed(8, 4, 2, 1000.0)]
    table = markdown_table(200.0, rows)
    assert table[2] == "| single env | 1 | 200.0 | 200.0 | 1.00 | - |"
    assert table[3] == "| 8 | 1 | 300.0 | 300.0 | 1.50 | - |"
    assert table[4] == "| 8 | 4 | 1000.0 | 500.0 | 2.50 | - |"


def test_rounds_pair_each_run_with_its_own_single_env() -> None:
    # the machine twice as fast in round 2: each round's ratio is the same, the medians are taken
    runs = [VectorSpeed(8, 1, 1, v) for v in (300.0, 600.0, 330.0)]
    row = PairedSpeed.of(runs, [200.0, 400.0, 200.0])
    assert row.ratios == (1.5, 1.5, 1.65)
    assert row.ratio == 1.5 and row.speed.env_steps_per_s == 330.0
    assert markdown_table(200.0, [row])[3] == "| 8 | 1 | 330.0 | 330.0 | 1.50 | 1.50-1.65 |"
    with pytest.raises(ValueError, match="one single-env figure per round"):
        PairedSpeed.of(runs, [200.0])


def test_vector_without_values_takes_the_default_ns() -> None:
    ap = build_parser()
    assert ap.parse_args(["--vector"]).vector == []  # main reads [] as VECTOR_NS
    assert VECTOR_NS == (1, 8, 32, 128)
    assert ap.parse_args([]).vector is None and ap.parse_args([]).processes == [1]
    assert ap.parse_args(["--vector", "3", "5"]).vector == [3, 5]


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["--vector", "0"], "--vector"),
        (["--vector", "2", "-1"], "--vector"),
        (["--vector", "two"], "--vector"),
        (["--vector", "5000"], "--vector"),
        (["--vector", "2", "--processes", "0"], "--processes"),
        (["--processes", "2"], "--processes"),  # without --vector
        (["--vector", "2", "--vector-steps", "0"], "--vector-steps"),
        (["--vector", "2", "--warmup", "-1"], "--warmup"),
        (["--vector", "2", "--rounds", "0"], "--rounds"),
        (["--vector", "2", "--id", "ihrcf_env/DeckHover-v0"], "--id"),
        (["--vector", "2", "--actions", "sine"], "--actions"),
    ],
)
def test_bad_vector_arguments_are_refused_by_name(
    affinity: None, argv: list[str], name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert f"argument {name}" in capsys.readouterr().err
