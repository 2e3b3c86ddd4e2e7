"""Benchmarks that print figures: simulation speed, per-frame estimation cost, estimator accuracy.

    python -m ihrcf_env.benchmark                 # speed + accuracy tables (pinned to one core)
    python -m ihrcf_env.benchmark --steps 400 --sizes 0 128 256 512 --no-accuracy
    python -m ihrcf_env.benchmark --accuracy-frames 600 --markdown out/benchmark.md

Speed: env steps per second and real-time factor (simulated seconds per wall-clock second) of the
raw env with zero velocity actions over the "paper" deck profile, without a camera and with the
camera at each size (rendered once per control step); then the wrapped env (IHRCF + ATDA + fused)
at the 1 m hover per camera model (image kept, tag window, projected: ratios from one run), the cost
of each component per control step (:func:`ihrcf_env.experiments.speed.component_costs`, timed
between full renders), the parts of the projected wrapped step timed inside it
(:func:`~ihrcf_env.experiments.speed.projected_step_costs`) and, with
``--vector``, ``AsyncVectorEnv`` scaling with 2 workers. Estimation: tag detection + IHRCF + ATDA +
fused per 512x512 frame with the shipped calibration.

Accuracy: the paper's experiment. A hovering drone 1 m (and 2 m) above the deck on the "paper"
profile (ideal preset: zero velocity commands, the autopilot holds position; realistic preset: the
autopilot's navigation estimate drifts, so the drone is kept horizontally over the tag on the fused
estimate, altitude still on the autopilot; the deck moves beneath it), mean absolute error of the ATDA,
IHRCF and fused deck poses (body frame) against ground truth over valid frames, for the ideal and
the realistic sensor preset. ``--distortion`` adds the tables with a mild radial lens distortion
(k1 = -0.05); for the distorted camera both calibrations are first re-run for it
(``python -m ihrcf_env.calibrate --k1 -0.05``), so ATDA's chessboard K/dist model the lens while
IHRCF's homography (a pinhole model) does not.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.metrics import table2_markdown
from ihrcf_env.experiments.accuracy import accuracy
from ihrcf_env.experiments.speed import (
    component_costs,
    mode_speeds,
    projected_step_costs,
    steps_per_second,
    vector_scaling,
)
from ihrcf_env.sim.sensors.camera import realism_cost_ms


def speed(size: int, steps: int, control_hz: int = 20) -> tuple[float, float]:
    """(env steps per second, real-time factor) for camera ``size`` (0 = no camera)."""
    kw = {"camera": False} if size == 0 else {"camera_width": size, "camera_height": size}
    env = gym.make("ihrcf_env/DeckHoverRaw-v0", control_hz=control_hz, max_episode_steps=steps + 10, **kw)
    try:
        sps = steps_per_second(env, steps)
    finally:
        env.close()
    return sps, sps / control_hz


def estimation_ms(frames: int) -> float | None:
    """Mean wall time (ms) of one frame through detection + IHRCF + ATDA + fused (a separate
    estimator fed the same rendered 512x512 frames, ranges and IMU as the env's), or None without a
    shipped calibration."""
    from ihrcf_env.core.calibration import Calibration, default_calibration_path
    from ihrcf_env.core.estimators import ImuSample
    from ihrcf_env.wrappers import estimator_from_calibration

    if not default_calibration_path().is_file():
        return None
    env = gym.make("ihrcf_env/DeckHoverRaw-v0", max_episode_steps=frames + 10)
    try:
        deck = env.unwrapped.config.world.deck  # type: ignore[attr-defined]
        est = estimator_from_calibration(
            Calibration.load(default_calibration_path()), deck.tag_size, deck.tag_id
        )
        raw, info = env.reset(seed=0)
        samples = []
        for _ in range(frames):
            imu = raw["imu"]
            t0 = time.perf_counter()
            frame = est.frame(
                raw["image"],
                raw["ranges"],
                raw["ranges_valid"].astype(bool),
                time=float(info["time"]),
                imu=ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"]),
            )
            est.update(frame)
            samples.append(time.perf_counter() - t0)
            raw, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return 1e3 * float(np.mean(samples))


MILD_DISTORTION = (-0.05, 0.0)


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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=300, help="timed env steps per configuration")
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=[0, 128, 256, 512], help="camera sizes (0 = none)"
    )
    ap.add_argument("--frames", type=int, default=100, help="frames for the estimation timing")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    ap.add_argument("--no-speed", action="store_true", help="skip the speed table")
    ap.add_argument("--no-accuracy", action="store_true", help="skip the accuracy tables")
    ap.add_argument("--accuracy-frames", type=int, default=600, help="frames per accuracy run (20 Hz)")
    ap.add_argument(
        "--altitudes", type=float, nargs="+", default=[1.0, 2.0], help="hover heights above the deck (m)"
    )
    ap.add_argument("--distortion", action="store_true", help="also the tables with lens distortion")
    ap.add_argument(
        "--vector", action="store_true", help="also AsyncVectorEnv scaling with 2 workers (uses 2 cores)"
    )
    ap.add_argument("--markdown", type=str, default=None, help="also write the tables to this file")
    args = ap.parse_args(argv)
    report: list[str] = []
    if not args.all_cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    print(
        f"ihrcf_env {ihrcf_env.__version__}, Python {sys.version.split()[0]}, control 20 Hz, physics 240 Hz"
    )
    if not args.no_speed:
        report += ["| camera | env steps/s | real-time factor |", "|---|---|---|"]
        print(f"{'camera':>10} {'steps/s':>10} {'real-time factor':>18}")
        for size in args.sizes:
            sps, rtf = speed(size, args.steps)
            label = "none" if size == 0 else f"{size}x{size}"
            print(f"{label:>10} {sps:10.1f} {rtf:17.2f}x", flush=True)
            report.append(f"| {label} | {sps:.1f} | {rtf:.2f}x |")
        report += _camera_mode_report(args.steps, args.frames, args.vector)
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
    if args.markdown:
        path = Path(args.markdown)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(report) + "\n")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
