"""Hover 1 m above the moving deck, track it with the IHRCF estimate, and reproduce the paper's Table 2.

    python examples/hover_and_track.py                        # the paper's 130 s run, ~2-3 min
    python examples/hover_and_track.py --seconds 20 --profile sea_state --tof-noise realistic
    python examples/hover_and_track.py --seconds 10 --no-plots --out out/quick

The drone flies in velocity mode and follows the deck using ONLY the IHRCF estimate of the deck
pose in its body frame (ground truth is recorded for the error statistics, never used to fly):

* the estimated deck position is rotated from the body frame to the heading frame with the IMU's
  roll and pitch (the two frames differ by the drone's tilt, which is as large as the deck's motion
  here), then ``vx = K_XY * x``, ``vy = K_XY * y`` drive the drone over the tag centre;
* ``vz = K_Z * (height - h)`` holds the drone ``--height`` (1 m) above the deck, ``h`` being the
  estimated height of the drone above the tag centre along world up; the drone therefore rides the
  deck's heave, keeping the camera-deck geometry of the paper's hover;
* ``yaw_rate = K_YAW * yaw`` turns the nose with the deck's estimated heading;
* while IHRCF is invalid the command is zero: the built-in controller holds position.

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import ihrcf_env  # noqa: F401  (registers ihrcf_env/DeckLanding-v0)
from ihrcf_env.core.frames import euler_from_matrix, matrix_from_euler, matrix_from_quat, wrap_angle

#: Tracking gains: (m/s)/m for x, y and z, (rad/s)/rad for yaw.
K_XY = 1.0
K_Z = 1.0
K_YAW = 1.0
#: Agent/camera rate (Hz), the env's default.
CONTROL_HZ = 20

ESTIMATORS = ("atda", "ihrcf")
SOURCES = ("gt", "ihrcf", "atda")
LABELS = {"gt": "GT", "ihrcf": "IHRCF", "atda": "ATDA"}
#: Paper-like colours: IHRCF blue, ground truth green, ATDA red (Figs. 14-16).
COLORS = {"ihrcf": "tab:blue", "gt": "tab:green", "atda": "tab:red"}
#: Drawing order and line styles: ground truth wide underneath, ATDA, then IHRCF on top (it sits on GT).
STYLE = {
    "gt": {"lw": 2.4, "alpha": 0.6, "zorder": 1},
    "atda": {"lw": 0.9, "alpha": 0.9, "zorder": 2},
    "ihrcf": {"lw": 1.0, "alpha": 1.0, "zorder": 3},
}
#: Error plots (Figs. 17-20): X blue, Y red, Z yellow (MATLAB's default colour order, as in the paper).
AXIS_COLORS = ("#0072BD", "#D95319", "#EDB120")
ROW_NAMES = ("X", "Y", "Z", "roll", "pitch", "yaw")

#: The paper's Table 2 (mean absolute errors): X, Y, Z in m, then roll, pitch, yaw in degrees.
PAPER_TABLE2 = {
    "atda": (0.0162, 0.0134, 0.0697, 2.9843, 1.657, 1.7743),
    "ihrcf": (0.0035, 0.0039, 0.0041, 0.98, 1.3731, 1.180),
}


@dataclass
class Results:
    """Time series of one run, one row per control step (after the step).

    Poses are the deck's in the drone body frame (FLU), positions in m and Euler angles
    (roll, pitch, yaw, Z-Y-X) in rad; an invalid estimate reads zeros with ``valid = 0``.
    """

    time: NDArray[np.float64]  # (n,) s
    position: dict[str, NDArray[np.float64]]  # source -> (n, 3) m
    euler: dict[str, NDArray[np.float64]]  # source -> (n, 3) rad
    valid: dict[str, NDArray[np.bool_]]  # estimator -> (n,)
    ranges: NDArray[np.float64]  # (n, 4) m
    ranges_valid: NDArray[np.bool_]  # (n, 4)
    command: NDArray[np.float64]  # (n, 4) (vx, vy, vz, yaw rate) in m/s, rad/s
    drone_minus_deck: NDArray[np.float64]  # (n, 3) m, world, ground truth (reporting only)
    heading_error: NDArray[np.float64]  # (n,) rad, drone yaw minus deck yaw, ground truth (reporting only)
    wall_time: float  # s, the simulation loop
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of recorded control steps."""
        return int(self.time.shape[0])


# -- progress -----------------------------------------------------------------------------------
class ProgressBar:
    """A minimal progress bar on stderr: redrawn in place on a terminal, a line per 10 % otherwise."""

    def __init__(self, total: int, stream: TextIO | None = None, width: int = 28) -> None:
        self.total = max(int(total), 1)
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.start = time.perf_counter()
        self._last_draw = -math.inf
        self._last_decile = -1

    def update(self, done: int, note: str = "") -> None:
        """Report ``done`` of ``total`` steps; ``note`` is appended to the line."""
        now = time.perf_counter()
        frac = min(max(done / self.total, 0.0), 1.0)
        if self.tty:
            if now - self._last_draw < 0.1 and done < self.total:
                return
            self._last_draw = now
            bar = "#" * int(round(frac * self.width))
            self.stream.write(f"\r[{bar:<{self.width}}] {100 * frac:3.0f}%  {self._eta(frac, now)}  {note}")
            self.stream.flush()
        else:
            decile = int(frac * 10)
            if decile > self._last_decile:
                self._last_decile = decile
                self.stream.write(f"{100 * frac:3.0f}%  {self._eta(frac, now)}  {note}\n")
                self.stream.flush()

    def close(self) -> None:
        """End the line on a terminal."""
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()

    def _eta(self, frac: float, now: float) -> str:
        elapsed = now - self.start
        left = elapsed * (1 - frac) / frac if frac > 0 else math.nan
        return f"elapsed {_clock(elapsed)}  left {_clock(left)}"


def _clock(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "--:--"
    m, s = divmod(int(round(seconds)), 60)
    return f"{m:d}:{s:02d}"


# -- control ------------------------------------------------------------------------------------
def tracking_action(
    estimate: dict[str, Any],
    quaternion: NDArray[np.floating],
    height: float,
    max_velocity: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Normalised velocity action that tracks the deck from one pose estimate (body frame).

    Args:
        estimate: ``obs["ihrcf"]``: ``position`` (3,) m, ``euler`` (3,) rad, ``valid`` 0/1.
        quaternion: the IMU attitude (x, y, z, w), world from body; only roll and pitch are used.
        height: wanted height of the drone above the tag centre (m, world up).
        max_velocity: the env's action scale (m/s, m/s, m/s, rad/s).

    Returns:
        ``(vx, vy, vz, yaw_rate) / max_velocity`` clipped to [-1, 1]; zeros if the estimate is invalid.
    """
    if not estimate["valid"]:
        return np.zeros(4)
    roll, pitch, _ = euler_from_matrix(matrix_from_quat(quaternion))
    R_heading_body = matrix_from_euler(roll, pitch, 0.0)
    p = R_heading_body @ np.asarray(estimate["position"], dtype=np.float64)  # deck in the heading frame
    h = -p[2]  # drone above the tag centre
    v = np.array([K_XY * p[0], K_XY * p[1], K_Z * (height - h), K_YAW * float(estimate["euler"][2])])
    return np.clip(v / max_velocity, -1.0, 1.0)


def run(
    seconds: float = 130.0,
    seed: int = 0,
    profile: str = "paper",
    tof_noise: str = "ideal",
    height: float = 1.0,
    progress: bool = True,
) -> Results:
    """Fly the IHRCF tracking hover for ``seconds`` of simulated time and record every step.

    Args:
        seconds: simulated duration (s); the paper's run lasts 130 s.
        seed: seeds the start (offset up to 0.1 m, yaw up to 0.2 rad), ToF noise and sea state.
        profile: deck motion, ``"paper"``, ``"sea_state"`` or ``"static"``.
        tof_noise: ``"ideal"`` or ``"realistic"`` ToF ranges.
        height: hover height above the deck (m); also the start altitude.
        progress: draw a progress bar on stderr.
    """
    if not (math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be positive, got {seconds!r}")
    env = gym.make(
        "ihrcf_env/DeckLanding-v0",
        deck_profile=profile,
        tof_noise=tof_noise,
        keep_image=False,
        # gym.make keeps the registered 600-step (30 s) TimeLimit when given None: set it explicitly
        max_episode_steps=max(int(round(seconds * CONTROL_HZ)), 1),
        control_hz=CONTROL_HZ,
    )
    base = env.unwrapped
    hz = base.config.control_hz
    n = max(int(round(seconds * hz)), 1)
    max_velocity = np.asarray(base.max_velocity, dtype=np.float64)
    t = np.zeros(n)
    pos = {k: np.zeros((n, 3)) for k in SOURCES}
    eul = {k: np.zeros((n, 3)) for k in SOURCES}
    valid = {k: np.zeros(n, dtype=bool) for k in ESTIMATORS}
    ranges = np.zeros((n, 4))
    ranges_valid = np.zeros((n, 4), dtype=bool)
    command = np.zeros((n, 4))
    offset = np.zeros((n, 3))
    heading = np.zeros(n)
    bar: ProgressBar | None = None
    k = 0
    try:
        obs, info = env.reset(seed=seed, options={"altitude": height})
        bar = ProgressBar(n) if progress else None
        t0 = time.perf_counter()
        for k in range(n):
            action = tracking_action(obs["ihrcf"], obs["imu"]["quaternion"], height, max_velocity)
            obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
            t[k] = info["time"]
            for src, key in (("gt", "ground_truth"), ("ihrcf", "ihrcf"), ("atda", "atda")):
                pos[src][k] = obs[key]["position"]
                eul[src][k] = obs[key]["euler"]
            for src in ESTIMATORS:
                valid[src][k] = bool(obs[src]["valid"])
            ranges[k] = obs["ranges"]
            ranges_valid[k] = obs["ranges_valid"].astype(bool)
            command[k] = action * max_velocity
            offset[k] = info["drone_position_world"] - info["deck_position_world"]
            yaw_drone = euler_from_matrix(matrix_from_quat(info["drone_quaternion_world"]))[2]
            yaw_deck = euler_from_matrix(matrix_from_quat(info["deck_quaternion_world"]))[2]
            heading[k] = float(wrap_angle(yaw_drone - yaw_deck))
            if bar is not None:
                wall = time.perf_counter() - t0
                rtf = t[k] / wall if wall > 0 else math.nan
                bar.update(k + 1, f"sim {t[k]:6.1f}/{n / hz:.1f} s  {rtf:4.2f}x real time")
            if terminated or truncated:
                if k + 1 < n:
                    why = "truncated" if truncated else f"{info.get('outcome')}: {info.get('crash_reason')}"
                    print(f"\nWARNING: episode ended early at t = {t[k]:.2f} s ({why})", file=sys.stderr)
                break
        wall_time = time.perf_counter() - t0
    finally:
        if bar is not None:
            bar.close()
        env.close()
    m = k + 1
    return Results(
        time=t[:m],
        position={s: a[:m] for s, a in pos.items()},
        euler={s: a[:m] for s, a in eul.items()},
        valid={s: a[:m] for s, a in valid.items()},
        ranges=ranges[:m],
        ranges_valid=ranges_valid[:m],
        command=command[:m],
        drone_minus_deck=offset[:m],
        heading_error=heading[:m],
        wall_time=wall_time,
        settings={
            "seconds": seconds,
            "seed": seed,
            "profile": profile,
            "tof_noise": tof_noise,
            "height": height,
            "control_hz": hz,
        },
    )


# -- statistics ---------------------------------------------------------------------------------
def errors(results: Results, estimator: str) -> NDArray[np.float64]:
    """(n, 6) estimate minus ground truth: X, Y, Z (m), roll, pitch, yaw (deg, wrapped to (-180, 180]);
    NaN rows where the estimate is invalid."""
    e = np.hstack(
        [
            results.position[estimator] - results.position["gt"],
            np.degrees(wrap_angle(results.euler[estimator] - results.euler["gt"])),
        ]
    )
    e[~results.valid[estimator]] = np.nan
    return e


def error_stats(results: Results) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64], int]]:
    """Per estimator: (MAE (6,), peak |error| (6,), invalid frame count); NaN where no frame is valid."""
    out = {}
    for key in ESTIMATORS:
        a = np.abs(errors(results, key)[results.valid[key]])
        if a.shape[0]:
            mae, peak = a.mean(axis=0), a.max(axis=0)
        else:
            mae = peak = np.full(6, np.nan)
        out[key] = (mae, peak, int(results.n - results.valid[key].sum()))
    return out


def mae_table(results: Results) -> str:
    """Table 2 in the paper's layout (MAE over valid frames), with peaks, invalid counts and the paper's."""
    stats = error_stats(results)
    cols = ("ATDA", "IHRCF")
    w = 9
    titles = ("Mean absolute error", "Peak absolute error", "Paper Table 2 (MAE)")
    head1 = f"{'':<22}" + "   ".join(f"{s:^{2 * w}}" for s in titles)
    head2 = f"{'':<22}" + "   ".join("".join(f"{c:>{w}}" for c in cols) for _ in range(3))
    lines = [head1, head2, "-" * len(head2)]
    for i, name in enumerate(ROW_NAMES):
        group = "Translations (m)" if i == 0 else ("Angles (degree)" if i == 3 else "")
        groups = (
            [stats[k][0][i] for k in ESTIMATORS],
            [stats[k][1][i] for k in ESTIMATORS],
            [PAPER_TABLE2[k][i] for k in ESTIMATORS],
        )
        cells = "   ".join("".join(f"{v:>{w}.4f}" for v in g) for g in groups)
        lines.append(f"{group:<16}{name:>6}{cells}")
    lines.append("-" * len(head2))
    n = results.n
    inv = "   ".join(f"{LABELS[k]} {stats[k][2]}/{n}" for k in ESTIMATORS)
    lines.append(f"Invalid frames (excluded from the statistics): {inv}")
    return "\n".join(lines)


def tracking_summary(results: Results) -> str:
    """How well the drone tracked the deck from the IHRCF estimate (scored on ground truth)."""
    settled = results.time >= min(10.0, results.time[-1] / 2)
    d = results.drone_minus_deck[settled]
    xy_mm = 1e3 * np.hypot(d[:, 0], d[:, 1])
    h_mm = 1e3 * d[:, 2]
    hdg = np.degrees(np.abs(results.heading_error[settled]))
    return "\n".join(
        (
            f"Tracking with IHRCF (scored on ground truth, from t = {results.time[settled][0]:.0f} s):",
            f"  horizontal offset drone-deck  mean {xy_mm.mean():5.1f} mm   max {xy_mm.max():5.1f} mm",
            f"  height above the deck         mean {h_mm.mean():5.0f} mm   std {h_mm.std():5.1f} mm",
            f"  heading error                 mean {hdg.mean():5.2f} deg  max {hdg.max():5.2f} deg",
        )
    )


# -- output -------------------------------------------------------------------------------------
def csv_header() -> list[str]:
    """Column names of :func:`save_csv` (units in the names; angles in radians)."""
    cols = ["time_s"]
    for src in SOURCES:
        cols += [f"{src}_{a}_m" for a in "xyz"] + [f"{src}_{a}_rad" for a in ("roll", "pitch", "yaw")]
        if src != "gt":
            cols.append(f"{src}_valid")
    cols += [f"range{i}_m" for i in range(1, 5)] + [f"range{i}_valid" for i in range(1, 5)]
    cols += ["cmd_vx_mps", "cmd_vy_mps", "cmd_vz_mps", "cmd_yaw_rate_radps"]
    return cols


def save_csv(results: Results, path: Path) -> Path:
    """Write the time series, one row per control step; deck pose in the body frame (FLU), ground truth
    first, then IHRCF and ATDA as reported by the env (zeros with ``valid = 0`` when invalid)."""
    blocks: list[NDArray[np.float64]] = [results.time[:, None]]
    for src in SOURCES:
        blocks += [results.position[src], results.euler[src]]
        if src != "gt":
            blocks.append(results.valid[src][:, None].astype(float))
    blocks += [results.ranges, results.ranges_valid.astype(float), results.command]
    data = np.hstack(blocks)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savetxt(path, data, delimiter=",", header=",".join(csv_header()), comments="", fmt="%.6g")
    return path


def _legend(ax: Any) -> None:
    """Legend in the order IHRCF, GT, ATDA (the paper's)."""
    handles, labels = ax.get_legend_handles_labels()
    by_label = dict(zip(labels, handles, strict=True))
    order = [LABELS[k] for k in ("ihrcf", "gt", "atda")]
    ax.legend([by_label[k] for k in order], order, loc="upper right", ncol=3, fontsize="small")


def save_figures(results: Results, out: Path) -> list[Path]:
    """Save PNG lookalikes of the paper's Figs. 14-20 into ``out``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    t = results.time
    paths: list[Path] = []

    def series(src: str, what: str) -> NDArray[np.float64]:
        a = results.position[src].copy() if what == "position" else np.degrees(results.euler[src])
        if src != "gt":
            a[~results.valid[src]] = np.nan  # gaps where the estimate is invalid
        return a

    def save(fig: Any, name: str) -> None:
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)

    # Figs. 14 and 15: Euler angles and translations vs time
    for what, names, unit, fname, title in (
        ("euler", ("Roll", "Pitch", "Yaw"), "deg", "fig14_euler_angles.png", "Euler angles of the deck"),
        ("position", ("X", "Y", "Z"), "m", "fig15_translations.png", "Translations of the deck"),
    ):
        fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
        for i, ax in enumerate(axes):
            for src in ("gt", "atda", "ihrcf"):
                ax.plot(t, series(src, what)[:, i], color=COLORS[src], label=LABELS[src], **STYLE[src])
            ax.set_ylabel(f"{names[i]} ({unit})")
            ax.grid(alpha=0.3)
        _legend(axes[0])
        axes[0].set_title(f"{title} in the drone body frame: IHRCF, GT and ATDA")
        axes[-1].set_xlabel("time (s)")
        save(fig, fname)

    # Fig. 16: trajectories, X-Z, Y-Z, X-Y and 3-D
    fig = plt.figure(figsize=(11, 9))
    views = ((0, 2, "X-Z view"), (1, 2, "Y-Z view"), (0, 1, "X-Y view"))
    for j, (a, b, title) in enumerate(views):
        ax = fig.add_subplot(2, 2, j + 1)
        for src in ("gt", "atda", "ihrcf"):
            p = series(src, "position")
            ax.plot(p[:, a], p[:, b], color=COLORS[src], label=LABELS[src], **STYLE[src])
        ax.set_xlabel(f"{'XYZ'[a]} (m)")
        ax.set_ylabel(f"{'XYZ'[b]} (m)")
        ax.set_title(f"({'abc'[j]}) {title}")
        ax.grid(alpha=0.3)
    ax3 = fig.add_subplot(2, 2, 4, projection="3d")
    for src in ("gt", "atda", "ihrcf"):
        p = series(src, "position")
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], color=COLORS[src], label=LABELS[src], **STYLE[src])
    ax3.set_xlabel("X (m)")
    ax3.set_ylabel("Y (m)")
    ax3.set_zlabel("Z (m)")
    ax3.set_title("(d) 3-D trajectory")
    ax3.zaxis.labelpad = 12
    _legend(ax3)
    save(fig, "fig16_trajectories.png")

    # Figs. 17-20: errors of each estimator
    for num, key in ((17, "ihrcf"), (19, "atda")):
        e = errors(results, key)
        for k, (sl, unit, kind, names) in enumerate(
            (
                (slice(0, 3), "m", "translation", ("X", "Y", "Z")),
                (slice(3, 6), "deg", "angle", ("roll", "pitch", "yaw")),
            )
        ):
            fig, ax = plt.subplots(figsize=(9, 4))
            for i, color in enumerate(AXIS_COLORS):
                ax.plot(t, e[:, sl][:, i], color=color, lw=1.0, label=names[i])
            ax.axhline(0.0, color="k", lw=0.5)
            ax.set_xlabel("time (s)")
            ax.set_ylabel(f"error ({unit})")
            ax.set_title(f"{LABELS[key]} {kind} estimation error (estimate minus ground truth)")
            ax.legend(loc="upper right", ncol=3)
            ax.grid(alpha=0.3)
            save(fig, f"fig{num + k}_{key}_{kind}_error.png")
    return paths


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
    sim_s = res.time[-1] if res.n else 0.0
    print()
    hz = res.settings["control_hz"]
    print(f"Deck pose errors (body frame), estimate minus ground truth, {res.n} frames at {hz} Hz")
    print(mae_table(res))
    print(tracking_summary(res))
    csv_path = save_csv(res, args.out / "timeseries.csv")
    saved = [csv_path]
    if not args.no_plots:
        try:
            saved += save_figures(res, args.out)
        except ImportError:
            print("matplotlib is not installed (pip install '.[plots]'): figures skipped")
    (args.out / "table2.txt").write_text(mae_table(res) + "\n")
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
