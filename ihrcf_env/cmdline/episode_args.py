"""The arguments that choose an env and a policy (``ihrcf-evaluate``, ``ihrcf-record``): those of
:mod:`ihrcf_env.cmdline.env_args` plus ``--policy`` (scripted, scripted-forecast, blind:VZ, a saved
.npz or stable-baselines3 .zip), ``--algo`` and ``--deck-motion``. :func:`check_episode_args`
checks them before any env is built, :func:`make_env_and_policy` makes both; :func:`format_episode`
is a report's line for one episode.
"""

from __future__ import annotations

import argparse
import math
import os
from typing import Any

import gymnasium as gym

from ihrcf_env import LANDING_V1_ID, LANDING_V2_ID
from ihrcf_env.cmdline.env_args import add_env_arguments, check_env_args, env_kwargs, make_env
from ihrcf_env.control.forecast_landing import FORECAST_POLICY_OPTIONS
from ihrcf_env.control.gru_policy import GruPolicy, PolicyFileError
from ihrcf_env.control.mlp_policy import MlpPolicy
from ihrcf_env.experiments.episode import EpisodeResult
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


def add_episode_arguments(ap: argparse.ArgumentParser) -> None:
    """The arguments that choose the env and the policy (shared with ``ihrcf-record``); checked by
    :func:`check_episode_args`, turned into an env and a policy by :func:`make_env_and_policy`."""
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


def check_episode_args(ap: argparse.ArgumentParser, args: argparse.Namespace) -> None:
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
    env = make_env(ap, args.env_id, kwargs)  # refused e.g. --deck-motion on an env without it
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


__all__ = [
    "BASELINE_OPTIONS",
    "add_episode_arguments",
    "check_episode_args",
    "format_episode",
    "make_env_and_policy",
]
