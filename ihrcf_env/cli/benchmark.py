"""Benchmarks that print figures: simulation speed, per-frame estimation cost, estimator accuracy.

    python -m ihrcf_env.benchmark                 # speed + accuracy tables (pinned to one core)
    python -m ihrcf_env.benchmark --steps 400 --sizes 0 128 256 512 --no-accuracy
    python -m ihrcf_env.benchmark --accuracy-frames 600 --markdown out/benchmark.md

Speed: env steps per second and real-time factor (simulated seconds per wall-clock second) of the
raw env with zero velocity actions over the "paper" deck profile, without a camera and with the
camera at each size (rendered once per control step). Estimation: tag detection + IHRCF + ATDA per
512x512 frame with the shipped calibration.

Accuracy: the paper's experiment. A motionless hovering drone 1 m above the deck on the "paper"
profile (the drone holds its world position; the deck moves beneath it), mean absolute error of
the IHRCF and ATDA deck poses (body frame) against ground truth over valid frames, for ideal and
realistic ToF sensors, with and without a mild radial lens distortion (k1 = -0.05); for the distorted
camera both calibrations are first re-run for it (``python -m ihrcf_env.calibrate --k1 -0.05``), so
ATDA's chessboard K/dist model the lens while IHRCF's homography (a pinhole model) does not.
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


def speed(size: int, steps: int, control_hz: int = 20) -> tuple[float, float]:
    """(env steps per second, real-time factor) for camera ``size`` (0 = no camera)."""
    kw = {"camera": False} if size == 0 else {"camera_width": size, "camera_height": size}
    env = gym.make("ihrcf_env/DeckLandingRaw-v0", control_hz=control_hz, max_episode_steps=steps + 10, **kw)
    try:
        env.reset(seed=0)
        a = np.zeros(4, dtype=np.float32)
        for _ in range(5):  # warm-up
            env.step(a)
        t0 = time.perf_counter()
        for _ in range(steps):
            env.step(a)
        wall = time.perf_counter() - t0
    finally:
        env.close()
    sps = steps / wall
    return sps, sps / control_hz


def estimation_ms(frames: int) -> float | None:
    """Mean wall time (ms) of detection + IHRCF + ATDA on rendered 512x512 frames, or None without
    a shipped calibration."""
    from ihrcf_env.core.calibration import default_calibration_path

    if not default_calibration_path().is_file():
        return None
    env = gym.make("ihrcf_env/DeckLanding-v0", max_episode_steps=frames + 10)
    try:
        obs, _ = env.reset(seed=0)
        est = env.get_wrapper_attr("estimator")
        samples = []
        for _ in range(frames):
            raw = env.unwrapped._get_obs()  # type: ignore[attr-defined]  # the raw obs, image included
            t0 = time.perf_counter()
            est.estimate(raw["image"], raw["ranges"], raw["ranges_valid"].astype(bool))
            samples.append(time.perf_counter() - t0)
            env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return 1e3 * float(np.mean(samples))


MILD_DISTORTION = (-0.05, 0.0)


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
        ms = estimation_ms(args.frames)
        if ms is None:
            print("estimation: no shipped calibration file; run python -m ihrcf_env.calibrate")
        else:
            print(f"estimation (detection + IHRCF + ATDA, 512x512): {ms:.2f} ms per frame")
            report += ["", f"Estimation (detection + IHRCF + ATDA, 512x512): {ms:.2f} ms per frame."]
    if not args.no_accuracy:
        for noise in ("ideal", "realistic"):
            for dist in ((0.0, 0.0), MILD_DISTORTION):
                t0 = time.perf_counter()
                res = accuracy(args.accuracy_frames, noise, dist, calibration=calibration_for(dist))
                kind = "no distortion" if dist == (0.0, 0.0) else f"distortion k1 = {dist[0]}"
                text = table2_markdown(res, f"ToF {noise}, {kind}")
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
