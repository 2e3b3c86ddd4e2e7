"""The DeckLanding-v2 baseline table: ``python -m ihrcf_env.experiments.benchmark_v2``.

Runs the benchmark protocol (the test seeds of :data:`~ihrcf_env.config.levels.TEST_SEEDS`) for each
level and baseline and writes the table as Markdown (``docs/benchmark-v2.md`` by default), stamped
like the results page: per level the blind descent (``blind:0.3``) and the scripted landing
(:class:`~ihrcf_env.control.policies.ScriptedLanding`) with the projected camera; with
``--policy FILE ...`` saved policies too (a stable-baselines3 ``.zip``, a recurrent ``.npz``); on
``--both-cameras`` levels (default ``moderate``) the scripted landing and the saved policies with the
rendered camera as well. Each row
is one policy on one level and camera: success with its 95 % Wilson interval and the touchdown
figures. ``--jobs N`` runs rows in N processes. ``--cache DIR`` keeps each finished row as a JSON
file and reuses it when the same row (level, policy file and its content, camera, episodes,
package version) is asked again, so an interrupted run resumes and a new policy adds its rows
without rerunning the others (delete the folder after changing the code).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import functools
import hashlib
import json
import multiprocessing
import os
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import ihrcf_env
from ihrcf_env.config.levels import LEVELS, TEST_SEEDS
from ihrcf_env.core.metrics import wilson_interval
from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.experiments.episode import run_episodes
from ihrcf_env.experiments.policies import make_env_for
from ihrcf_env.experiments.results import LandingRow, Stamp, landing_row, machine, pair, stamp_markdown

#: Baselines every level runs (projected camera).
BASELINES: tuple[str, ...] = ("blind:0.3", "scripted")


@dataclass(frozen=True)
class Job:
    """One row: ``policy`` (a POLICY spec) on ``level`` with ``camera_model``, ``episodes`` seeds."""

    level: str
    policy: str
    camera_model: str
    episodes: int


def label(policy: str) -> str:
    """The table's name of a policy spec (a saved policy by its file name)."""
    return os.path.basename(policy) if policy.endswith((".zip", ".npz")) else policy


def plan(episodes: int, policies: str | Sequence[str] | None, both_cameras: Sequence[str]) -> list[Job]:
    """The rows to run, in table order (``policies``: saved policy files, one or several)."""
    saved = [policies] if isinstance(policies, str) else list(policies or [])
    jobs = []
    for level in LEVELS:
        specs = [*BASELINES, *saved]
        jobs += [Job(level, s, "projected", episodes) for s in specs]
        if level in both_cameras:
            jobs += [Job(level, s, "rendered", episodes) for s in specs if s != "blind:0.3"]
    return jobs


def cache_key(job: Job) -> str:
    """A file name for ``job``'s row: its fields, the policy file's content and the version."""
    text = f"{job.level}|{job.policy}|{job.camera_model}|{job.episodes}|{ihrcf_env.__version__}"
    if job.policy.endswith((".zip", ".npz")):
        text += "|" + hashlib.sha256(Path(job.policy).read_bytes()).hexdigest()
    return hashlib.sha256(text.encode()).hexdigest()[:24] + ".json"


def load_row(path: Path) -> LandingRow | None:
    """A cached row, or None if there is none (or it cannot be read)."""
    try:
        d = json.loads(path.read_text())
        return LandingRow(**{**d, **{k: tuple(d[k]) for k in ("speed", "tilt_deg", "offset", "time")}})
    except (OSError, ValueError, TypeError, KeyError):
        return None


def run_cached(job: Job, cache: str | None) -> tuple[LandingRow, bool]:
    """:func:`run_job` through the cache folder ``cache`` (None: no cache): (row, from the cache)."""
    if cache is None:
        return run_job(job), False
    path = Path(cache) / cache_key(job)
    row = load_row(path)
    if row is not None:
        return row, True
    row = run_job(job)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(dataclasses.asdict(row)))
    tmp.replace(path)
    return row, False


def run_job(job: Job) -> LandingRow:
    """One row: the policy on the level's test seeds."""
    kwargs = {"level": job.level, "camera_model": job.camera_model}
    env, policy = make_env_for(ihrcf_env.LANDING_V2_ID, kwargs, job.policy)
    try:
        results = run_episodes(env, policy, job.episodes, TEST_SEEDS.start)
    finally:
        env.close()
    print(f"{job.level} {label(job.policy)} {job.camera_model} done", flush=True)
    return landing_row(job.camera_model, results)


def table_markdown(rows: Mapping[Job, LandingRow]) -> str:
    """One row per (level, policy, camera): success with its 95 % Wilson interval, touchdown figures
    (mean / max over the episodes that touched down), failures."""
    out = [
        "| level | policy | camera | success (95 % interval) | vertical speed (m/s) | tilt (deg) "
        "| offset from the tag (m) | failures |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for job, r in rows.items():
        lo, hi = wilson_interval(r.successes, r.episodes)
        fail = ", ".join(f"{k} x{v}" for k, v in sorted(r.failures.items())) or "none"
        out.append(
            f"| {job.level} | {label(job.policy)} | {job.camera_model} "
            f"| {r.successes}/{r.episodes} ({lo:.0%}-{hi:.0%}) | {pair(r.speed, '{:.3f}')} "
            f"| {pair(r.tilt_deg, '{:.2f}')} | {pair(r.offset, '{:.3f}')} | {fail} |"
        )
    return "\n".join(out)


def page_markdown(rows: Mapping[Job, LandingRow], stamp: Stamp) -> str:
    """The whole page."""
    return "\n".join(
        [
            "# DeckLanding-v2 baselines",
            "",
            "<!-- Generated by python -m ihrcf_env.experiments.benchmark_v2: do not edit by hand. -->",
            "",
            stamp_markdown(stamp),
            "",
            "`ihrcf_env/DeckLanding-v2` per level (see [tasks](tasks.md#decklanding-v2)) on the protocol's "
            f"test seeds from {TEST_SEEDS.start} up, the same seeds for every policy and camera. "
            "`blind:0.3` descends at 0.3 m/s with no lateral command; `scripted` is the package's landing "
            "controller on the fused estimate (own sensing only); a `.zip` is a saved stable-baselines3 "
            "policy, a `.npz` a saved numpy policy, recurrent (GRU) or not (MLP) "
            "([learning](learning.md)). The same figures for one row: "
            "`ihrcf-evaluate --level L --policy P --episodes N --camera-model C`.",
            "",
            table_markdown(rows),
            "",
        ]
    )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--episodes", type=int, default=len(TEST_SEEDS), help="test seeds per row (default: all)")
    ap.add_argument(
        "--policy",
        nargs="*",
        default=[],
        help="saved policies to add (a stable-baselines3 PPO .zip, a recurrent .npz)",
    )
    ap.add_argument(
        "--both-cameras",
        nargs="*",
        default=["moderate"],
        choices=list(LEVELS),
        help="levels also run with the rendered camera (default: moderate)",
    )
    ap.add_argument("--jobs", type=int, default=1, help="processes (default: 1)")
    ap.add_argument("--out", default="docs/benchmark-v2.md", help="the page to write")
    ap.add_argument("--cache", default=None, help="folder of finished rows to reuse (default: none)")
    args = ap.parse_args(argv)
    if not 1 <= args.episodes <= len(TEST_SEEDS):
        ap.error(f"argument --episodes: must be in 1..{len(TEST_SEEDS)}")
    if not 1 <= args.jobs <= 64:
        ap.error("argument --jobs: must be in 1..64")
    for path in args.policy:
        if not os.path.isfile(path):
            ap.error(f"argument --policy: no such file {path!r}")
    jobs = plan(args.episodes, args.policy, args.both_cameras)
    argv_shown = list(sys.argv[1:] if argv is None else argv)
    command = shlex.join(["python", "-m", "ihrcf_env.experiments.benchmark_v2", *argv_shown])
    started = time.perf_counter()
    date = datetime.date.today().isoformat()
    mach = machine()
    if args.jobs > 1:
        run = functools.partial(run_cached, cache=args.cache)
        with one_blas_thread():
            pool = multiprocessing.get_context("spawn").Pool(args.jobs)
        with pool:
            ran = dict(zip(jobs, pool.map(run, jobs, chunksize=1), strict=True))
    else:
        ran = {job: run_cached(job, args.cache) for job in jobs}
    rows = {job: row for job, (row, _) in ran.items()}
    cached = sum(hit for _, hit in ran.values())
    wall = time.perf_counter() - started
    done = f"{len(jobs)} rows of {args.episodes} episodes, {args.jobs} process(es)"
    if cached:
        done += f", {cached} of the rows from the cache of earlier runs (wall time: this run only)"
    stamp = Stamp(ihrcf_env.__version__, date, command, mach, done, wall)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(page_markdown(rows, stamp))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "BASELINES",
    "Job",
    "cache_key",
    "label",
    "load_row",
    "main",
    "page_markdown",
    "plan",
    "run_cached",
    "run_job",
    "table_markdown",
]
