"""``ihrcf-benchmark`` (``python -m ihrcf_env.benchmark``): print the speed and accuracy figures.

The measurements are in :mod:`ihrcf_env.experiments.speed` (env and component speed),
:mod:`ihrcf_env.experiments.camera_realism` (the realistic camera's cost) and
:mod:`ihrcf_env.experiments.accuracy` (the paper's hover); this module runs them and prints (and
with ``--markdown`` writes) the tables.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.cmdline.common import check_output, command_main, int_in, make_parser, write_whole
from ihrcf_env.core.metrics import table2_markdown
from ihrcf_env.core.threads import limit_blas_threads
from ihrcf_env.experiments.accuracy import accuracy
from ihrcf_env.experiments.camera_realism import realism_cost_ms
from ihrcf_env.experiments.speed import (
    component_costs,
    estimation_ms,
    mode_speeds,
    projected_step_costs,
    raw_speed,
    vector_scaling,
)
from ihrcf_env.experiments.vector_speed import (
    ACTIONS,
    PairedSpeed,
    VectorSpeed,
    markdown_table,
    process_speed,
    single_speed,
    vector_speed,
)
from ihrcf_env.vector.checks import MAX_ENVS

MILD_DISTORTION = (-0.05, 0.0)
#: ``--vector``'s N when it has no values.
VECTOR_NS = (1, 8, 32, 128)
#: Most rounds of ``--rounds``.
MAX_ROUNDS = 100
#: Most processes of ``--processes``.
MAX_PROCESSES = 64
#: Bounds (px) of a camera size of --sizes other than 0: the env's camera sizes.
CAMERA_SIZES = (16, 4096)
#: Options of the envs the vector comparison times (as ``gym.make`` gives them otherwise).
VECTOR_OPTIONS: dict[str, object] = {"camera_model": "projected"}


def _camera_mode_report(steps: int, frames: int, vector: bool) -> list[str]:
    """Print and return (markdown) the wrapped env's speed per camera mode, the per-component cost
    table and, with ``vector``, the AsyncVectorEnv scaling."""
    out = ["", "| wrapped env, 1 m hover, all estimators | steps/s | real-time factor | vs image kept |"]
    out.append("|---|---|---|---|")
    print(f"\n{'wrapped env (1 m hover, ihrcf+atda+fused)':<44} {'steps/s':>9} {'RTF':>8} {'ratio':>7}")
    speeds = mode_speeds(steps)
    base = speeds[0].steps_per_s
    for sp in speeds:
        ratio = sp.steps_per_s / base
        print(f"{sp.label:<44} {sp.steps_per_s:9.1f} {sp.real_time_factor:7.2f}x {ratio:6.1f}x", flush=True)
        out.append(f"| {sp.label} | {sp.steps_per_s:.1f} | {sp.real_time_factor:.2f}x | {ratio:.1f}x |")
    costs = component_costs(frames)
    print("\nper-component cost (ms per control step, 512x512, 1 m hover):")
    out += ["", "| component | ms per step |", "|---|---|"]
    for name, ms in costs.items():
        print(f"  {name:<10} {ms:8.3f}")
        out.append(f"| {name} | {ms:.3f} |")
    split = projected_step_costs(steps)
    line = "inside the projected wrapped step (ms, warm): " + ", ".join(
        f"{k} {v:.3f}" for k, v in split.items()
    )
    print(line)
    out += ["", line + "."]
    if vector:
        v = vector_scaling()
        line = (
            f"AsyncVectorEnv, {v['workers']:.0f} workers, projected: {v['vector_steps_per_s']:.0f} steps/s "
            f"vs {v['single_steps_per_s']:.0f} for one env in-process: {v['factor']:.2f}x"
        )
        print(line)
        out += ["", line + "."]
    return out


def _vector_report(args: argparse.Namespace, cores: list[int] | None) -> list[str]:
    """Time the single env and the vector env for each N (and each number of processes, each
    pinned to its own core of ``cores`` when given) in ``args.rounds`` rounds, each starting with
    the single env; print and return the markdown table (medians over the rounds)."""
    ns = list(args.vector) or list(VECTOR_NS)
    common = {"env_id": args.id, "warmup": args.warmup, "actions": args.actions, **VECTOR_OPTIONS}
    pinned = "pinned to one core" if cores else "not pinned"
    limit_blas_threads(1)  # as the spawned processes run (one_blas_thread): the same for both sides
    head = (
        f"{args.id}, camera_model=projected, {args.actions} actions: single env {args.steps} steps, "
        f"vector env {args.vector_steps} steps per N, {args.warmup} untimed "
        f"first ({pinned}); one BLAS thread per process; {args.rounds} round(s), each timing the "
        "single env and then every configuration, ratios taken within a round"
    )
    print(head, flush=True)
    singles: list[float] = []
    runs: dict[tuple[int, int], list[VectorSpeed]] = {}
    for k in range(args.rounds):
        single = single_speed(steps=args.steps, **common)
        singles.append(single)
        print(f"round {k + 1}: single env {single:.1f} steps/s", flush=True)
        for n in ns:
            for p in args.processes:
                if p == 1:
                    row = vector_speed(num_envs=n, steps=args.vector_steps, **common)
                else:
                    row = process_speed(
                        num_envs=n, processes=p, steps=args.vector_steps, cores=cores, **common
                    )
                print(
                    f"round {k + 1}: N={n}, {p} process(es): {row.env_steps_per_s:.1f} "
                    f"env-steps/s ({row.ratio(single):.2f}x)",
                    flush=True,
                )
                runs.setdefault((n, p), []).append(row)
    table = markdown_table(statistics.median(singles), [PairedSpeed.of(r, singles) for r in runs.values()])
    print()
    print("\n".join(table))
    return [head + ".", "", *table]


def calibration_for(distortion: tuple[float, float]) -> str | None:
    """Calibration file for a camera with radial ``distortion`` (k1, k2), made by the calibrate CLI
    in a temporary folder; ``None`` (the shipped file) for the undistorted camera."""
    if tuple(distortion) == (0.0, 0.0):
        return None
    from ihrcf_env.cli.calibrate import main as calibrate

    path = str(Path(tempfile.mkdtemp(prefix="ihrcf_bench_")) / "calibration.json")
    k1, k2 = distortion
    argv = ["--k1", str(k1), "--k2", str(k2), "--quiet", "--output", path]
    with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
        if calibrate(argv) != 0:
            raise RuntimeError(f"calibration for distortion {distortion} failed")
    return path


DESCRIPTION = """\
Benchmarks that print figures: simulation speed, per-frame estimation cost, estimator accuracy.

Speed: env steps per second and real-time factor (simulated seconds per wall-clock second) of the
raw env with zero velocity actions over the "paper" deck profile, without a camera and with the
camera at each size (rendered once per control step); then the wrapped env (IHRCF + ATDA + fused)
at the 1 m hover per camera model (image kept, tag window, projected), the cost of each component
per control step, the parts of the projected wrapped step and, with --async-vector, AsyncVectorEnv
scaling with 2 workers. Estimation: tag detection + IHRCF + ATDA + fused per 512x512 frame with
the shipped calibration; the realistic camera's added cost per frame.

Accuracy: the paper's experiment. A drone hovering 1 m (and 2 m) above the deck on the "paper"
profile (ideal preset: zero velocity commands, the autopilot holds position; realistic preset: the
autopilot's navigation estimate drifts, so the drone is kept horizontally over the tag on the fused
estimate), mean absolute error of the ATDA, IHRCF and fused deck poses (body frame) against ground
truth over valid frames, for the ideal and the realistic sensor preset. --distortion adds the
tables with a mild radial lens distortion (k1 = -0.05), both calibrations first re-run for it.

examples:
  ihrcf-benchmark                 # speed + accuracy tables (pinned to one core)
  ihrcf-benchmark --steps 400 --sizes 0 128 256 512 --no-accuracy
  python -m ihrcf_env.benchmark --accuracy-frames 600 --markdown out/benchmark.md
  ihrcf-benchmark --vector 1 8 32 --processes 1 2   # the native vector env against the single env
"""


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = make_parser("benchmark", DESCRIPTION)
    ap.add_argument("--steps", type=int_in(1), default=300, help="timed env steps per configuration")
    ap.add_argument(
        "--sizes",
        type=int_in(0, CAMERA_SIZES[1]),
        nargs="+",
        default=[0, 128, 256, 512],
        help=f"camera sizes in px ({CAMERA_SIZES[0]}..{CAMERA_SIZES[1]}; 0 = none)",
    )
    ap.add_argument("--frames", type=int_in(1), default=100, help="frames for the estimation timing")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    ap.add_argument("--no-speed", action="store_true", help="skip the speed table")
    ap.add_argument("--no-accuracy", action="store_true", help="skip the accuracy tables")
    ap.add_argument("--accuracy-frames", type=int_in(1), default=600, help="frames per accuracy run (20 Hz)")
    ap.add_argument(
        "--altitudes", type=float, nargs="+", default=[1.0, 2.0], help="hover heights above the deck (m)"
    )
    ap.add_argument("--distortion", action="store_true", help="also the tables with lens distortion")
    ap.add_argument(
        "--async-vector",
        action="store_true",
        help="also AsyncVectorEnv scaling with 2 workers (uses 2 cores)",
    )
    vec = ap.add_argument_group(
        "native vector env", "--vector runs this comparison instead of the speed and accuracy tables"
    )
    vec.add_argument(
        "--vector",
        type=int_in(1, MAX_ENVS),
        nargs="*",
        default=None,
        metavar="N",
        help="time gym.make_vec(ID, num_envs=N) for each N against the single env "
        f"(no values: {' '.join(map(str, VECTOR_NS))}; default: not run)",
    )
    vec.add_argument(
        "--processes",
        type=int_in(1, MAX_PROCESSES),
        nargs="+",
        default=[1],
        metavar="P",
        help="with --vector: also P processes, each with its own vector env of N on its own core",
    )
    vec.add_argument("--id", default=ihrcf_env.LANDING_V1_ID, choices=ihrcf_env.VECTOR_IDS, help="env id")
    vec.add_argument("--vector-steps", type=int_in(1), default=20, help="timed vector steps per N")
    vec.add_argument(
        "--rounds",
        type=int_in(1, MAX_ROUNDS),
        default=3,
        help="rounds of the comparison, each timing the single env and then every configuration "
        "(the ratios are taken within a round, the table shows their median)",
    )
    vec.add_argument("--warmup", type=int_in(0), default=5, help="untimed steps before each timing")
    vec.add_argument("--actions", choices=ACTIONS, default="random", help="actions of the timed steps")
    ap.add_argument(
        "--markdown", default=None, help="also write the tables to this file (default: not written)"
    )
    return ap


@command_main("benchmark")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-benchmark``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    markdown = None if args.markdown is None else check_output(ap, "--markdown", args.markdown)
    if any(not (math.isfinite(a) and 0.3 <= a <= 10.0) for a in args.altitudes):
        ap.error(f"argument --altitudes: heights must be in [0.3, 10] m, got {args.altitudes}")
    small = [n for n in args.sizes if 0 < n < CAMERA_SIZES[0]]
    if small:
        ap.error(f"argument --sizes: a camera size is 0 (none) or at least {CAMERA_SIZES[0]} px, got {small}")
    report: list[str] = []
    if args.vector is None and args.processes != [1]:
        ap.error("argument --processes: only with --vector")
    if args.vector is None and args.no_speed and args.no_accuracy:
        ap.error("arguments --no-speed --no-accuracy: nothing left to run")
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if not args.all_cores and cores:
        os.sched_setaffinity(0, {cores[0]})
    print(
        f"ihrcf_env {ihrcf_env.__version__}, Python {sys.version.split()[0]}, control 20 Hz, physics 240 Hz"
    )
    if args.vector is not None:
        report = _vector_report(args, None if args.all_cores or not cores else cores)
        if markdown is not None:
            write_whole(markdown, "\n".join(report) + "\n")
            print(f"wrote {markdown}")
        return 0
    if not args.no_speed:
        report += ["| camera | env steps/s | real-time factor |", "|---|---|---|"]
        print(f"{'camera':>10} {'steps/s':>10} {'real-time factor':>18}")
        for size in args.sizes:
            sps, rtf = raw_speed(size, args.steps)
            label = "none" if size == 0 else f"{size}x{size}"
            print(f"{label:>10} {sps:10.1f} {rtf:17.2f}x", flush=True)
            report.append(f"| {label} | {sps:.1f} | {rtf:.2f}x |")
        report += _camera_mode_report(args.steps, args.frames, args.async_vector)
        ms = estimation_ms(args.frames)
        if ms is None:
            print("estimation: no shipped calibration file; run python -m ihrcf_env.calibrate")
        else:
            print(f"estimation (detection + IHRCF + ATDA + fused, 512x512): {ms:.2f} ms per frame")
            report += ["", f"Estimation (detection + IHRCF + ATDA + fused, 512x512): {ms:.2f} ms per frame."]
        cost = realism_cost_ms(args.frames)
        line = (
            f"realistic camera (512x512, 1 m hover): {cost['ideal_ms']:.1f} ms ideal render, "
            f"{cost['realistic_ms']:.1f} ms realistic, +{cost['added_ms']:.2f} ms per frame "
            f"(median +{cost['added_median_ms']:.2f}; post-processing {cost['processing_ms']:.2f} ms)"
        )
        print(line)
        report += ["", line[0].upper() + line[1:] + "."]
    if not args.no_accuracy:
        runs: list[tuple[str, float, tuple[float, float]]] = [
            (preset, alt, (0.0, 0.0)) for preset in ("ideal", "realistic") for alt in args.altitudes
        ]
        if args.distortion:
            runs += [(preset, 1.0, MILD_DISTORTION) for preset in ("ideal", "realistic")]
        for preset, alt, dist in runs:
            t0 = time.perf_counter()
            res = accuracy(
                args.accuracy_frames,
                distortion=dist,
                calibration=calibration_for(dist),
                env_kwargs={"sensor_preset": preset},
                altitude=alt,
                # the realistic autopilot drifts ~0.4 m in 30 s: keep the tag in view on the fused estimate
                track="fused" if preset == "realistic" else None,
            )
            kind = "" if dist == (0.0, 0.0) else f", distortion k1 = {dist[0]}"
            text = table2_markdown(res, f"sensor_preset={preset!r}, hover {alt:g} m{kind}")
            print()
            print(text)
            print(f"({time.perf_counter() - t0:.0f} s)", flush=True)
            report += ["", text]
    if markdown is not None:
        write_whole(markdown, "\n".join(report) + "\n")
        print(f"wrote {markdown}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "DESCRIPTION",
    "MAX_PROCESSES",
    "MAX_ROUNDS",
    "MILD_DISTORTION",
    "VECTOR_NS",
    "VECTOR_OPTIONS",
    "build_parser",
    "calibration_for",
    "main",
]
