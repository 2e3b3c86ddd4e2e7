"""``ihrcf-mavlink`` (``python -m ihrcf_env.mavlink``): run a landing or hover env as a MAVLink 2
vehicle.

The env is chosen by the arguments of ``ihrcf-evaluate``
(:func:`ihrcf_env.cmdline.env_args.add_env_arguments`, checked the same way); the vehicle is
:class:`ihrcf_env.mavlink.loop.MavlinkVehicle`, its options checked once by
:class:`~ihrcf_env.mavlink.loop.VehicleOptions`. A port in use, a destination that cannot be
reached or a missing pymavlink exit with status 2, Ctrl-C with 130 (the sockets and the env
closed).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence

from ihrcf_env.cmdline.common import command_main, int_in, make_parser, real_in
from ihrcf_env.cmdline.env_args import add_env_arguments, check_env_args, env_kwargs, make_env

DESCRIPTION = """\
Run a landing (or hover) env as a MAVLink 2 vehicle, PX4-style: heartbeat, arming, the hold /
offboard / land modes, SET_POSITION_TARGET_LOCAL_NED velocity setpoints into the env's velocity
autopilot, telemetry (ATTITUDE, LOCAL_POSITION_NED, EXTENDED_SYS_STATE, SYS_STATUS,
DISTANCE_SENSOR per ToF beam, SYSTEM_TIME, TIMESYNC answers) and the deck-pose estimate as
LANDING_TARGET at the camera rate. A MAVSDK or pymavlink script connects to it as to PX4 SITL
(e.g. examples/mavsdk_landing.py). Each episode waits, disarmed in hold with the world still,
until the first arm; after the touchdown the vehicle disarms and, with --episodes N, starts the
next seed (exits after the N-th), else stays up until Ctrl-C. Needs the [mavlink] extra
(pip install "ihrcf-env[mavlink]"). Reference: docs/mavlink.md.

examples:
  ihrcf-mavlink --level calm --camera-model projected
  ihrcf-mavlink --level calm --camera-model projected --speed 4 --episodes 10 \\
      --out udpout:127.0.0.1:14540 --out udpout:127.0.0.1:14541
  ihrcf-mavlink --level calm --camera-model projected --bench 25
"""


def _speed(text: str) -> float | None:
    """``--speed``: a positive number, or ``max`` (None: as fast as it runs)."""
    if text.strip().lower() == "max":
        return None
    return real_in(0.0, 1e6, low_open=True)(text)


_speed.__name__ = "speed"


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    from ihrcf_env.mavlink.loop import DEFAULT_OUT
    from ihrcf_env.mavlink.target import PROFILES, TARGETS

    ap = make_parser("mavlink", DESCRIPTION)
    add_env_arguments(ap)
    ap._option_string_actions["--max-steps"].help = "end an episode after this many steps (default: no limit)"
    ap.add_argument(
        "--out",
        action="append",
        default=None,
        metavar="CONNECTION",
        help=f"where the vehicle sends, as a pymavlink connection string (udpout:HOST:PORT sends there, "
        f"udpin:HOST:PORT listens); repeatable (default: {DEFAULT_OUT})",
    )
    ap.add_argument(
        "--speed",
        type=_speed,
        default=argparse.SUPPRESS,
        help="simulated seconds per wall second, or 'max' (as fast as it runs) "
        "(default: 1; max with --bench)",
    )
    ap.add_argument(
        "--episodes",
        type=int_in(1),
        default=None,
        help="exit after this many episodes (default: one episode, then stay up until Ctrl-C)",
    )
    ap.add_argument("--target", choices=TARGETS, default="fused", help="LANDING_TARGET's source")
    ap.add_argument(
        "--profile", choices=PROFILES, default="px4", help="LANDING_TARGET's form (docs/mavlink.md)"
    )
    ap.add_argument("--system-id", type=int_in(1, 255), default=1, help="the vehicle's MAVLink system id")
    ap.add_argument(
        "--bench",
        type=real_in(0.0, 3600.0, low_open=True),
        default=None,
        metavar="SECONDS",
        help="benchmark: arm at once, hold for SECONDS simulated, print the real-time factor and the "
        "message rates (default: off)",
    )
    return ap


@command_main("mavlink")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-mavlink``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        from ihrcf_env.mavlink import loop
        from ihrcf_env.mavlink._pymavlink import import_pymavlink
        from ihrcf_env.mavlink.link import LinkError

        import_pymavlink()
    except ImportError as e:
        ap.error(str(e))
    check_env_args(ap, args, args.episodes or 1)
    bench = args.bench is not None
    speed = getattr(args, "speed", None if bench else 1.0)
    try:
        options = loop.VehicleOptions(
            endpoints=tuple(args.out or (loop.DEFAULT_OUT,)),
            speed=speed,
            episodes=args.episodes,
            seed=args.seed,
            target=args.target,
            profile=args.profile,
            system_id=args.system_id,
            auto_arm=bench,
            duration=args.bench,
        )
    except ValueError as e:
        ap.error(f"argument --out: {e}" if str(e).startswith("endpoints") else str(e))
    kwargs = env_kwargs(args)
    kwargs.setdefault("max_episode_steps", -1)  # no step limit: a vehicle waits for its client
    env = make_env(ap, args.env_id, kwargs)
    try:
        try:
            vehicle = loop.MavlinkVehicle(env, options)
        except ValueError as e:
            ap.error(str(e))
        try:
            vehicle.open()
        except LinkError as e:
            ap.error(f"argument --out: {e}")
        with vehicle:
            pace = "as fast as it runs" if speed is None else f"{speed:g}x real time"
            print(
                f"ihrcf-mavlink: {args.env_id} (seed {args.seed}) as MAVLink system {args.system_id}, "
                f"sending to {', '.join(options.endpoints)}, {pace}, LANDING_TARGET from {args.target} "
                f"({args.profile} profile)",
                flush=True,
            )
            report = vehicle.run()
    finally:
        env.close()
    eps = report.episodes
    if eps:
        ok = sum(e.outcome == "success" for e in eps)
        print(f"episodes {len(eps)}, success {ok}/{len(eps)}")
    counts = {k: v for k, v in sorted(report.counts.items()) if v}
    if counts:
        print("counters: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    if bench:
        rtf = report.real_time_factor
        print(
            f"real-time factor {rtf:.1f}x ({report.sim_time:.1f} s simulated in "
            f"{report.wall_time:.2f} s wall, "
            f"{args.camera_model or 'env default'} camera, MAVLink on)"
        )
        if report.steps:
            per = (report.wall_time - report.env_time) / report.steps * 1e3
            print(
                f"env.step {report.env_time / report.wall_time:.0%} of the wall time; MAVLink and the loop "
                f"{per:.2f} ms per step of {1e3 * report.sim_time / report.steps:.0f} ms simulated"
            )
        print("messages sent (count, per simulated second, per wall second):")
        for line in loop.format_rates(report):
            print(line)
        if not math.isfinite(rtf):
            return 1
    return 0


__all__ = ["DESCRIPTION", "build_parser", "main"]
