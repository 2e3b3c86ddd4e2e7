"""The user-facing docs: README shape and wording, links, the generated results page's writer, and
the custom-estimator example (run in a subprocess)."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.core.metrics import ErrorStats
from ihrcf_env.experiments.results import (
    HEADLINE_BEGIN,
    HEADLINE_END,
    LandingRow,
    Results,
    SpeedRow,
    Stamp,
    headline_markdown,
    replace_block,
    results_markdown,
)

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
#: Words about how the project was developed, which user-facing text must not contain.
WORK_LOG = re.compile(r"session \d|target (met|missed)|design card|\d asked\)", re.IGNORECASE)
NAN = math.nan
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def _pages() -> list[Path]:
    return [README, ROOT / "CHANGELOG.md", *sorted(DOCS.glob("*.md"))]


def _stats(scale: float, invalid: int = 0, frames: int = 10) -> ErrorStats:
    mae = scale * np.array([0.001, 0.002, 0.003, 0.1, 0.2, 0.3])
    return ErrorStats(mae=mae, peak=2 * mae, invalid=invalid, frames=frames)


def _results() -> tuple[Results, Stamp]:
    res = Results(
        accuracy={
            ("ideal", 1.0): {"ihrcf": _stats(1.0), "atda": _stats(2.0), "fused": _stats(0.5, invalid=2)},
            ("realistic", 1.0): {"ihrcf": _stats(3.0, invalid=4), "atda": _stats(2.0)},
        },
        raw_speed=[SpeedRow("none", 2000.0, 100.0), SpeedRow("512x512", 20.0, 1.0)],
        wrapped_speed=[SpeedRow("rendered 512, image kept", 18.0, 0.9), SpeedRow("projected", 450.0, 22.5)],
        landing=[
            LandingRow("projected", 4, 3, (0.3, 0.4), (4.0, 6.0), (0.05, 0.1), (9.0, 12.0), {"timeout": 1}),
            LandingRow("rendered", 1, 0, (NAN, NAN), (NAN, NAN), (1.0, 1.0), (NAN, NAN)),
        ],
    )
    command = "python -m ihrcf_env.experiments.results --quick"
    stamp = Stamp("9.9.9", "2001-02-03", command, "box, 2 CPUs", "quick", wall_s=90.0, cpu_share=0.5)
    return res, stamp


# -- the results writer --------------------------------------------------------------------------
def test_results_page_has_stamp_and_every_table():
    res, stamp = _results()
    md = results_markdown(res, stamp)
    for text in ("9.9.9", "2001-02-03", "--quick", "box, 2 CPUs", "quick", "wall time: 1.5 min"):
        assert text in md
    assert "this process ran 50 %" in md
    # Table 2 rows per axis, MAE (peak) in the estimators' order ATDA, IHRCF, fused
    assert "| X (m) | 0.0020 (0.0040) | 0.0010 (0.0020) | 0.0005 (0.0010) | 0.0162 | 0.0035 |" in md
    assert "| invalid frames | 0 | 0 | 2 | | |" in md
    assert "| 512x512 | 20.0 | 1.00x |" in md
    assert "| projected | 450.0 | 22.50x | 25.0x |" in md
    assert "| projected | 3/4 | 0.300 / 0.400 | 4.00 / 6.00 | 0.050 / 0.100 | 9.0 / 12.0 | timeout x1 |" in md
    assert "| rendered | 0/1 | - / - |" in md
    assert "nan" not in md.lower()


def test_headline_table_in_mm_and_deg_with_the_paper():
    res, stamp = _results()
    md = headline_markdown(res, stamp)
    assert "| IHRCF | paper (real flight) | 3.50 | 3.90 | 4.10 | 0.980 | 1.373 | 1.180 | |" in md
    assert "| IHRCF | simulated, realistic | 3.00 | 6.00 | 9.00 | 0.300 | 0.600 | 0.900 | 6/10 |" in md
    assert "| fused | simulated, ideal | 0.50 | 1.00 | 1.50 | 0.050 | 0.100 | 0.150 | 8/10 |" in md
    assert "Scripted landing on the landing task: 3/4 (projected camera), 0/1 (rendered camera)." in md
    assert "real time" not in md  # speed depends on the machine: on the results page only
    assert "9.9.9" in md and "2001-02-03" in md
    assert all(line.startswith("|") for line in md.splitlines()[:2])


def test_replace_block_rewrites_only_between_the_markers():
    text = f"intro\n{HEADLINE_BEGIN}\nold\ntable\n{HEADLINE_END}\noutro\n"
    out = replace_block(text, "new table\n")
    assert out == f"intro\n{HEADLINE_BEGIN}\nnew table\n{HEADLINE_END}\noutro\n"
    assert replace_block(out, "new table") == out  # idempotent
    with pytest.raises(ValueError, match="markers"):
        replace_block("no markers here", "x")
    with pytest.raises(ValueError, match="markers"):
        replace_block(f"{HEADLINE_END}\n{HEADLINE_BEGIN}", "x")


# -- the README and the pages --------------------------------------------------------------------
def test_readme_is_short_and_starts_with_the_two_commands():
    lines = README.read_text().splitlines()
    assert len(lines) <= 220
    commands = [ln.strip() for ln in lines if ln.strip().startswith("python3 -m venv")]
    assert len(commands) >= 2
    setup = 'python3 -m venv .venv && .venv/bin/pip install ".[test]"'
    assert commands[0] == setup + " && .venv/bin/python examples/hover_and_track.py"
    assert commands[1] == setup + " && .venv/bin/pytest"
    first_code = next(i for i, ln in enumerate(lines) if ln.startswith("```"))
    first_command = next(i for i, ln in enumerate(lines) if ln.strip() == commands[0])
    assert first_command == first_code + 1 or first_command == first_code + 2  # the first code block
    assert not any(ln.startswith("```python") for ln in lines[:first_code])


def test_readme_has_the_generated_headline_block():
    text = README.read_text()
    i, j = text.find(HEADLINE_BEGIN), text.find(HEADLINE_END)
    assert 0 <= i < j
    assert "python -m ihrcf_env.experiments.results" in text[i:j]


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.name)
def test_no_words_about_how_the_project_was_developed(page):
    hits = [ln for ln in page.read_text().splitlines() if WORK_LOG.search(ln)]
    assert not hits, f"{page.name}: {hits[:3]}"


@pytest.mark.parametrize("page", _pages(), ids=lambda p: p.name)
def test_relative_links_point_to_existing_files(page):
    missing = []
    for target in LINK.findall(page.read_text()):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue  # absolute URL or an anchor in the same page
        path = (page.parent / target.split("#")[0]).resolve()
        if not path.exists():
            missing.append(target)
    assert not missing, f"{page.name}: broken links {missing}"


def test_results_page_is_generated_and_stamped():
    text = (DOCS / "results.md").read_text()
    assert "do not edit by hand" in text
    assert re.search(r"- ihrcf_env \d+\.\d+\.\d+, generated \d{4}-\d\d-\d\d", text)
    assert "- command: `python -m ihrcf_env.experiments.results" in text
    assert "- machine: " in text and "CPUs" in text


def test_benchmark_v2_page_is_generated_and_stamped():
    text = (DOCS / "benchmark-v2.md").read_text()
    assert "do not edit by hand" in text
    assert "- command: `python -m ihrcf_env.experiments.benchmark_v2" in text
    for level in ("calm", "moderate", "rough"):
        assert re.search(rf"\| {level} \| scripted \| projected \| \d+/\d+ \(", text), level
        assert re.search(rf"\| {level} \| blind:0.3 \| projected \| \d+/\d+ \(", text), level
    assert "| moderate | scripted | rendered |" in text


def test_the_docs_pages_exist():
    for name in (
        "tasks",
        "observations",
        "sensors",
        "estimators",
        "camera-models",
        "learning",
        "architecture",
        "results",
        "extending",
    ):
        assert (DOCS / f"{name}.md").is_file(), name


# -- the custom estimator example ----------------------------------------------------------------
def test_custom_estimator_example_runs():
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    env = {**os.environ, "PYTHONWARNINGS": "error::ResourceWarning", "PYTHONPATH": path}
    out = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "custom_estimator.py"), "--steps", "20"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
        env=env,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert "mytoy" in out.stdout
    assert re.search(r"valid on \d+ of 20 steps", out.stdout)


def test_v2_table_has_the_wilson_interval() -> None:
    from ihrcf_env.experiments.benchmark_v2 import Job, table_markdown
    from ihrcf_env.experiments.results import LandingRow

    row = LandingRow("projected", 20, 10, (0.3, 0.4), (4.0, 6.0), (0.05, 0.1), (9.0, 12.0), {"timeout": 10})
    md = table_markdown({Job("moderate", "out/ppo/best.zip", "rendered", 20): row})
    assert "| moderate | best.zip | rendered | 10/20 (30%-70%) |" in md and "timeout x10" in md


def test_the_observation_tables_are_generated_from_the_layout_code() -> None:
    """``docs/observations.md`` holds the tables ``ihrcf_env.wrappers.obs_tables`` makes from the
    wrappers' field lists, as they are now (rerun ``python -m ihrcf_env.wrappers.obs_tables --write
    docs/observations.md`` after changing a layout)."""
    from ihrcf_env.wrappers.obs_tables import TABLES, render

    page = (DOCS / "observations.md").read_text()
    assert render(page) == page
    for key in TABLES:
        assert f"<!-- layout:{key} -->" in page and f"<!-- /layout:{key} -->" in page


def test_rendering_replaces_a_stale_table_and_refuses_an_unknown_one() -> None:
    from ihrcf_env.wrappers.obs_tables import render, tables

    stale = "intro\n<!-- layout:landing -->\n| old |\n<!-- /layout:landing -->\nend\n"
    assert (
        render(stale)
        == f"intro\n<!-- layout:landing -->\n{tables()['landing']}\n<!-- /layout:landing -->\nend\n"
    )
    with pytest.raises(KeyError, match="nosuch"):
        render("<!-- layout:nosuch -->\n<!-- /layout:nosuch -->\n")


def test_the_documented_layouts_are_the_envs_layouts() -> None:
    """The blocks the tables are made from are the ones each id's wrapper builds its observation
    from (default options)."""
    import gymnasium as gym

    import ihrcf_env
    from ihrcf_env.core.estimators import DEFAULT_ESTIMATORS
    from ihrcf_env.wrappers.estimates import hover_blocks
    from ihrcf_env.wrappers.landing_obs import landing_blocks
    from ihrcf_env.wrappers.layout import build_layout
    from ihrcf_env.wrappers.obs_tables import LANDING_IDS

    assert set(LANDING_IDS) == {ihrcf_env.LANDING_V1_ID, ihrcf_env.LANDING_V2_ID}
    landing = build_layout(landing_blocks(DEFAULT_ESTIMATORS)).slices
    for env_id in LANDING_IDS:
        with gym.make(env_id, camera_model="projected") as env:
            assert env.get_wrapper_attr("obs_slices") == landing
            assert env.observation_space.shape == (landing["all"].stop,)
    with gym.make(ihrcf_env.HOVER_ID, camera_model="projected", flatten=True) as env:
        hover = build_layout(hover_blocks(DEFAULT_ESTIMATORS)).slices
        assert env.get_wrapper_attr("flat_slices") == hover
        assert env.observation_space.shape == (hover["all"].stop,)
