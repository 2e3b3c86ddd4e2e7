"""The generated results page: ``python -m ihrcf_env.experiments.results [--quick] [--out FILE]``.

Runs the package's own experiments and writes their tables as Markdown (``docs/results.md`` by
default), stamped with the package version, the date, the command line and the machine:

* accuracy: the paper's hover (:func:`ihrcf_env.experiments.accuracy.accuracy`) with the ideal and
  the realistic sensor preset at 1 m and 2 m above the deck, Table 2 style;
* speed: the raw env per camera size and the wrapped env per camera model
  (:mod:`ihrcf_env.experiments.speed`), pinned to one core unless ``--all-cores``;
* landing: the scripted landing (:class:`~ihrcf_env.control.policies.ScriptedLanding`, own sensing
  only) on the landing task ``ihrcf_env/DeckLanding-v1``, per camera model.

It also rewrites the headline block of ``README.md`` (between :data:`HEADLINE_BEGIN` and
:data:`HEADLINE_END`; ``--readme PATH``, ``--no-readme``). ``--quick`` runs fewer frames, steps and
episodes (said in the stamp). The Markdown is built by pure functions (:func:`results_markdown`,
:func:`headline_markdown`, :func:`replace_block`) so it can be tested without running anything.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ihrcf_env
from ihrcf_env.core.metrics import (
    ESTIMATORS,
    LABELS,
    PAPER_TABLE2,
    EpisodeResult,
    ErrorStats,
    failure_groups,
    table2_markdown,
    table_columns,
)
from ihrcf_env.experiments.episode import run_episodes

#: Markers of the README block this command rewrites.
HEADLINE_BEGIN = "<!-- results:headline -->"
HEADLINE_END = "<!-- /results -->"
PRESETS: tuple[str, ...] = ("ideal", "realistic")


@dataclass(frozen=True)
class Plan:
    """How much to run: accuracy frames (20 Hz) per run, hover heights (m), timed steps per speed
    configuration, camera sizes of the raw env (0 = none), scripted landings per camera model."""

    name: str
    frames: int
    altitudes: tuple[float, ...]
    speed_steps: int
    sizes: tuple[int, ...]
    landings: Mapping[str, int]
    seed: int = 0

    def describe(self) -> str:
        landings = ", ".join(f"{n} {m}" for m, n in self.landings.items() if n)
        return (
            f"{self.name}: {self.frames} frames per hover run, {self.speed_steps} timed steps per speed "
            f"configuration, scripted landings per camera model: {landings or 'none'}; seed {self.seed}"
        )


FULL = Plan("full", 600, (1.0, 2.0), 300, (0, 128, 256, 512), {"projected": 30, "rendered": 10}, 0)
QUICK = Plan("quick", 120, (1.0, 2.0), 60, (0, 512), {"projected": 4, "rendered": 1}, 0)


@dataclass(frozen=True)
class Stamp:
    """Where and how a results page was made."""

    version: str
    date: str
    command: str
    machine: str
    plan: str
    wall_s: float = math.nan
    cpu_share: float = math.nan  # CPU time of this process / wall time (1 = one full core)


@dataclass(frozen=True)
class SpeedRow:
    """Steps per wall-clock second of one configuration and its real-time factor."""

    label: str
    steps_per_s: float
    real_time_factor: float


@dataclass(frozen=True)
class LandingRow:
    """Scripted landings on v1 with one camera model: outcomes and touchdown figures (mean, max)."""

    camera_model: str
    episodes: int
    successes: int
    speed: tuple[float, float]  # |relative vertical speed| at touchdown, m/s
    tilt_deg: tuple[float, float]  # relative tilt at touchdown, deg
    offset: tuple[float, float]  # horizontal distance from the tag centre at touchdown, m
    time: tuple[float, float]  # simulated s to land, over successes
    failures: dict[str, int] = field(default_factory=dict)


@dataclass
class Results:
    """Everything the page shows. ``accuracy`` is keyed by (preset, altitude in m)."""

    accuracy: dict[tuple[str, float], dict[str, ErrorStats]] = field(default_factory=dict)
    raw_speed: list[SpeedRow] = field(default_factory=list)
    wrapped_speed: list[SpeedRow] = field(default_factory=list)
    landing: list[LandingRow] = field(default_factory=list)


# -- formatting (pure) ---------------------------------------------------------------------------
def _mm_deg(values: Sequence[float]) -> list[str]:
    """X, Y, Z in mm (from m) and roll, pitch, yaw in deg, formatted."""
    out = []
    for i, v in enumerate(values):
        out.append("-" if not math.isfinite(v) else (f"{1e3 * v:.2f}" if i < 3 else f"{v:.3f}"))
    return out


def pair(p: tuple[float, float], fmt: str) -> str:
    """A (mean, max) pair formatted with ``fmt`` (``-`` for a missing value)."""
    return " / ".join("-" if not math.isfinite(v) else fmt.format(v) for v in p)


def stamp_markdown(stamp: Stamp) -> str:
    """The stamp as a Markdown list."""
    wall = "" if not math.isfinite(stamp.wall_s) else f"\n- wall time: {stamp.wall_s / 60:.1f} min"
    if math.isfinite(stamp.cpu_share):
        wall += (
            f", of which this process ran {100 * stamp.cpu_share:.0f} % (CPU time / wall time; below "
            "100 % the machine was shared and the speed figures are low by about that factor)"
        )
    return (
        f"- ihrcf_env {stamp.version}, generated {stamp.date}\n"
        f"- command: `{stamp.command}`\n"
        f"- machine: {stamp.machine}\n"
        f"- run: {stamp.plan}{wall}"
    )


def headline_markdown(results: Results, stamp: Stamp, altitude: float = 1.0) -> str:
    """The README's table: the deck-pose mean absolute error at the ``altitude`` m hover per preset
    and estimator beside the paper's Table 2, then one line on the scripted landings (speed depends
    on the machine and stays on the results page)."""
    head = (
        "| estimator | sensors | X (mm) | Y (mm) | Z (mm) | roll (deg) | pitch (deg) | yaw (deg) "
        "| valid frames |"
    )
    lines = [head, "|---|---|---|---|---|---|---|---|---|"]
    for k in ESTIMATORS:
        cells = _mm_deg(list(PAPER_TABLE2[k]))
        lines.append(f"| {LABELS[k]} | paper (real flight) | " + " | ".join(cells) + " | |")
    for preset in PRESETS:
        stats = results.accuracy.get((preset, altitude))
        if stats is None:
            continue
        for k in table_columns(stats):
            s = stats[k]
            cells = _mm_deg(list(s.mae))
            label = f"| {LABELS.get(k, k)} | simulated, {preset} | "
            lines.append(label + " | ".join(cells) + f" | {s.valid}/{s.frames} |")
    landed = ", ".join(f"{r.successes}/{r.episodes} ({r.camera_model} camera)" for r in results.landing)
    text = "\n".join(lines)
    text += f"\n\nMean absolute error at the {altitude:g} m hover over the moving deck."
    if landed:
        text += f" Scripted landing on the landing task: {landed}."
    text += (
        f" Generated by `{stamp.command}` (ihrcf_env {stamp.version}, {stamp.date}); speed and the "
        "other tables: [docs/results.md](docs/results.md)."
    )
    return text


def speed_markdown(raw: Sequence[SpeedRow], wrapped: Sequence[SpeedRow]) -> str:
    """Two tables: the raw env per camera size, the wrapped env per camera model."""
    out = ["| raw env, camera | steps/s | real-time factor |", "|---|---|---|"]
    out += [f"| {r.label} | {r.steps_per_s:.1f} | {r.real_time_factor:.2f}x |" for r in raw]
    if wrapped:
        base = wrapped[0].steps_per_s
        out += ["", "| wrapped env (all estimators), camera | steps/s | real-time factor | vs first row |"]
        out.append("|---|---|---|---|")
        out += [
            f"| {r.label} | {r.steps_per_s:.1f} | {r.real_time_factor:.2f}x | {r.steps_per_s / base:.1f}x |"
            for r in wrapped
        ]
    return "\n".join(out)


def landing_markdown(rows: Sequence[LandingRow]) -> str:
    """One row per camera model: success, touchdown figures (mean / max), failures."""
    out = [
        "| camera model | success | vertical speed (m/s) | tilt (deg) | offset from the tag (m) "
        "| time to land (s) | failures |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        fail = ", ".join(f"{k} x{v}" for k, v in sorted(r.failures.items())) or "none"
        out.append(
            f"| {r.camera_model} | {r.successes}/{r.episodes} | {pair(r.speed, '{:.3f}')} "
            f"| {pair(r.tilt_deg, '{:.2f}')} | {pair(r.offset, '{:.3f}')} | {pair(r.time, '{:.1f}')} "
            f"| {fail} |"
        )
    return "\n".join(out)


def results_markdown(results: Results, stamp: Stamp) -> str:
    """The whole results page."""
    parts = [
        "# Results",
        "",
        "<!-- Generated by python -m ihrcf_env.experiments.results: do not edit by hand. -->",
        "",
        stamp_markdown(stamp),
        "",
        "Figures depend on the machine and, for speed, on what else runs on it. Regenerate them with "
        "`python -m ihrcf_env.experiments.results` (add `--quick` for a short run).",
    ]
    if results.accuracy:
        parts += [
            "",
            "## Deck-pose accuracy (the paper's hover experiment)",
            "",
            "The drone hovers above the deck on the `paper` deck profile at 20 Hz; the deck pose in the "
            "body frame from each estimator is compared with ground truth over its valid frames. "
            "`ideal`: noise-free sensors, the autopilot holds position on the true state. `realistic`: "
            "every sensor hardware-like and the autopilot on a drifting navigation estimate, so the drone "
            "is kept over the tag horizontally on the fused estimate. The paper's columns are its "
            "Table 2 (real flight, 1 m). Translations in m, angles in degrees. See "
            "[tasks](tasks.md) and [estimators](estimators.md).",
        ]
        for (preset, alt), stats in results.accuracy.items():
            parts += ["", table2_markdown(stats, f"sensor_preset={preset!r}, hover {alt:g} m")]
    if results.raw_speed or results.wrapped_speed:
        parts += [
            "",
            "## Speed",
            "",
            "Zero velocity actions at the 1 m hover, 20 Hz control, 240 Hz physics, ideal preset; the "
            "real-time factor is simulated seconds per wall-clock second. Raw env: the full camera image "
            "rendered every step. Wrapped env: all three estimators; `image kept` renders the full frame, "
            "`tag window` only the window around the tag, `projected` renders nothing "
            "(see [camera models](camera-models.md)).",
            "",
            speed_markdown(results.raw_speed, results.wrapped_speed),
        ]
    if results.landing:
        parts += [
            "",
            "## Scripted landing on the landing task",
            "",
            "`ihrcf_env/DeckLanding-v1` with its defaults (realistic sensors, wind, `sea_state` deck); "
            "the scripted landing flies on the fused estimate and the ranges, never ground truth; seeds "
            "from the stamp's seed upward, the same starts for both camera models. Touchdown figures are "
            "mean / max over the episodes that touched down; time to land over successes.",
            "",
            landing_markdown(results.landing),
        ]
    parts += [
        "",
        "The baselines of `ihrcf_env/DeckLanding-v2` (the benchmark protocol) have their own page, "
        "[benchmark-v2](benchmark-v2.md), generated by `python -m ihrcf_env.experiments.benchmark_v2`.",
    ]
    return "\n".join(parts) + "\n"


def replace_block(text: str, block: str, begin: str = HEADLINE_BEGIN, end: str = HEADLINE_END) -> str:
    """``text`` with what lies between the ``begin`` and ``end`` markers replaced by ``block``;
    ValueError if the markers are missing or out of order."""
    i = text.find(begin)
    j = text.find(end, i + len(begin)) if i >= 0 else -1
    if i < 0 or j < 0:
        raise ValueError(f"markers {begin!r} ... {end!r} not found (in this order)")
    return text[: i + len(begin)] + "\n" + block.strip("\n") + "\n" + text[j:]


def machine() -> str:
    """Platform, Python, CPU count and the load average at the time of the call (speed figures
    depend on what else runs on the machine)."""
    load = ""
    if hasattr(os, "getloadavg"):
        load = f", load average {os.getloadavg()[0]:.2f} at start"
    return (
        f"{platform.platform()}, {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} CPUs, Python {platform.python_version()}{load}"
    )


# -- running the experiments ---------------------------------------------------------------------
def run_accuracy(plan: Plan) -> dict[tuple[str, float], dict[str, ErrorStats]]:
    """The paper's hover per preset and height (the realistic drone kept over the tag on ``fused``)."""
    from ihrcf_env.experiments.accuracy import accuracy

    out = {}
    for preset in PRESETS:
        for alt in plan.altitudes:
            out[(preset, alt)] = accuracy(
                plan.frames,
                seed=plan.seed,
                env_kwargs={"sensor_preset": preset},
                altitude=alt,
                track="fused" if preset == "realistic" else None,
            )
            print(f"accuracy {preset} {alt:g} m done", flush=True)
    return out


def run_speed(plan: Plan) -> tuple[list[SpeedRow], list[SpeedRow]]:
    """The raw env per camera size and the wrapped env per camera model."""
    from ihrcf_env.experiments.speed import mode_speeds, steps_per_second

    raw = []
    for size in plan.sizes:
        kw = {"camera": False} if size == 0 else {"camera_width": size, "camera_height": size}
        env = gym.make(ihrcf_env.HOVER_RAW_ID, max_episode_steps=plan.speed_steps + 10, **kw)
        try:
            sps = steps_per_second(env, plan.speed_steps)
        finally:
            env.close()
        raw.append(SpeedRow("none" if size == 0 else f"{size}x{size}", sps, sps / 20))
    wrapped = [SpeedRow(s.label, s.steps_per_s, s.real_time_factor) for s in mode_speeds(plan.speed_steps)]
    print("speed done", flush=True)
    return raw, wrapped


def _mean_max(values: Sequence[float]) -> tuple[float, float]:
    return (float(np.mean(values)), float(np.max(values))) if values else (math.nan, math.nan)


def landing_row(camera_model: str, results: Sequence[EpisodeResult]) -> LandingRow:
    """The table row of a set of landing episodes."""
    touched = [r for r in results if r.touched_down]
    failures = dict(failure_groups(results))
    return LandingRow(
        camera_model,
        len(results),
        sum(r.outcome == "success" for r in results),
        _mean_max([float(r.speed) for r in touched if r.speed is not None]),
        _mean_max([math.degrees(r.tilt) for r in touched if r.tilt is not None]),
        _mean_max([float(r.offset) for r in touched if r.offset is not None]),
        _mean_max([r.time for r in results if r.outcome == "success"]),
        failures,
    )


def _policy(spec: str, env: gym.Env) -> Any:
    from ihrcf_env.control.policies import BlindDescent, ScriptedLanding

    if spec == "scripted":
        return ScriptedLanding.from_env(env)
    max_velocity = tuple(float(v) for v in env.unwrapped.max_velocity)  # type: ignore[attr-defined]
    return BlindDescent(float(spec.removeprefix("blind:")), max_velocity)


def run_landings(camera_model: str, episodes: int, seed: int = 0) -> LandingRow:
    """The scripted landing on ``ihrcf_env/DeckLanding-v1`` for seeds ``seed .. seed + episodes - 1``."""
    env = gym.make(ihrcf_env.LANDING_V1_ID, camera_model=camera_model)
    try:
        results = run_episodes(env, _policy("scripted", env), episodes, seed)
    finally:
        env.close()
    print(f"landings {camera_model} done", flush=True)
    return landing_row(camera_model, results)


def run(plan: Plan) -> Results:
    """All experiments of ``plan``."""
    res = Results()
    res.accuracy = run_accuracy(plan)
    res.raw_speed, res.wrapped_speed = run_speed(plan)
    res.landing = [run_landings(m, n, plan.seed) for m, n in plan.landings.items() if n > 0]
    return res


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer frames, steps and episodes (a minute or two)")
    ap.add_argument("--out", default="docs/results.md", help="the results page to write")
    ap.add_argument("--readme", default="README.md", help="README whose headline block is rewritten")
    ap.add_argument("--no-readme", action="store_true", help="do not touch the README")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    args = ap.parse_args(argv)
    plan = QUICK if args.quick else FULL
    pinned = ""
    if not args.all_cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
        pinned = " (pinned to one core)"
    argv_shown = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["python", "-m", "ihrcf_env.experiments.results", *argv_shown])
    started, cpu_started = time.perf_counter(), time.process_time()
    date = datetime.date.today().isoformat()
    mach = machine() + pinned
    results = run(plan)
    if hasattr(os, "getloadavg"):
        mach += f", {os.getloadavg()[0]:.2f} at the end"
    wall = time.perf_counter() - started
    cpu = (time.process_time() - cpu_started) / wall
    stamp = Stamp(ihrcf_env.__version__, date, command, mach, plan.describe(), wall, cpu)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(results_markdown(results, stamp))
    print(f"wrote {out}")
    readme = Path(args.readme)
    if not args.no_readme:
        if readme.is_file() and HEADLINE_BEGIN in readme.read_text():
            readme.write_text(replace_block(readme.read_text(), headline_markdown(results, stamp)))
            print(f"rewrote the headline block of {readme}")
        else:
            print(f"{readme}: no {HEADLINE_BEGIN} block, left unchanged")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "FULL",
    "HEADLINE_BEGIN",
    "HEADLINE_END",
    "PRESETS",
    "QUICK",
    "LandingRow",
    "Plan",
    "Results",
    "SpeedRow",
    "Stamp",
    "headline_markdown",
    "landing_markdown",
    "landing_row",
    "machine",
    "main",
    "pair",
    "replace_block",
    "results_markdown",
    "run",
    "run_accuracy",
    "run_landings",
    "run_speed",
    "speed_markdown",
    "stamp_markdown",
]
