"""The arguments that choose an env, shared by the command lines that make one (``ihrcf-evaluate``,
``ihrcf-record``, ``ihrcf-mavlink``): id, level, ``--option KEY=VALUE``, first seed, camera model,
sensor preset, step limit. :func:`add_env_arguments` adds them, :func:`check_env_args` checks
them before any env is built (``ap.error``, exit status 2, naming the argument),
:func:`env_kwargs` turns them into ``gym.make`` keywords.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from typing import Any

import gymnasium as gym

from ihrcf_env import LANDING_V1_ID, LANDING_V2_ID
from ihrcf_env.cmdline.common import MAX_SEED, int_in, seed_type
from ihrcf_env.config.levels import LEVELS, TEST_SEEDS


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
        ap.error(f"argument --option: render_mode is not an option of {ap.prog} (it renders nothing)")
    return out


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


def make_env(ap: argparse.ArgumentParser, env_id: str, kwargs: dict[str, Any]) -> gym.Env:
    """``gym.make(env_id, **kwargs)``, or ``ap.error`` (exit status 2) naming the id and the options
    if the env refuses them (e.g. an option the env does not have). The caller closes the env."""
    try:
        return gym.make(env_id, **kwargs)
    except (TypeError, ValueError, RuntimeError) as e:
        ap.error(f"cannot make {env_id} with {kwargs}: {e}")


__all__ = ["FLAG_OPTIONS", "add_env_arguments", "check_env_args", "env_kwargs", "make_env"]
