"""The command line of ``examples/train_ppo.py`` (PPO on the landing tasks): its options and their
checks, kept apart so the example stays a thin script (no stable-baselines3 import here)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from ihrcf_env import VECTOR_IDS
from ihrcf_env.rl.envs import default_env_id, name_value

TRAIN_SEED_BASE, EVAL_SEED_BASE, DAGGER_SEED_BASE = 10_000, 20_000, 30_000
INT_OPTIONS = (
    ("--total-steps", 1_000_000, 1, "PPO environment steps in all"),
    ("--seed", 0, 0, "seed of the network, training and DAgger episodes"),
    (
        "--n-envs",
        2,
        1,
        "training envs (processes of a SubprocVecEnv if > 1, or with --vector one vector env)",
    ),
    ("--curriculum-steps", 0, 0, "steps of a start curriculum from low near the tag (0: off)"),
    ("--n-steps", 1024, 1, "rollout length per env"),
    ("--batch-size", 256, 1, "PPO minibatch"),
    ("--n-epochs", 10, 1, "PPO epochs per rollout"),
    ("--eval-every", 50_000, 1, "steps between evaluations"),
    ("--eval-episodes", 20, 1, "episodes per evaluation"),
    ("--checkpoint-every", 50_000, 1, "steps between checkpoints"),
    ("--dagger-rounds", 0, 0, "DAgger warm start from the scripted landing (0: off)"),
    ("--dagger-episodes", 30, 1, "episodes per DAgger round"),
    ("--critic-warmup-steps", 50_000, 0, "after DAgger: PPO steps that train the critic only"),
    ("--frame-stack", 1, 1, "observations the policy reads, the newest last (its memory)"),
)


def parse_args(
    argv: Sequence[str] | None, description: str | None
) -> tuple[argparse.ArgumentParser, argparse.Namespace]:
    """The parser and the checked options of ``argv`` (argparse exits with status 2 on a bad one)."""
    ap = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    for flag, default, least, text in INT_OPTIONS:  # (name, default, minimum, help)
        ap.add_argument(flag, type=int, default=default, help=f"{text} (>= {least})")
    ap.add_argument("--out", type=Path, default=Path("out/ppo"))
    ap.add_argument("--resume", action="store_true", help="continue from OUT/checkpoints/latest.zip")
    ap.add_argument("--env-id", default=None, help="default: ihrcf_env/DeckLanding-v1 (v0 if v1 is absent)")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    ap.add_argument("--max-episode-steps", type=int, default=None, help="default: the env's limit")
    ap.add_argument("--deck-motion", action="store_true", help="v1 deck_motion=True (CLI detects it)")
    ap.add_argument(
        "--vector",
        action="store_true",
        help="train on the id's native vector env in this process (ihrcf_env.rl.vec), not SubprocVecEnv",
    )
    ap.add_argument(
        "--workers",
        type=int,
        default=1,
        help="with --vector: processes sharing the envs (gym.make_vec workers)",
    )
    ap.add_argument("--ent-coef", type=float, default=0.0, help="PPO entropy bonus")
    ap.add_argument("--init-action-mean", type=float, nargs="+", default=None, help="e.g. 0 0 -0.3 0")
    ap.add_argument("--log-std-init", type=float, default=0.0, help="initial log std of the actions")
    ap.add_argument("--reward-weights", nargs="*", type=name_value, default=[], metavar="NAME=W")
    ap.add_argument("--learning-rate", type=float, default=None, help="3e-4; with --resume: replaces it")
    ap.add_argument("--gamma", type=float, default=0.99)
    ap.add_argument("--drop-inputs", nargs="*", default=[], help="observation fields the policy ignores")
    ap.add_argument("--net-arch", type=int, nargs="+", default=[64, 64], help="hidden layer sizes")
    ap.add_argument("--max-wall-min", type=float, default=None, help="wall budget (min), resumes counted")
    args = ap.parse_args(None if argv is None else list(argv))
    for flag, _, least, _ in INT_OPTIONS:
        if getattr(args, flag[2:].replace("-", "_")) < least:
            ap.error(f"{flag} must be >= {least}")
    if args.max_wall_min is not None and not args.max_wall_min > 0:
        ap.error("--max-wall-min must be > 0 (minutes)")
    env_id = args.env_id or default_env_id()
    if args.vector and env_id not in VECTOR_IDS:
        ap.error(f"--vector: {env_id} has no native vector env (those with one: {', '.join(VECTOR_IDS)})")
    if args.workers != 1 and not args.vector:
        ap.error("--workers: only with --vector (SubprocVecEnv already runs one process per env)")
    if args.workers < 1:
        ap.error(f"--workers: at least 1, got {args.workers}")
    if args.frame_stack > 64:
        ap.error(f"--frame-stack must be <= 64, got {args.frame_stack}")
    if args.vector and args.frame_stack > 1:
        ap.error("--vector: the native vector env gives single observations; use --frame-stack without it")
    if args.vector and args.curriculum_steps:
        ap.error("--vector: the start curriculum wraps single envs; use it without --vector")
    args.env_id = env_id
    return ap, args


__all__ = [
    "INT_OPTIONS",
    "parse_args",
]
