"""``ihrcf-calibrate`` (``python -m ihrcf_env.calibrate``): run the simulated calibration and
write a calibration file.

It runs the chessboard intrinsics calibration (paper section 2.1) and the camera-range calibration
ascent (section 2.2) in a fresh simulated world, writes the versioned calibration file
(:meth:`ihrcf_env.core.calibration.Calibration.to_json`) and prints a summary. The file shipped as
``assets/calibration_default.json`` is produced by running it with the defaults. The output is
checked before the run (a file name, in a folder that can be written) and written whole.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, TextIO

from ihrcf_env.cmdline.common import (
    check_output,
    command_main,
    int_in,
    make_parser,
    real_in,
    seed_type,
    write_whole,
)
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.experiments.progress import Progress

if TYPE_CHECKING:
    from ihrcf_env.sim.calibration_procedure import CalibrationRun


#: Bounds of --width and --height (px): the env's camera sizes.
IMAGE_SIZE = (16, 4096)
#: Most ascent stages (--stages) and chessboard views (--views).
MAX_STAGES = 1000
MAX_VIEWS = 500
#: Largest range (m) of --top and --bottom: the ToF's largest max range.
MAX_RANGE = 100.0


class PhaseProgress:
    """The ``progress(phase, done, total)`` callback of
    :func:`ihrcf_env.sim.calibration_procedure.run_calibration`: one
    :class:`~ihrcf_env.experiments.progress.Progress` per phase (``chessboard`` views, then
    ``ascent`` stages) on ``stream``: a bar on a terminal, plain lines otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self._phase: str | None = None
        self._bar: Progress | None = None

    def __call__(self, phase: str, done: int, total: int) -> None:
        """Show ``done`` of ``total`` steps of ``phase``; a new phase starts a new bar."""
        if self._bar is None or phase != self._phase or total != self._bar.total:
            self.close()
            self._phase = phase
            self._bar = Progress(max(total, 0), phase, stream=self.stream)
        self._bar.update(done)

    def close(self) -> None:
        """Finish the current bar, if any."""
        if self._bar is not None:
            self._bar.close()
            self._bar, self._phase = None, None


DESCRIPTION = """\
Simulated IHRCF calibration: chessboard intrinsics and the range -> pixel tables.

Runs the chessboard intrinsics calibration (paper section 2.1) and the camera-range calibration
ascent (section 2.2) in a fresh simulated world, writes the versioned calibration file and prints
a summary. The package's shipped calibration is what the defaults produce.

examples:
  ihrcf-calibrate --output calibration.json
  python -m ihrcf_env.calibrate --k1 -0.05 --output calibration_k1.json
"""


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = make_parser("calibrate", DESCRIPTION)
    ap.add_argument(
        "--width",
        type=int_in(*IMAGE_SIZE),
        default=512,
        help=f"image width (px, {IMAGE_SIZE[0]}..{IMAGE_SIZE[1]})",
    )
    ap.add_argument(
        "--height",
        type=int_in(*IMAGE_SIZE),
        default=512,
        help=f"image height (px, {IMAGE_SIZE[0]}..{IMAGE_SIZE[1]})",
    )
    ap.add_argument("--fov-deg", type=float, default=60.0, help="vertical field of view (deg)")
    ap.add_argument("--k1", type=float, default=0.0, help="camera radial distortion k1")
    ap.add_argument("--k2", type=float, default=0.0, help="camera radial distortion k2")
    ap.add_argument(
        "--output",
        default=None,
        help="calibration file to write (default: calibration_<W>x<H>_fov<F>.json in the working directory)",
    )
    ap.add_argument(
        "--stages",
        type=int_in(4, MAX_STAGES),
        default=120,
        help=f"ascent stages (4..{MAX_STAGES}; the paper's: 120)",
    )
    ap.add_argument(
        "--top",
        type=real_in(0.0, MAX_RANGE, low_open=True),
        default=None,
        help="range of the last stage (m) (default: the ToF max range)",
    )
    ap.add_argument(
        "--bottom",
        type=real_in(0.0, MAX_RANGE, low_open=True),
        default=0.15,
        help="range of the first stage (m)",
    )
    ap.add_argument("--seed", type=seed_type, default=0, help="seed of the chessboard poses, an integer >= 0")
    ap.add_argument(
        "--views",
        type=int_in(3, MAX_VIEWS),
        default=30,
        help=f"chessboard views (3..{MAX_VIEWS}; >= 15 advised)",
    )
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


@command_main("calibrate")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-calibrate``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    default = f"calibration_{args.width}x{args.height}_fov{args.fov_deg:g}.json"
    out = check_output(ap, "--output", default if args.output is None else args.output)
    # Imported here so that ``--help`` does not start PyBullet.
    from ihrcf_env.config.sensors import CameraConfig
    from ihrcf_env.core.calibration import CalibrationError
    from ihrcf_env.sim.calibration_procedure import (
        AscentSettings,
        CalibrationFailed,
        ChessboardSettings,
        run_calibration,
    )

    try:
        camera = CameraConfig(
            width=args.width,
            height=args.height,
            fov=math.radians(args.fov_deg),
            distortion=(args.k1, args.k2),
        )
        ascent = AscentSettings(stages=args.stages, bottom=args.bottom, top=args.top)
        board = ChessboardSettings(n_views=args.views)
    except ValueError as e:
        ap.error(str(e))
    bar = PhaseProgress(sys.stderr) if not args.quiet else None
    t0 = time.perf_counter()
    try:
        run = run_calibration(
            camera=camera, rig=SensorRig(), ascent=ascent, chessboard=board, seed=args.seed, progress=bar
        )
    except (CalibrationFailed, CalibrationError, ValueError) as e:
        if bar is not None:
            bar.close()
        print(f"calibration failed: {e}", file=sys.stderr)
        return 1
    if bar is not None:
        bar.close()
    elapsed = time.perf_counter() - t0
    path = write_whole(out, run.calibration.to_json())
    _print_summary(run, str(path), elapsed)
    return 0


def _print_summary(run: CalibrationRun, path: str, elapsed: float) -> None:
    """Print the run's summary (stdout): chessboard errors vs the true K, table check, skipped stages."""
    cal, cb, asc = run.calibration, run.chessboard, run.ascent
    K, K0 = cb.intrinsics.K, cb.K_true
    lo, hi = asc.table.spans[:, 0].max(), asc.table.spans[:, 1].min()
    lines = [
        f"wrote {path}",
        f"camera {cal.image_width}x{cal.image_height}, vertical fov {math.degrees(cal.fov):g} deg, "
        f"seed {cal.seed}",
        f"chessboard: {cb.intrinsics.n_views} views ({cb.views_tried} rendered), "
        f"RMS {cb.intrinsics.rms:.3f} px",
        f"  fx {K[0, 0]:.2f} fy {K[1, 1]:.2f} (true {K0[0, 0]:.2f}): "
        f"focal error {100 * cb.focal_error_rel:.3f} %",
        f"  cx {K[0, 2]:.2f} cy {K[1, 2]:.2f} (true {K0[0, 2]:.2f} {K0[1, 2]:.2f}): "
        f"principal point error {cb.principal_point_error_px:.2f} px",
        f"  dist {' '.join(f'{x:.4g}' for x in cb.intrinsics.dist)}",
        f"ascent: {len(asc.stages)} stages {asc.bottom:g}..{asc.top:g} m, {len(asc.usable)} used, "
        f"table span {lo:.3f}..{hi:.3f} m",
        f"  table vs true projection at the samples: max {run.table_check_px['max']:.3f} px, "
        f"mean {run.table_check_px['mean']:.3f} px",
    ]
    if asc.skipped:
        lines.append(f"  skipped {len(asc.skipped)} stage(s):")
        lines += [f"    stage {s.index} at {float(s.ranges.mean()):.3f} m: {s.reason}" for s in asc.skipped]
    else:
        lines.append("  skipped 0 stages")
    lines.append(f"time {elapsed:.1f} s")
    print("\n".join(lines))


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "DESCRIPTION",
    "PhaseProgress",
    "build_parser",
    "main",
]
