"""Benchmarks that print figures: simulation speed and per-frame estimation cost.

    python -m ihrcf_env.benchmark                 # speed table (pinned to one core)
    python -m ihrcf_env.benchmark --steps 400 --sizes 0 128 256 512

Speed: env steps per second and real-time factor (simulated seconds per wall-clock second) of the
raw env with zero velocity actions over the "paper" deck profile, without a camera and with the
camera at each size (rendered once per control step). Estimation: tag detection + IHRCF + ATDA per
512x512 frame with the shipped calibration.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401  (registers the envs)


def speed(size: int, steps: int, control_hz: int = 20) -> tuple[float, float]:
    """(env steps per second, real-time factor) for camera ``size`` (0 = no camera)."""
    kw = {"camera": False} if size == 0 else {"camera_width": size, "camera_height": size}
    env = gym.make("ihrcf_env/DeckLandingRaw-v0", control_hz=control_hz, max_episode_steps=None, **kw)
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
    from ihrcf_env.calibration import default_calibration_path

    if not default_calibration_path().is_file():
        return None
    env = gym.make("ihrcf_env/DeckLanding-v0", max_episode_steps=None)
    try:
        obs, _ = env.reset(seed=0)
        wrapper = env
        while not hasattr(wrapper, "estimator"):
            wrapper = wrapper.env
        est = wrapper.estimator
        samples = []
        for _ in range(frames):
            raw = env.unwrapped._get_obs()
            t0 = time.perf_counter()
            est.estimate(raw["image"], raw["ranges"], raw["ranges_valid"].astype(bool))
            samples.append(time.perf_counter() - t0)
            env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return 1e3 * float(np.mean(samples))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=300, help="timed env steps per configuration")
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=[0, 128, 256, 512], help="camera sizes (0 = none)"
    )
    ap.add_argument("--frames", type=int, default=100, help="frames for the estimation timing")
    ap.add_argument("--all-cores", action="store_true", help="do not pin the process to one core")
    args = ap.parse_args(argv)
    if not args.all_cores and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    print(
        f"ihrcf_env {ihrcf_env.__version__}, Python {sys.version.split()[0]}, control 20 Hz, physics 240 Hz"
    )
    print(f"{'camera':>10} {'steps/s':>10} {'real-time factor':>18}")
    for size in args.sizes:
        sps, rtf = speed(size, args.steps)
        label = "none" if size == 0 else f"{size}x{size}"
        print(f"{label:>10} {sps:10.1f} {rtf:17.2f}x", flush=True)
    ms = estimation_ms(args.frames)
    if ms is None:
        print("estimation: no shipped calibration file; run python -m ihrcf_env.calibrate")
    else:
        print(f"estimation (detection + IHRCF + ATDA, 512x512): {ms:.2f} ms per frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
