"""Scripted landing on the moving deck using only the drone's own sensing (IHRCF + ToF + IMU).

The controller is :class:`ihrcf_env.control.landing.LandingController` (approach, hold until the
deck's predicted tilt at touchdown and heave velocity allow it, drop on the ToF ranges); it never
reads ground truth, and ``info`` is used only to report how each episode ended
(:func:`ihrcf_env.experiments.landing.evaluate`). On the "paper" profile the deck tilts more than
10 deg from ~3.5 s to ~13.5 s, so with ``--deck-start zero`` the drone waits at the hold height and
lands at ~16 s (by default each episode starts the deck at a seeded random time).

python examples/land.py                       # 20 seeds x paper and sea_state (~12 min wall)
python examples/land.py --episodes 2 --profiles static --max-seconds 10
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

from ihrcf_env.core.metrics import LandingSummary, format_episode, format_landing_summary, summarize_landings
from ihrcf_env.experiments.landing import PROFILES, evaluate


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry point; prints per-episode lines and a per-profile report."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--episodes", type=int, default=20, help="episodes (seeds) per profile (default 20)")
    ap.add_argument("--profiles", nargs="+", default=["paper", "sea_state"], choices=PROFILES)
    ap.add_argument("--seed", type=int, default=0, help="first seed (default 0)")
    ap.add_argument("--sensor-preset", default="ideal", choices=("ideal", "realistic"))
    ap.add_argument("--tof-noise", default=None, choices=("ideal", "realistic"), help="override the preset")
    ap.add_argument(
        "--estimator", default="ihrcf", choices=("ihrcf", "fused"), help="deck estimate to fly on"
    )
    ap.add_argument("--max-seconds", type=float, default=30.0, help="episode limit, simulated s (default 30)")
    ap.add_argument(
        "--control-hz", type=int, default=20, help="agent/camera rate (default 20; 10 halves the wall time)"
    )
    ap.add_argument(
        "--deck-start",
        choices=("random", "zero"),
        default="random",
        help="start the deck motion at a seeded random time of its profile (default) or at t = 0",
    )
    ap.add_argument("--short", action="store_true", help="quick check: 1 episode on the static deck, 10 s")
    ap.add_argument("--quiet", action="store_true", help="only the summary")
    args = ap.parse_args(argv)
    if args.short:
        args.episodes, args.profiles, args.max_seconds = 1, ["static"], 10.0
    if args.episodes < 1:
        ap.error("--episodes must be >= 1")
    if not (math.isfinite(args.max_seconds) and args.max_seconds > 0):
        ap.error("--max-seconds must be positive")

    summaries: dict[str, LandingSummary] = {}
    t0 = time.perf_counter()
    for profile in args.profiles:
        results = evaluate(
            profile,
            args.episodes,
            args.seed,
            args.tof_noise,
            args.max_seconds,
            env_kwargs={
                "control_hz": args.control_hz,
                "random_deck_start": args.deck_start == "random",
                "sensor_preset": args.sensor_preset,
            },
            on_episode=None if args.quiet else lambda r: print(format_episode(r), flush=True),
            estimator=args.estimator,
        )
        summaries[profile] = summarize_landings(results)
    wall = time.perf_counter() - t0
    print(
        f"\nlanding report ({args.episodes} episodes per profile, sensor_preset={args.sensor_preset}, "
        f"tof_noise={args.tof_noise or 'preset'}, estimator={args.estimator}, "
        f"deck start {args.deck_start}, wall {wall:.0f} s)"
    )
    for profile, s in summaries.items():
        print(format_landing_summary(profile, s))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
