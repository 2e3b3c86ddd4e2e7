"""Paired validation of the "projected" camera model against the rendered camera.

At the same physical states, with the same ToF and IMU readings, every frame goes through two
pipelines, each into its own :class:`~ihrcf_env.core.estimators.DeckPoseEstimator` (IHRCF, ATDA,
fused; the shipped calibration):

* **rendered**: the TinyRenderer frame -> :class:`~ihrcf_env.core.estimators.TagDetector`
  (``refine="subpix"``);
* **projected**: :class:`~ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera` (exact projection +
  the fitted detector model, ``assets/detector_model.json``), the realistic camera on the rendered
  camera's episode (light, exposure, gain).

The states are short trajectories flown in a :class:`~ihrcf_env.sim.world.World` (20 Hz): the deck
on the ``paper`` profile (started at a random time of its 130 s) or a seeded ``sea_state``, so its
tilts span the profiles' ranges; the drone starting 0.45-3 m above the deck, its centre offset
anywhere out to the image edge, random yaw, holding position or flying a constant velocity command
(to 0.5 m/s, 0.5 rad/s: blur and motion). Both sensor presets: ``"ideal"`` (ideal camera, ToF and
IMU) and ``"realistic"`` (realistic camera, VL53L1X ToF, BMI088 IMU), the autopilot on the true
state in both (the states are what matters here, not how they were flown).

Scores per preset: the detection rate in both modes, and per estimator and axis the mean absolute
error of each mode over the frames where both modes are valid (paired), their ratio (projected /
rendered; ``replicas`` projected runs with independent noise are averaged) and a 90 % bootstrap
interval of the ratio over trajectories. Errors within a trajectory are strongly correlated (a
hovering drone keeps its corner errors in both modes), so the trajectories, not the frames, are
the samples; the fused filter's MAE over a trajectory of 1-2 s is mostly its convergence transient
seeded by the first ATDA attitudes, so a few trajectories decide it and its ratio needs many
trajectories. Acceptance: ratio within 1 +- 0.25 on every axis of every estimator, detection
rates within 3 percentage points.

``python -m ihrcf_env.experiments.camera_validation [--trajectories N] [--frames F] [--seed S]
[--replicas R]`` prints the Markdown table (exit status 1 if a bound is missed).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.detector_model import DetectorModel
from ihrcf_env.core.estimators import DeckPoseEstimator, ImuSample, SensorFrame
from ihrcf_env.core.frames import euler_from_matrix
from ihrcf_env.core.metrics import POSE_AXES, pose_errors
from ihrcf_env.core.profiles import (
    PAPER_DURATION,
    MotionProfile,
    ShiftedProfile,
    paper_profile,
    sea_state_profile,
)

#: Sensor presets of the validation (camera quality, ToF model, IMU noise), as SENSOR_PRESETS.
PRESETS: dict[str, dict[str, str]] = {
    "ideal": {"camera_quality": "ideal", "tof_noise": "ideal", "imu_noise": "ideal"},
    "realistic": {"camera_quality": "realistic", "tof_noise": "realistic", "imu_noise": "realistic"},
}
MODES: tuple[str, ...] = ("rendered", "projected")
ESTIMATORS: tuple[str, ...] = ("ihrcf", "atda", "fused")
#: Bootstrap resamples of the trajectories for the ratio's interval.
BOOTSTRAP = 2000
#: Acceptance bounds: MAE ratio within 1 +- MAE_TOLERANCE, detection rates within DETECTION_TOLERANCE.
MAE_TOLERANCE = 0.25
DETECTION_TOLERANCE = 0.03


@dataclass(frozen=True, eq=False)
class PresetValidation:
    """The paired comparison for one sensor preset.

    Attributes:
        preset: ``"ideal"`` or ``"realistic"``. frames: frames compared. trajectories: their count.
        detection: mode -> fraction of frames with tag corners.
        mae: mode -> estimator -> (6,) MAE over the frames where both modes are valid: X, Y, Z (m),
            roll, pitch, yaw (deg).
        paired: estimator -> frames where both modes are valid. valid: mode -> estimator -> valid
            frames.
        corner_rms: mode -> RMS corner error (px) against the exact projection, over frames where
            both modes found the tag.
        seconds: wall time of the run. replicas: projected runs averaged.
        trajectory_mae: mode -> estimator -> (trajectories, 6) paired MAE per trajectory (NaN
            where none): where the modes differ.
        p95: mode -> estimator -> (6,) 95th percentile of the absolute error over the same paired
            frames (units as ``mae``): whether the model reproduces the large errors as well as
            the mean (informative; not an acceptance bound).
        ratio_ci: estimator -> (2, 6) 90 % bootstrap interval (over trajectories) of the MAE
            ratio: the sampling uncertainty of the comparison. Errors within a trajectory are
            strongly correlated (a hovering drone keeps its corner errors), so the trajectories,
            not the frames, are the samples; the fused filter's MAE is dominated by a few
            trajectories with large excursions (ATDA's planar-ambiguity flips).
    """

    preset: str
    frames: int
    trajectories: int
    detection: dict[str, float]
    mae: dict[str, dict[str, NDArray[np.float64]]]
    paired: dict[str, int]
    valid: dict[str, dict[str, int]]
    corner_rms: dict[str, float]
    seconds: float
    replicas: int = 1
    trajectory_mae: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)
    ratio_ci: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    p95: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)

    def ratio(self, estimator: str) -> NDArray[np.float64]:
        """(6,) projected / rendered MAE of ``estimator``, per axis."""
        r: NDArray[np.float64] = self.mae["projected"][estimator] / self.mae["rendered"][estimator]
        return r

    def failures(
        self, mae_tolerance: float = MAE_TOLERANCE, detection_tolerance: float = DETECTION_TOLERANCE
    ) -> list[str]:
        """What misses the acceptance bounds (empty when everything is within them)."""
        out = []
        dd = self.detection["projected"] - self.detection["rendered"]
        if not abs(dd) <= detection_tolerance:
            out.append(f"{self.preset}: detection rate {100 * dd:+.1f} pp")
        for est in self.mae["rendered"]:
            if self.paired[est] == 0:  # e.g. the fused filter on trajectories shorter than its convergence
                continue
            for axis, r in zip(POSE_AXES, self.ratio(est), strict=True):
                if not abs(r - 1.0) <= mae_tolerance:
                    out.append(f"{self.preset}: {est} {axis} MAE ratio {r:.2f}")
        return out


@dataclass(frozen=True, eq=False)
class CameraValidation:
    """The validation over the presets (:func:`validate_camera_model`)."""

    presets: dict[str, PresetValidation]
    settings: dict[str, object] = field(default_factory=dict)

    def failures(
        self, mae_tolerance: float = MAE_TOLERANCE, detection_tolerance: float = DETECTION_TOLERANCE
    ) -> list[str]:
        """Every miss of the acceptance bounds, over all presets."""
        return [f for v in self.presets.values() for f in v.failures(mae_tolerance, detection_tolerance)]

    def markdown(self) -> str:
        """The tables (one per preset): per estimator and axis the rendered and projected MAE and
        their ratio; detection rates; corner RMS."""
        lines: list[str] = []
        for name, v in self.presets.items():
            dpp = 100 * (v.detection["projected"] - v.detection["rendered"])
            lines += [
                f"**sensor_preset={name!r}**: {v.frames} frames ({v.trajectories} trajectories), "
                f"detection rendered {100 * v.detection['rendered']:.1f} % / projected "
                f"{100 * v.detection['projected']:.1f} % ({dpp:+.1f} pp); "
                f"corner RMS vs projection rendered {v.corner_rms['rendered']:.3f} px / projected "
                f"{v.corner_rms['projected']:.3f} px",
                "",
                "Valid frames, rendered / projected: "
                + ", ".join(
                    f"{est} {100 * v.valid['rendered'][est] / v.frames:.1f} / "
                    f"{100 * v.valid['projected'][est] / v.frames:.1f} %"
                    for est in v.valid["rendered"]
                ),
                "",
                "| estimator | axis | rendered MAE | projected MAE | ratio | 90 % interval | p95 ratio |",
                "|---|---|---|---|---|---|---|",
            ]
            for est in v.mae["rendered"]:
                if v.paired[est] == 0:
                    lines.append(f"| {est} (no paired valid frames) | | | | | | |")
                    continue
                for i, axis in enumerate(POSE_AXES):
                    unit, fmt = ("mm", 1e3) if i < 3 else ("deg", 1.0)
                    a, b = v.mae["rendered"][est][i] * fmt, v.mae["projected"][est][i] * fmt
                    flag = "" if abs(v.ratio(est)[i] - 1) <= MAE_TOLERANCE else " **"
                    ci = v.ratio_ci.get(est)
                    interval = f"{ci[0, i]:.2f}-{ci[1, i]:.2f}" if ci is not None else ""
                    p95 = (
                        f"{v.p95['projected'][est][i] / v.p95['rendered'][est][i]:.2f}"
                        if est in v.p95.get("rendered", {})
                        else ""
                    )
                    lines.append(
                        f"| {est} ({v.paired[est]} frames) | {axis} ({unit}) | {a:.3f} | {b:.3f} "
                        f"| {b / a:.2f}{flag} | {interval} | {p95} |"
                    )
            lines.append("")
        fails = self.failures()
        lines.append(
            "All within the bounds." if not fails else "Outside the bounds (**): " + "; ".join(fails)
        )
        return "\n".join(lines)


def _estimators(
    cal: Calibration, tag_size: float, tag_id: int, tof_model: object, names: Sequence[str] = ESTIMATORS
) -> DeckPoseEstimator:
    from ihrcf_env.config.observation import fused_params_for_tof
    from ihrcf_env.wrappers import estimator_from_calibration

    return estimator_from_calibration(
        cal,
        tag_size,
        tag_id,
        estimators=tuple(names),
        fused_params=fused_params_for_tof(tof_model),  # type: ignore[arg-type]
    )


def validate_preset(
    preset: str,
    trajectories: int = 40,
    frames: int = 30,
    seed: int = 0,
    model: DetectorModel | None = None,
    calibration: Calibration | None = None,
    progress: Callable[[int, int], None] | None = None,
    replicas: int = 1,
    altitudes: tuple[float, float] = (0.45, 3.0),
    offset_fraction: float = 1.0,
    estimators: Sequence[str] = ESTIMATORS,
    warmup: int = 0,
) -> PresetValidation:
    """The paired comparison for one preset (see the module docstring): ``trajectories`` of
    ``frames`` control steps each, seeded by ``seed``. ``replicas`` projected cameras (independent
    noise, each with its own estimators) run beside the rendered one; their MAE and detection rate
    are averaged (less sampling noise on the projected side). Start altitudes are uniform in
    ``altitudes`` (m above the deck) and the horizontal offset uniform over a disk reaching
    ``offset_fraction`` of the way to the image edge. ``estimators``: the registered estimators
    compared (default IHRCF, ATDA, fused). The first ``warmup`` frames of every trajectory reach
    the estimators but are not scored (e.g. ATDA's first frame, without its flip prior)."""
    from ihrcf_env.config.sensors import CameraConfig, IMUConfig, ToFConfig
    from ihrcf_env.config.world import WorldConfig
    from ihrcf_env.sim.sensors.tag_camera import ProjectedTagCamera
    from ihrcf_env.sim.world import World

    if preset not in PRESETS:
        raise ValueError(f"preset must be one of {tuple(PRESETS)}, got {preset!r}")
    for name, count in (("trajectories", trajectories), ("frames", frames), ("replicas", replicas)):
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError(f"{name} must be a positive integer, got {count!r}")
    if not (0.3 <= altitudes[0] <= altitudes[1] <= 5.0):
        raise ValueError(f"altitudes must be (low, high) with 0.3 <= low <= high <= 5 m, got {altitudes!r}")
    if not (0.0 <= offset_fraction <= 1.5):
        raise ValueError(f"offset_fraction must be in [0, 1.5], got {offset_fraction!r}")
    if isinstance(warmup, bool) or not isinstance(warmup, int) or not 0 <= warmup < frames:
        raise ValueError(f"warmup must be an integer in [0, frames), got {warmup!r}")
    names = tuple(estimators)
    unknown = [e for e in names if e not in ESTIMATORS]
    if unknown or not names:
        raise ValueError(f"estimators must be a non-empty subset of {ESTIMATORS}, got {estimators!r}")
    t_start = time.perf_counter()
    model = model if model is not None else DetectorModel.load()
    cal = calibration if calibration is not None else Calibration.load(default_calibration_path())
    cfg = PRESETS[preset]
    wcfg = WorldConfig(
        camera=CameraConfig(quality=cfg["camera_quality"]),
        tof=ToFConfig(noise=cfg["tof_noise"]),
        imu=IMUConfig(cfg["imu_noise"]),
    )
    rng = np.random.default_rng(seed)
    replica_rngs = [np.random.default_rng([seed, 1, i]) for i in range(replicas)]
    channels = ["rendered", *(f"projected{i}" for i in range(replicas))]
    lo_alt, hi_alt = altitudes
    world = World(wcfg)
    try:
        assert world.camera is not None and wcfg.camera is not None
        deck_cfg = wcfg.deck
        projs = [
            ProjectedTagCamera(world.client, wcfg.camera, wcfg.rig, world.deck, deck_cfg.tag_size, model)
            for _ in range(replicas)
        ]
        pipes = {
            ch: _estimators(cal, deck_cfg.tag_size, deck_cfg.tag_id, wcfg.tof.model, names) for ch in channels
        }
        detector = pipes["rendered"].detector
        dt = wcfg.substeps / wcfg.physics_hz
        errs: dict[str, dict[str, list[NDArray[np.float64]]]] = {
            ch: {e: [] for e in names} for ch in channels
        }
        found = dict.fromkeys(channels, 0)
        corner_sq: dict[str, list[float]] = {m: [] for m in MODES}
        n = 0
        traj_of_frame: list[int] = []
        for traj in range(trajectories):
            ep_rng = np.random.default_rng([seed, traj])
            profile: MotionProfile
            if traj % 2 == 0:
                profile = ShiftedProfile(paper_profile(), float(ep_rng.uniform(0.0, PAPER_DURATION)))
            else:
                profile = sea_state_profile(ep_rng)
            altitude = float(ep_rng.uniform(lo_alt, hi_alt))
            reach = (altitude - 0.03) * math.tan(wcfg.camera.fov / 2) * offset_fraction
            heading = ep_rng.uniform(0.0, 2.0 * math.pi)
            radius = reach * math.sqrt(ep_rng.uniform())  # uniform over the disk
            offset = radius * np.array([math.cos(heading), math.sin(heading)])
            yaw = float(ep_rng.uniform(-math.pi, math.pi))
            world.reset(
                profile,
                horizon_s=frames * dt + 2.0,
                altitude=altitude,
                offset_xy=(float(offset[0]), float(offset[1])),
                yaw=yaw,
            )
            world.reset_random(ep_rng)
            for proj, r in zip(projs, replica_rngs, strict=True):
                proj.reset(r, episode=world.camera.episode)
            if ep_rng.random() < 0.5:
                setpoint = np.zeros(4)
            else:
                v = ep_rng.uniform(-0.5, 0.5, 2)
                vz = float(np.clip(ep_rng.uniform(-0.1, 0.1), (lo_alt - altitude) / (frames * dt), 0.3))
                setpoint = np.array([v[0], v[1], vz, ep_rng.uniform(-0.5, 0.5)])
            world.set_velocity_setpoint(setpoint)
            for pipe in pipes.values():
                pipe.reset()
            for k in range(frames):
                scored = k >= warmup  # warm-up frames reach the estimators but are not scored
                world.step()
                state = world.sensing.body_state()
                tof = world.tof.read(state, dt, rng)
                imu_r = world.imu_sensor.read(state, dt, rng)
                imu = ImuSample(imu_r["quaternion"], imu_r["angular_velocity"], imu_r["linear_acceleration"])
                world.deck.update_visuals()
                image = world.camera.read(state, dt, rng)["image"]
                corners: dict[str, NDArray[np.float64] | None] = {"rendered": detector.detect(image)}
                reasons = {"rendered": ""}
                for i, (proj, r) in enumerate(zip(projs, replica_rngs, strict=True)):
                    reading = proj.read(state, dt, r)
                    seen = bool(reading["tag_detected"])
                    corners[f"projected{i}"] = reading["tag_corners"] if seen else None
                    reasons[f"projected{i}"] = str(reading["tag_reason"])
                truth = projs[0].last_features
                p_bd, R_bd = world.sensing.deck_in_body()
                gt_euler = euler_from_matrix(R_bd)
                ranges = np.asarray(tof["ranges"], dtype=np.float64)
                ranges_valid = np.asarray(tof["ranges_valid"]).astype(bool)
                for ch in channels:
                    c = corners[ch]
                    found[ch] += scored and c is not None
                    frame = SensorFrame(
                        time=world.time,
                        corners=c,
                        ranges=ranges,
                        ranges_valid=ranges_valid,
                        corners_reason=reasons[ch],
                        imu=imu,
                    )
                    for est, out in pipes[ch].update(frame).items():
                        if scored:
                            errs[ch][est].append(
                                pose_errors(out.position, out.euler, p_bd, gt_euler, [out.valid])[0]
                            )
                if not scored:
                    continue
                cr = corners["rendered"]
                if truth is not None and cr is not None:
                    for i in range(replicas):
                        cp = corners[f"projected{i}"]
                        if cp is not None:
                            corner_sq["rendered"].append(float(((cr - truth.corners) ** 2).mean()))
                            corner_sq["projected"].append(float(((cp - truth.corners) ** 2).mean()))
                n += 1
                traj_of_frame.append(traj)
            if progress is not None:
                progress(traj + 1, trajectories)
    finally:
        world.close()
    mae: dict[str, dict[str, NDArray[np.float64]]] = {m: {} for m in MODES}
    p95: dict[str, dict[str, NDArray[np.float64]]] = {m: {} for m in MODES}
    trajectory_mae: dict[str, dict[str, NDArray[np.float64]]] = {}
    ratio_ci: dict[str, NDArray[np.float64]] = {}
    paired: dict[str, int] = {}
    valid: dict[str, dict[str, int]] = {m: {} for m in MODES}
    for est in names:
        e = {ch: np.array(errs[ch][est]) for ch in channels}
        ok = {ch: np.all(np.isfinite(e[ch]), axis=1) for ch in channels}
        counts = []
        means: dict[str, list[NDArray[np.float64]]] = {m: [] for m in MODES}
        tails: dict[str, list[NDArray[np.float64]]] = {m: [] for m in MODES}
        for ch in channels[1:]:  # each replica paired with the rendered run
            both = ok["rendered"] & ok[ch]
            counts.append(int(both.sum()))
            for m, err in (("rendered", e["rendered"]), ("projected", e[ch])):
                a = np.abs(err[both])
                means[m].append(a.mean(axis=0) if both.any() else np.full(6, np.nan))
                tails[m].append(np.percentile(a, 95.0, axis=0) if both.any() else np.full(6, np.nan))
        for m in MODES:
            mae[m][est] = np.mean(means[m], axis=0)
            p95[m][est] = np.mean(tails[m], axis=0)
        tid = np.array(traj_of_frame)
        per = {m: np.full((trajectories, 6), np.nan) for m in MODES}
        sums = {m: np.zeros((trajectories, 6)) for m in MODES}  # summed |error| of the paired frames
        for t in range(trajectories):
            r_vals, p_vals = [], []
            for ch in channels[1:]:
                sel = (tid == t) & ok["rendered"] & ok[ch]
                if sel.any():
                    r_vals.append(np.abs(e["rendered"][sel]).mean(axis=0))
                    p_vals.append(np.abs(e[ch][sel]).mean(axis=0))
                    sums["rendered"][t] += np.abs(e["rendered"][sel]).sum(axis=0)
                    sums["projected"][t] += np.abs(e[ch][sel]).sum(axis=0)
            if r_vals:
                per["rendered"][t], per["projected"][t] = np.mean(r_vals, axis=0), np.mean(p_vals, axis=0)
        for m in MODES:
            trajectory_mae.setdefault(m, {})[est] = per[m]
        # bootstrap over trajectories (paired frames: the ratio of the summed errors)
        boot = np.random.default_rng([seed, 2]).integers(0, trajectories, (BOOTSTRAP, trajectories))
        with np.errstate(invalid="ignore", divide="ignore"):
            ratios = sums["projected"][boot].sum(axis=1) / sums["rendered"][boot].sum(axis=1)
        finite = np.isfinite(ratios).all(axis=1)
        ratio_ci[est] = (
            np.percentile(ratios[finite], [5.0, 95.0], axis=0) if finite.any() else np.full((2, 6), np.nan)
        )
        paired[est] = int(round(float(np.mean(counts))))
        valid["rendered"][est] = int(ok["rendered"].sum())
        valid["projected"][est] = int(round(float(np.mean([ok[ch].sum() for ch in channels[1:]]))))
    return PresetValidation(
        preset=preset,
        frames=n,
        trajectories=trajectories,
        detection={
            "rendered": found["rendered"] / max(n, 1),
            "projected": float(np.mean([found[ch] for ch in channels[1:]])) / max(n, 1),
        },
        mae=mae,
        paired=paired,
        valid=valid,
        corner_rms={m: math.sqrt(float(np.mean(corner_sq[m]))) if corner_sq[m] else math.nan for m in MODES},
        seconds=time.perf_counter() - t_start,
        replicas=replicas,
        trajectory_mae=trajectory_mae,
        ratio_ci=ratio_ci,
        p95=p95,
    )


def validate_camera_model(
    presets: Iterable[str] = tuple(PRESETS),
    trajectories: int = 40,
    frames: int = 30,
    seed: int = 0,
    model: DetectorModel | None = None,
    calibration: Calibration | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    replicas: int = 1,
    altitudes: tuple[float, float] = (0.45, 3.0),
    offset_fraction: float = 1.0,
    estimators: Sequence[str] = ESTIMATORS,
    warmup: int = 0,
) -> CameraValidation:
    """:func:`validate_preset` for every preset in ``presets`` (same seed: the same starts under
    both presets); see it for the arguments."""
    model = model if model is not None else DetectorModel.load()
    out = {}
    for preset in presets:
        cb = None if progress is None else (lambda d, n, p=preset: progress(p, d, n))
        out[preset] = validate_preset(
            preset,
            trajectories,
            frames,
            seed,
            model,
            calibration,
            cb,
            replicas,
            altitudes,
            offset_fraction,
            estimators,
            warmup,
        )
    settings: dict[str, object] = {
        "trajectories": trajectories,
        "frames": frames,
        "seed": seed,
        "replicas": replicas,
        "altitudes": altitudes,
        "offset_fraction": offset_fraction,
        "estimators": tuple(estimators),
        "warmup": warmup,
        "model": model.source,
    }
    return CameraValidation(out, settings)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m ihrcf_env.experiments.camera_validation",
        description="Paired validation of the projected camera model against rendered frames + TagDetector.",
    )
    ap.add_argument("--trajectories", type=int, default=40, help="trajectories per preset (default 40)")
    ap.add_argument("--frames", type=int, default=30, help="control steps per trajectory (default 30)")
    ap.add_argument("--replicas", type=int, default=1, help="projected runs per frame, averaged (default 1)")
    ap.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    ap.add_argument("--presets", nargs="+", default=list(PRESETS), choices=list(PRESETS))
    ap.add_argument("--model", default=None, help="detector model file (default: the shipped one)")
    ap.add_argument("--markdown", default=None, help="also write the table to this file")
    args = ap.parse_args(argv)
    model = DetectorModel.load(args.model)
    res = validate_camera_model(
        args.presets, args.trajectories, args.frames, args.seed, model, replicas=args.replicas
    )
    text = res.markdown()
    print(text)
    for v in res.presets.values():
        print(f"{v.preset}: {v.seconds:.1f} s")
    if args.markdown:
        Path(args.markdown).write_text(text + "\n", encoding="utf-8")
    return 0 if not res.failures() else 1


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "BOOTSTRAP",
    "DETECTION_TOLERANCE",
    "ESTIMATORS",
    "MAE_TOLERANCE",
    "MODES",
    "PRESETS",
    "CameraValidation",
    "PresetValidation",
    "main",
    "validate_camera_model",
    "validate_preset",
]
