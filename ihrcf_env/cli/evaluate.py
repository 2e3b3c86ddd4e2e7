"""``ihrcf-evaluate`` (``python -m ihrcf_env.evaluate``): run a landing policy over seeded episodes
and report.

The episodes run through the one episode loop, :func:`ihrcf_env.experiments.episode.run_episodes`
(results: :class:`~ihrcf_env.experiments.episode.EpisodeResult`); this module turns the POLICY
argument into a policy and checks the arguments before any env is built
(:mod:`ihrcf_env.cmdline.episode_args`, shared with ``ihrcf-record``) and formats the report
(:func:`summary`).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

import gymnasium as gym
import numpy as np

from ihrcf_env import LANDING_V1_ID, LANDING_V2_ID
from ihrcf_env.cmdline.common import command_main, int_in, make_parser
from ihrcf_env.cmdline.episode_args import (
    add_episode_arguments,
    check_episode_args,
    format_episode,
    make_env_and_policy,
)
from ihrcf_env.config.levels import TEST_SEEDS
from ihrcf_env.core.metrics import failure_groups, wilson_interval
from ihrcf_env.experiments.episode import EpisodeResult, run_episodes


def _stat(values: Sequence[float], unit: str, fmt: str = ".3f") -> str:
    if not values:
        return "n/a"
    return f"{np.mean(values):{fmt}} / {np.max(values):{fmt}} {unit}"


def summary(episodes: Sequence[EpisodeResult]) -> list[str]:
    """The report's lines; the last one is ``success K/N``."""
    n = len(episodes)
    ok = [e for e in episodes if e.outcome == "success"]
    touched = [e for e in episodes if e.touched_down]
    speeds = [e.speed for e in touched if e.speed is not None]
    tilts = [math.degrees(e.tilt) for e in touched if e.tilt is not None]
    offsets = [e.offset for e in touched if e.offset is not None]
    lo, hi = wilson_interval(len(ok), n)
    lines = [
        f"episodes {n}, success rate {len(ok) / n:.1%} (95 % Wilson interval {lo:.1%}..{hi:.1%}), "
        f"mean return {np.mean([e.ret for e in episodes]):.2f}",
        f"touchdown (mean / max over the {len(touched)} episodes that touched down): relative vertical "
        f"speed {_stat(speeds, 'm/s')}, relative tilt {_stat(tilts, 'deg', '.2f')}, offset from the tag "
        f"centre {_stat(offsets, 'm')}",
        f"time to land (successes, mean / max): {_stat([e.time for e in ok], 's', '.1f')}",
    ]
    failures = failure_groups(episodes)
    if failures:
        lines.append("failures: " + "; ".join(f"{k} x{v}" for k, v in failures))
    lines.append(f"success {len(ok)}/{n}")
    return lines


DESCRIPTION = f"""\
Run a landing policy over seeded episodes and report.

POLICY is one of
  scripted   the package's landing controller on the landing observation (own sensing only,
             never ground truth); needs a landing env ({LANDING_V1_ID} or {LANDING_V2_ID})
  blind:VZ   constant descent at VZ m/s (> 0), no lateral command
  FILE.npz   a saved recurrent or MLP policy (ihrcf_env.control.gru_policy / mlp_policy; numpy only)
  FILE.zip   a saved stable-baselines3 policy (--algo names its class), run deterministically;
             needs stable-baselines3 (pip install ".[rl]")

Prints one line per episode (unless --quiet), then the success rate, the touchdown relative
vertical speed / relative tilt / horizontal offset from the tag centre (mean, max), the time to
land, the failures with their figures and, as the last line, "success K/N".

The benchmark protocol of {LANDING_V2_ID}: --level L runs that level's test seeds
({TEST_SEEDS.start}..{TEST_SEEDS.stop - 1}, unless --seed is given) on {LANDING_V2_ID}.

examples:
  ihrcf-evaluate --policy scripted --level moderate --episodes 100 --camera-model projected
  ihrcf-evaluate --policy blind:0.3 --episodes 50 --camera-model projected --option wind=false
  ihrcf-evaluate --policy scripted --episodes 10 --seed 100
  python -m ihrcf_env.evaluate --policy ppo_landing.zip --episodes 50 --camera-model rendered
"""


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = make_parser("evaluate", DESCRIPTION)
    add_episode_arguments(ap)
    ap.add_argument("--episodes", type=int_in(1), default=10, help="episodes, one seed each (>= 1)")
    ap.add_argument(
        "--record",
        metavar="DIR",
        default=None,
        help="write a Rerun recording (.rrd) of each failed episode into DIR (needs the [viewer] extra; "
        "default: none)",
    )
    ap.add_argument("--record-all", action="store_true", help="with --record: record every episode")
    ap.add_argument("--quiet", action="store_true", help="only the summary")
    return ap


def _check_record_dir(ap: argparse.ArgumentParser, directory: str) -> None:
    """``ap.error`` naming ``--record`` unless ``directory`` is a folder recordings may be written
    into (made if missing) and the Rerun SDK is installed."""
    from ihrcf_env.record import RecordingPathError, RerunMissingError, check_record_dir, import_rerun

    try:
        import_rerun()
        check_record_dir(directory)
    except (RecordingPathError, RerunMissingError) as e:
        ap.error(f"argument --record: {e}")


def _record_failures(ap: argparse.ArgumentParser, env: gym.Env, args: argparse.Namespace) -> gym.Env:
    """``env`` recording its failed episodes (each with ``--record-all``) into ``--record``."""
    from ihrcf_env.record import RecordingPathError, RerunMissingError, record_failures

    try:
        return record_failures(env, args.record, args.env_id, args.record_all)
    except (RecordingPathError, RerunMissingError) as e:
        ap.error(f"argument --record: {e}")


@command_main("evaluate")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-evaluate``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    check_episode_args(ap, args)
    spec = args.policy
    if args.record_all and args.record is None:
        ap.error("argument --record-all: needs --record DIR")
    if args.record is not None:
        _check_record_dir(ap, args.record)
    env, policy, kwargs = make_env_and_policy(ap, args)
    try:
        if args.record is not None:
            env = _record_failures(ap, env, args)
        t0 = time.perf_counter()
        results = run_episodes(
            env,
            policy,
            args.episodes,
            args.seed,
            None if args.quiet else lambda e: print(format_episode(e), flush=True),
        )
        wall = time.perf_counter() - t0
    finally:
        env.close()
    print(
        f"\n{args.env_id}, policy {spec}, seeds {args.seed}..{args.seed + args.episodes - 1}, "
        f"{' '.join(f'{k}={v}' for k, v in kwargs.items()) or 'env defaults'}, wall {wall:.0f} s"
    )
    for line in summary(results):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = ["DESCRIPTION", "build_parser", "main", "summary"]
