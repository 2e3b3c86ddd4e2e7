"""``ihrcf-record`` (``python -m ihrcf_env.record``): fly one episode and write a Rerun recording.

The env and the policy are chosen by the arguments of ``ihrcf-evaluate``
(:func:`ihrcf_env.cmdline.episode_args.add_episode_arguments`, checked the same way); the episode runs
through :func:`ihrcf_env.experiments.episode.run_episode` inside
:class:`~ihrcf_env.record.RecordEpisode`. Every check (the output file, the Rerun SDK, the viewer
for ``--spawn``) runs before the env is made.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from ihrcf_env.cmdline.common import command_main, make_parser
from ihrcf_env.cmdline.episode_args import (
    add_episode_arguments,
    check_episode_args,
    format_episode,
    make_env_and_policy,
)
from ihrcf_env.experiments.episode import run_episode
from ihrcf_env.record import (
    RecordEpisode,
    RecordingPathError,
    RerunMissingError,
    ViewerMissingError,
    check_recording_path,
    check_viewer,
    import_rerun,
)

__all__ = ["build_parser", "main"]

DESCRIPTION = """\
Fly one episode of a landing env with a policy and write a Rerun recording of it: the deck and the
drone in 3D, the ToF beams, the camera's tag corners (and image with the rendered camera), each
estimator's deck pose against the truth, actions, reward terms, wind, faults and the outcome, on
the simulated-time timeline. Open the file with `rerun FILE.rrd`. Needs the [viewer] extra
(pip install "ihrcf-env[viewer]"). An existing FILE is replaced only if its name ends in .rrd.

examples:
  ihrcf-record --level rough --policy scripted --camera-model projected --out landing.rrd
  ihrcf-record --policy blind:0.3 --spawn
"""


def _require_rerun(ap: argparse.ArgumentParser) -> None:
    """``ap.error`` saying how to install the Rerun SDK if it is missing."""
    try:
        import_rerun()
    except RerunMissingError as e:
        ap.error(str(e))


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = make_parser("record", DESCRIPTION)
    add_episode_arguments(ap)
    out = ap.add_mutually_exclusive_group(required=True)
    out.add_argument(
        "--out",
        metavar="FILE.rrd",
        default=None,
        help="the recording file to write (default: none; give --out or --spawn)",
    )
    out.add_argument(
        "--spawn", action="store_true", help="send the recording to a Rerun viewer (started; 'rerun' on PATH)"
    )
    ap.set_defaults(episodes=1)
    return ap


@command_main("record")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-record``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    _require_rerun(ap)
    if args.out is not None:
        if "{" in args.out or "}" in args.out:
            ap.error(f"argument --out: {args.out!r}: braces are not allowed in the file name")
        try:
            check_recording_path(args.out)
        except RecordingPathError as e:
            ap.error(f"argument --out: {e}")
    if args.spawn:
        try:
            check_viewer()
        except ViewerMissingError as e:
            ap.error(f"argument --spawn: {e}")
    check_episode_args(ap, args)
    env, policy, _ = make_env_and_policy(ap, args)
    try:
        try:
            env = RecordEpisode(env, args.out, spawn=args.spawn)
        except (RecordingPathError, RerunMissingError, ViewerMissingError) as e:
            ap.error(f"cannot record {args.env_id}: {e}")
        result = run_episode(env, policy, args.seed)
    finally:
        env.close()
    print(format_episode(result))
    print(f"recording: {args.out}" if args.out is not None else "recording sent to the Rerun viewer")
    return 0
