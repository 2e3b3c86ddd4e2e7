"""``ihrcf-fit-detector`` (``python -m ihrcf_env.fit_detector``): fit the projected camera's
detector model to rendered frames and write the model file.

The experiment itself (rendering, detection, the fit) is
:func:`ihrcf_env.experiments.detector_fit.fit_detector_model`; this command checks its arguments
first, reports progress on stderr and writes the model whole (never a partial file). The default
output is ``detector_model.json`` in the working directory: the package's shipped model is never
overwritten.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Sequence
from pathlib import Path

from ihrcf_env.cmdline.common import check_output, command_main, int_in, make_parser, seed_type, write_whole

#: Where the model goes without ``--out``: the working directory.
DEFAULT_OUTPUT = "detector_model.json"

#: Fewest track frames per quality (one track of 6 frames).
MIN_FRAMES = 6

DESCRIPTION = """\
Fit the projected camera's detector model to rendered frames (both camera qualities).

Renders seeded frames of the tag (tracks at 20 Hz, far and oblique views) with the rendered
camera, runs the tag detector on them, pairs each with the exact projection of the same state and
fits the detector model per camera quality. Progress goes to stderr, the summary to stdout. The
package's shipped model is never overwritten: the model is written to --out.

examples:
  ihrcf-fit-detector --out detector_model.json
  python -m ihrcf_env.fit_detector --frames 120 --seed 1 --out /tmp/quick_model.json
"""


def build_parser() -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = make_parser("fit-detector", DESCRIPTION)
    ap.add_argument(
        "--out",
        default=DEFAULT_OUTPUT,
        help="model file to write; its folder must exist (default: detector_model.json in the "
        "working directory)",
    )
    ap.add_argument("--seed", type=seed_type, default=0, help="random seed, an integer >= 0")
    ap.add_argument(
        "--frames",
        type=int_in(MIN_FRAMES),
        default=1200,
        help=f"track frames per camera quality (>= {MIN_FRAMES})",
    )
    ap.add_argument(
        "--samples",
        default=None,
        help="also write the rendered frames (npz) to this folder (default: not written)",
    )
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    return ap


@command_main("fit-detector")
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ihrcf-fit-detector``; returns the process exit code."""
    ap = build_parser()
    args = ap.parse_args(argv)
    out = check_output(ap, "--out", args.out)
    if args.samples is not None:
        samples = Path(args.samples)
        if samples.exists() and not samples.is_dir():
            ap.error(f"argument --samples: {args.samples!r} is a file, not a folder")
        if not samples.exists() and not samples.parent.is_dir():
            ap.error(f"argument --samples: the folder {str(samples.parent)!r} does not exist")
    # Imported here so that --help and argument errors do not start PyBullet.
    from ihrcf_env.core.detector_model import QUALITIES
    from ihrcf_env.experiments.detector_fit import fit_detector_model
    from ihrcf_env.experiments.progress import Progress

    bars: dict[str, Progress] = {}

    def progress(quality: str, done: int, total: int) -> None:
        if args.quiet:
            return
        if quality not in bars:
            for bar in bars.values():
                bar.close()
            bars[quality] = Progress(total, f"{quality} tracks", unit="track")
        bars[quality].update(done)

    try:
        model = fit_detector_model(args.frames, args.seed, progress, args.samples)
    finally:
        for bar in bars.values():
            bar.close()
    text = json.dumps(model.to_dict(), indent=1, allow_nan=False) + "\n"
    write_whole(out, text)
    print(f"wrote {out} ({out.stat().st_size} bytes) in {model.fit['seconds']} s")
    for quality in QUALITIES:
        prm, rep = model.params(quality), model.fit["reports"][quality]
        sd_r, sd_t = math.exp(prm.log_sd_radial[0]), math.exp(prm.log_sd_tangential[0])
        print(
            f"[{quality}] frames {rep['frames']}, detected {rep['detected']} "
            f"(rate: model {rep['detection_rate_model']:.3f}, "
            f"rendered {rep['detection_rate_rendered']:.3f}); "
            f"normalised s.d. r/t {rep['normalised_sd'][0]:.3f}/{rep['normalised_sd'][1]:.3f}"
        )
        print(
            f"  at 100 px: radial bias {prm.mean_radial[0]:+.3f} px, s.d. r/t {sd_r:.3f}/{sd_t:.3f} px; "
            f"noise gain {prm.noise_gain:.3g}, blur gain {prm.blur_gain:.3g}"
        )
        print(
            f"  correlation {prm.corr_max:.2f} exp(-(d / {prm.corr_length_px:.3f} px)^2); "
            f"measured by displacement {rep['correlation_by_displacement']}"
        )
        print(
            f"  margin >= {prm.min_margin_px:.2f} px; quiet-zone band "
            f"[{prm.band_low_px:.2f}, {prm.band_high_px:.2f}) px fails {prm.band_fail_prob:.2f}; "
            f"size50 {prm.size50_px:.1f} px (width {prm.size_width_px:.2f}); "
            f"cos_view >= {prm.min_cos_view:.3f}; miss {prm.miss_prob:.4f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "DEFAULT_OUTPUT",
    "DESCRIPTION",
    "MIN_FRAMES",
    "build_parser",
    "main",
]
