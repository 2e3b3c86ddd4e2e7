"""Hover 1 m above the moving deck, track it with the IHRCF estimate, and reproduce the paper's Table 2.

    python examples/hover_and_track.py                        # the paper's 130 s run, ~2-3 min
    python examples/hover_and_track.py --seconds 20 --profile sea_state --tof-noise realistic
    python examples/hover_and_track.py --seconds 10 --no-plots --out out/quick

The drone flies in velocity mode and follows the deck using ONLY the IHRCF estimate of the deck
pose in its body frame (:class:`ihrcf_env.control.hover.HoverTracker`; ground truth is recorded for
the error statistics, never used to fly): it moves over the tag centre, holds ``--height`` above the
deck (riding its heave) and turns with the deck's heading; while IHRCF is invalid it holds position.

At the end it prints the mean absolute errors of ATDA (AprilTag + camera) and IHRCF (AprilTag +
camera + four ToF ranges) in the layout of the paper's Table 2, over valid frames only and with
angle errors wrapped to (-pi, pi], beside the peak errors, the invalid-frame counts and the
paper's own values; saves Figs. 14-20 lookalikes (PNG) and the time series (CSV) to ``--out``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from ihrcf_env.core.metrics import table2_text
from ihrcf_env.experiments.figures import save_figures
from ihrcf_env.experiments.hover_and_track import run, save_csv, tracking_summary


def _clock(seconds: float) -> str:
    """``m:ss`` of a duration in seconds."""
    m, s = divmod(int(round(seconds)), 60)
    return f"{m:d}:{s:02d}"


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--seconds", type=float, default=130.0, help="simulated seconds (default 130, the paper's run)"
    )
    ap.add_argument("--seed", type=int, default=0, help="seed of the start pose and sensor noise (default 0)")
    ap.add_argument(
        "--profile",
        choices=("paper", "sea_state", "static"),
        default="paper",
        help="deck motion (default paper)",
    )
    ap.add_argument(
        "--tof-noise", choices=("ideal", "realistic"), default="ideal", help="ToF range model (default ideal)"
    )
    ap.add_argument("--height", type=float, default=1.0, help="hover height above the deck, m (default 1)")
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("out/hover_and_track"),
        help="output folder (default out/hover_and_track)",
    )
    ap.add_argument(
        "--no-plots", action="store_true", help="skip the PNG figures (the CSV is always written)"
    )
    args = ap.parse_args(argv)
    if not (math.isfinite(args.seconds) and args.seconds > 0):
        ap.error(f"--seconds must be positive, got {args.seconds}")
    if not (math.isfinite(args.height) and 0.3 <= args.height <= 3.0):
        ap.error(f"--height must be in [0.3, 3] m, got {args.height}")

    print(
        f"IHRCF tracking hover: {args.seconds:g} s over the {args.profile!r} deck, {args.height:g} m up, "
        f"ToF {args.tof_noise}, seed {args.seed}",
        flush=True,
    )
    t_start = time.perf_counter()
    res = run(args.seconds, args.seed, args.profile, args.tof_noise, args.height)
    if res.ended_early:
        t_end = res.time[-1]
        print(f"\nWARNING: episode ended early at t = {t_end:.2f} s ({res.ended_early})", file=sys.stderr)
    sim_s = res.time[-1] if res.n else 0.0
    print()
    hz = res.settings["control_hz"]
    table = table2_text(res.error_stats())
    print(f"Deck pose errors (body frame), estimate minus ground truth, {res.n} frames at {hz} Hz")
    print(table)
    print(tracking_summary(res))
    saved = [save_csv(res, args.out / "timeseries.csv")]
    if not args.no_plots:
        try:
            saved += save_figures(res, args.out)
        except ImportError:
            print("matplotlib is not installed (pip install '.[plots]'): figures skipped")
    (args.out / "table2.txt").write_text(table + "\n")
    saved.append(args.out / "table2.txt")
    total = time.perf_counter() - t_start
    print(
        f"Wall time: {_clock(res.wall_time)} for {sim_s:.1f} simulated s ({sim_s / res.wall_time:.2f}x real "
        f"time); {total:.1f} s in all"
    )
    print(f"Saved {len(saved)} files to {args.out}/: " + ", ".join(p.name for p in saved))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
