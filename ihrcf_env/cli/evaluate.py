"""``ihrcf-evaluate`` (``python -m ihrcf_env.evaluate``): run a landing policy over seeded episodes
and report.

The episodes run through the one episode loop, :func:`ihrcf_env.experiments.episode.run_episodes`
(results: :class:`~ihrcf_env.experiments.episode.EpisodeResult`); this module turns the POLICY
argument into a policy (:func:`~ihrcf_env.experiments.policies.make_policy`), checks the arguments
before any env is built and formats the report (:func:`format_episode`, :func:`summary`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env import LANDING_V1_ID, LANDING_V2_ID
from ihrcf_env.cli.common import MAX_SEED, command_main, int_in, make_parser, seed_type
from ihrcf_env.config.levels import LEVELS, TEST_SEEDS
from ihrcf_env.control.forecast_landing import FORECAST_POLICY_OPTIONS
from ihrcf_env.control.gru_policy import GruPolicy, PolicyFileError
from ihrcf_env.control.mlp_policy import MlpPolicy
from ihrcf_env.core.metrics import failure_groups, wilson_interval
from ihrcf_env.experiments.episode import EpisodeResult, run_episodes
from ihrcf_env.experiments.policies import (
    FORECAST_POLICY,
    SB3_ALGOS,
    SCRIPTED_ESTIMATOR,
    PolicyError,
    make_policy,
    with_deck_motion,
)


def format_episode(ep: EpisodeResult) -> str:
    """One line per episode: seed, outcome, end time, return, touchdown figures, crash reason."""
    td = (
        f"speed {ep.speed:.3f} m/s  tilt {math.degrees(ep.tilt):5.2f} deg  offset {ep.offset:.3f} m"
        if ep.speed is not None and ep.tilt is not None and ep.offset is not None
        else "no touchdown"
    )
    why = f"  ({ep.reason})" if ep.reason else ""
    return f"seed {ep.seed:5d}  {ep.outcome:8s} t {ep.time:6.2f} s  return {ep.ret:8.2f}  {td}{why}"


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


def _parse_options(ap: argparse.ArgumentParser, items: Sequence[str]) -> dict[str, Any]:
    """``--option KEY=VALUE`` items as env options (VALUE as JSON, else as text)."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.isidentifier():
            ap.error(f"argument --option: {item!r} is not KEY=VALUE")
        try:
            out[key] = json.loads(text)
        except RecursionError:
            ap.error(f"argument --option: the value of {key} is nested too deeply")
        except ValueError:
            out[key] = text
    if "render_mode" in out:
        ap.error("argument --option: render_mode is not an option of ihrcf-evaluate (it renders nothing)")
    return out


#: Env options the scripted and blind baselines need as they are (option -> the value they fly).
BASELINE_OPTIONS: dict[str, object] = {"action_mode": "velocity"}


def _check_baseline_options(ap: argparse.ArgumentParser, policy: str, options: dict[str, Any]) -> None:
    """``ap.error`` naming the option if ``options`` change what the scripted/blind baselines need:
    velocity actions and, for the scripted policy, the fused estimate it reads."""
    for key, want in BASELINE_OPTIONS.items():
        if key in options and options[key] != want:
            ap.error(
                f"argument --option: {key}={options[key]!r}: the {policy.partition(':')[0]} policy "
                f"flies {key}={want!r}"
            )
    if policy in ("scripted", FORECAST_POLICY) and "estimators" in options:
        names = options["estimators"]
        if isinstance(names, str) or not isinstance(names, list) or SCRIPTED_ESTIMATOR not in names:
            ap.error(
                f"argument --option: estimators={names!r}: the scripted policy reads the "
                f"{SCRIPTED_ESTIMATOR!r} estimate; keep {SCRIPTED_ESTIMATOR!r} in estimators"
            )


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


def add_episode_arguments(ap: argparse.ArgumentParser) -> None:
    """The arguments that choose the env and the policy (shared with ``ihrcf-record``); checked by
    :func:`_check_args`, turned into an env and a policy by :func:`make_env_and_policy`."""
    add_env_arguments(ap)
    ap.add_argument(
        "--policy",
        required=True,
        help="scripted | scripted-forecast | blind:VZ | a saved .npz (recurrent or MLP) | a "
        "stable-baselines3 .zip (required)",
    )
    ap.add_argument(
        "--algo", choices=SB3_ALGOS, default="PPO", help="stable-baselines3 class of a .zip policy"
    )
    ap.add_argument(
        "--deck-motion",
        action="store_true",
        help="v1 observation with the fused filter's deck motion (deck_motion=True); a saved policy "
        "trained so is detected without it",
    )


def add_env_arguments(ap: argparse.ArgumentParser) -> None:
    """The arguments that choose the env: id, level, options, first seed, camera model, sensor
    preset, step limit (shared with ``ihrcf-mavlink``); checked by :func:`check_env_args`, turned
    into ``gym.make`` keywords by :func:`env_kwargs`."""
    ap.add_argument(
        "--env-id",
        default=None,
        help=f"registered ihrcf_env env id (default: {LANDING_V1_ID}; with --level {LANDING_V2_ID})",
    )
    ap.add_argument(
        "--level", choices=tuple(LEVELS), default=None, help=f"a level of {LANDING_V2_ID} (default: none)"
    )
    ap.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an env option (repeatable); VALUE is read as JSON (true, 0.5, a dict) or else as text",
    )
    ap.add_argument(
        "--seed",
        type=seed_type,
        default=None,
        help="first seed, an integer >= 0 (default: 0; the test seeds with --level)",
    )
    ap.add_argument(
        "--camera-model",
        choices=("rendered", "projected"),
        default=None,
        help="camera model (default: the env's)",
    )
    ap.add_argument(
        "--sensor-preset",
        choices=("ideal", "realistic"),
        default=None,
        help="sensor preset (default: the env's)",
    )
    ap.add_argument(
        "--max-steps", type=int_in(1), default=None, help="episode limit in steps (default: the env's)"
    )


#: Arguments that set an env option themselves: (attribute, flag, option key).
FLAG_OPTIONS: tuple[tuple[str, str, str], ...] = (
    ("level", "--level", "level"),
    ("camera_model", "--camera-model", "camera_model"),
    ("sensor_preset", "--sensor-preset", "sensor_preset"),
    ("max_steps", "--max-steps", "max_episode_steps"),
    ("deck_motion", "--deck-motion", "deck_motion"),
)


def _check_option_conflicts(ap: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``ap.error`` naming both if ``--option KEY=VALUE`` sets an option that a flag of its own
    (``--level``, ``--camera-model``, ...) sets to another value: one value per option."""
    for attr, flag, key in FLAG_OPTIONS:
        given = getattr(args, attr, None)
        if given is None or given is False or key not in args.options:
            continue
        if args.options[key] != given:
            shown = "" if given is True else f" {given}"
            ap.error(
                f"argument --option: {key}={args.options[key]!r} conflicts with {flag}{shown}; "
                "give the value once"
            )


def check_env_args(ap: argparse.ArgumentParser, args: argparse.Namespace, episodes: int = 1) -> None:
    """The checks of :func:`add_env_arguments` that need no env (``ap.error``, exit status 2,
    naming the argument); fills in the defaults of ``--env-id`` and ``--seed`` and parses the
    ``--option`` items into ``args.options``. ``episodes``: seeds used from ``--seed`` on."""
    if args.env_id is None:
        args.env_id = LANDING_V2_ID if args.level is not None else LANDING_V1_ID
    elif args.level is not None and args.env_id != LANDING_V2_ID:
        ap.error(f"argument --level: levels are of {LANDING_V2_ID}, not {args.env_id}")
    if args.seed is None:
        args.seed = TEST_SEEDS.start if args.level is not None else 0
    args.options = _parse_options(ap, args.option)
    _check_option_conflicts(ap, args)
    last = args.seed + episodes - 1
    if last > MAX_SEED:
        ap.error(f"argument --seed: the seeds {args.seed}..{last} go beyond {MAX_SEED}")
    spec_env = gym.registry.get(args.env_id)
    if spec_env is None:
        ap.error(f"argument --env-id: unknown env id {args.env_id!r}")
    if spec_env.namespace != "ihrcf_env":
        ours = ", ".join(k for k, v in gym.registry.items() if v.namespace == "ihrcf_env")
        ap.error(f"argument --env-id: {args.env_id!r} is not an ihrcf_env landing env (one of {ours})")


def env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The ``gym.make`` keywords of checked :func:`add_env_arguments` (:func:`check_env_args`)."""
    kwargs: dict[str, Any] = dict(args.options)
    if args.level is not None:
        kwargs["level"] = args.level
    if args.camera_model is not None:
        kwargs["camera_model"] = args.camera_model
    if args.sensor_preset is not None:
        kwargs["sensor_preset"] = args.sensor_preset
    if args.max_steps is not None:
        kwargs["max_episode_steps"] = args.max_steps
    return kwargs


def _check_args(ap: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Every check that needs no env: ``ap.error`` (exit status 2) naming the argument."""
    check_env_args(ap, args, args.episodes)
    if args.policy in ("scripted", FORECAST_POLICY) or args.policy.startswith("blind:"):
        _check_baseline_options(ap, args.policy, args.options)
    spec = args.policy
    saved = spec.endswith((".zip", ".npz"))
    if not (
        spec in ("scripted", FORECAST_POLICY) or spec.startswith("blind:") or saved or os.path.exists(spec)
    ):
        ap.error(
            f"argument --policy: {spec!r} is not 'scripted', '{FORECAST_POLICY}', 'blind:VZ', a saved .npz "
            "or a saved stable-baselines3 .zip"
        )
    if spec in ("scripted", FORECAST_POLICY) and args.env_id not in (LANDING_V1_ID, LANDING_V2_ID):
        ap.error(f"argument --policy: {spec} needs a landing observation: use --env-id {LANDING_V2_ID}")
    if spec.startswith("blind:"):
        try:
            vz = float(spec.removeprefix("blind:"))
        except ValueError:
            ap.error(f"argument --policy: {spec!r}: VZ must be a number of m/s, e.g. blind:0.3")
        if not (math.isfinite(vz) and vz > 0):
            ap.error(f"argument --policy: {spec!r}: VZ must be a positive descent speed (m/s)")
    if saved and not os.path.isfile(spec):
        ap.error(f"argument --policy: no such file {spec!r}")
    if spec.endswith(".npz"):  # read before any env is built: a corrupt file is named at once
        try:
            MlpPolicy.load(spec) if MlpPolicy.is_mlp_file(spec) else GruPolicy.load(spec)
        except PolicyFileError as e:
            ap.error(f"argument --policy: {e}")


def make_env_and_policy(ap: argparse.ArgumentParser, args: argparse.Namespace) -> tuple[gym.Env, Any, dict]:
    """The env and the policy of checked arguments (:func:`add_episode_arguments`) and the env
    options used; ``ap.error`` (exit status 2) if the env cannot be made or the policy not loaded.
    The caller closes the env."""
    spec = args.policy
    kwargs = env_kwargs(args)
    if args.deck_motion:
        kwargs["deck_motion"] = True
    if spec == FORECAST_POLICY and "deck_forecast" not in kwargs:
        kwargs["deck_forecast"] = FORECAST_POLICY_OPTIONS  # the forecast block it flies on
    try:
        env = gym.make(args.env_id, **kwargs)
    except (TypeError, ValueError, RuntimeError) as e:  # e.g. --deck-motion on an env without it
        ap.error(f"cannot make {args.env_id} with {kwargs}: {e}")
    try:
        try:
            policy = make_policy(spec, env, args.algo)
        except PolicyError as e:
            retry = (
                with_deck_motion(args.env_id, kwargs, spec, args.algo)
                if "deck_motion" not in kwargs
                else None
            )
            if retry is None:
                ap.error(f"argument {e}")
            env.close()
            env, policy = retry
            kwargs["deck_motion"] = True
            print(f"{spec}: trained with deck_motion=True, evaluated so (as with --deck-motion)", flush=True)
    except BaseException:
        env.close()
        raise
    return env, policy, kwargs


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
    _check_args(ap, args)
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

__all__ = [
    "DESCRIPTION",
    "add_env_arguments",
    "add_episode_arguments",
    "build_parser",
    "check_env_args",
    "env_kwargs",
    "format_episode",
    "main",
    "make_env_and_policy",
    "summary",
]
