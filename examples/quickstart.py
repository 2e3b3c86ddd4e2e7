"""Quick start: make the env, hover for a few seconds, print ground truth and save camera frames.

python examples/quickstart.py --seconds 5 --out out/quickstart
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401  (registers ihrcf_env/DeckHover-v0)


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds (default 5)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("out/quickstart"), help="folder for the PNG frames")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)

    env = gym.make("ihrcf_env/DeckHover-v0", render_mode="rgb_array", raw=True, chase_size=(640, 480))
    try:
        obs, info = env.reset(seed=args.seed)
        hz = env.unwrapped.config.world.control_hz
        n = int(round(args.seconds * hz))
        cols = ("t (s)", "deck x", "deck y", "deck z", "roll", "pitch", "yaw")
        print(" ".join(f"{c:>8}" for c in cols), " ranges (m)")
        for k in range(n):
            obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
            if k % hz == 0 or k == n - 1:
                x, y, z = info["deck_position_body"]
                r, p, yw = np.degrees(info["deck_euler_body"])
                vals = (info["time"], x, y, z, r, p, yw)
                print(" ".join(f"{v:8.3f}" for v in vals), "", obs["ranges"].round(3))
            if terminated or truncated:
                break
        cv2.imwrite(str(args.out / "camera.png"), cv2.cvtColor(obs["image"], cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(args.out / "chase.png"), cv2.cvtColor(env.render(), cv2.COLOR_RGB2BGR))
    finally:
        env.close()
    print(f"saved {args.out / 'camera.png'} and {args.out / 'chase.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
