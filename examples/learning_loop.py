"""A learning-loop skeleton: vectorised envs with the flat estimator observation.

Two processes run ``ihrcf_env/DeckHover-v0`` with ``flatten=True`` (one float32 vector of 39
values: ranges, validity flags, IMU, then IHRCF, ATDA and ground-truth deck poses) under
``gymnasium.vector.AsyncVectorEnv``. The policy here is a simple proportional tracker on the IHRCF
block (or uniform random actions with ``--policy random``); swap in your learner.

    python examples/learning_loop.py --steps 100 --policy tracker
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.wrappers.estimates import flat_slices

IHRCF = flat_slices()["ihrcf"]  # position (3), euler (3), valid (1) inside the flat observation


def make_env(max_episode_steps: int) -> Callable[[], gym.Env]:
    def thunk() -> gym.Env:
        return gym.make(
            "ihrcf_env/DeckHover-v0",
            flatten=True,
            deck_profile="sea_state",
            max_episode_steps=max_episode_steps,
        )

    return thunk


def tracker(obs: np.ndarray) -> np.ndarray:
    """Batch policy: move over the deck (IHRCF x, y in the body frame) and hold altitude."""
    est = obs[:, IHRCF]
    valid = est[:, 6:7]
    act = np.zeros((obs.shape[0], 4), dtype=np.float32)
    act[:, 0:2] = np.clip(0.8 * est[:, 0:2], -1.0, 1.0)
    act[:, 3] = np.clip(0.8 * est[:, 5], -1.0, 1.0)
    return act * valid


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=100, help="vector steps")
    ap.add_argument("--num-envs", type=int, default=2)
    ap.add_argument("--episode-steps", type=int, default=60, help="max_episode_steps of each env")
    ap.add_argument("--policy", choices=("tracker", "random"), default="tracker")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    with one_blas_thread():  # one BLAS thread per env process (see docs/learning.md)
        envs = gym.vector.AsyncVectorEnv([make_env(args.episode_steps) for _ in range(args.num_envs)])
    try:
        obs, _ = envs.reset(seed=args.seed)
        returns = np.zeros(args.num_envs)
        finished: list[float] = []
        t0 = time.perf_counter()
        for _ in range(args.steps):
            act = tracker(obs) if args.policy == "tracker" else envs.action_space.sample()
            obs, reward, terminated, truncated, _ = envs.step(act)
            returns += reward
            for i in np.flatnonzero(terminated | truncated):
                finished.append(float(returns[i]))
                returns[i] = 0.0
        wall = time.perf_counter() - t0
    finally:
        envs.close()
    rate = args.num_envs * args.steps / wall
    print(f"{args.num_envs} envs x {args.steps} steps in {wall:.1f} s ({rate:.1f} env steps/s)")
    print(f"observation {obs.shape}, finished episodes: {len(finished)}", end="")
    print(f", mean return {np.mean(finished):.1f}" if finished else "")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
