"""Fit the detector model of the "projected" camera to rendered frames (the fit's experiment).

:func:`fit_detector_model` renders frames in a
:class:`~ihrcf_env.sim.world.World` (512x512, 60 deg, the default camera) for both camera qualities,
runs :class:`~ihrcf_env.core.estimators.TagDetector` (``refine="subpix"``) on each, pairs them with
the exact projection of the same state (:class:`~ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera`
features) and fits :class:`~ihrcf_env.core.detector_model.QualityParams` per quality
(:func:`~ihrcf_env.core.detector_model.fit_quality`). Seeded and re-runnable; the
command line ``ihrcf-fit-detector`` (:mod:`ihrcf_env.cli.fit_detector`) runs it and writes the
model file.

The frames (no physics: poses and velocities are placed directly):

* tracks of 6 consecutive 20 Hz frames (``frames`` per quality): camera-to-tag distance along
  the optical axis 0.4-3 m (log-uniform: as many frames of tags 150-450 px wide as of 60-150 px),
  deck roll/pitch to +-0.23 rad (the ``paper`` profile's ~13 deg peaks; ``sea_state``'s 8/5 deg
  are inside), drone roll/pitch to +-0.2 rad, random yaw, the tag centre anywhere in the image
  (35 % of the tracks out to 1.15x the half field of view, so the tag crosses the border), drone
  velocity to 1.5 m/s and rate to 3 rad/s, deck rates of a few cm/s and deg/s; 30 % of the tracks
  nearly still (drone to 1 cm/s and 0.01 rad/s, deck five times slower: corners moving 0.02-0.1 px
  per frame), for the correlation at sub-pixel motion;
* single frames of a small tag, 6-40 m away (camera far plane moved to 45 m for them), for the
  size limit (``frames // 10``);
* single frames of a deck tilted 30-88 deg, for the obliqueness limit (``frames // 10``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.core.detector_model import (
    FIT_COMMAND,
    N_BASIS,
    QUALITIES,
    DetectorModel,
    DetectorSamples,
    QualityParams,
    fit_detector_params,
)
from ihrcf_env.core.estimators.detector import TagDetector
from ihrcf_env.core.frames import R_BODY_CAM, matrix_from_euler, quat_from_matrix

FRAMES_PER_TRACK = 6
CONTROL_DT = 0.05


def _rotvec(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrix of a rotation vector (rad)."""
    a = float(np.linalg.norm(w))
    if a < 1e-12:
        return np.eye(3)
    k = w / a
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * Kx + (1.0 - math.cos(a)) * Kx @ Kx


def _euler(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    return matrix_from_euler(float(roll), float(pitch), float(yaw))


def _ball(rng: np.random.Generator, radius: float) -> NDArray[np.float64]:
    v = rng.standard_normal(3)
    return v / max(float(np.linalg.norm(v)), 1e-12) * radius


def collect_samples(
    quality: str,
    frames: int,
    seed: int,
    progress: Callable[[int, int], None] | None = None,
) -> DetectorSamples:
    """Render and detect ``frames`` track frames plus ``frames // 10`` small-tag and ``frames // 10``
    oblique frames of camera ``quality`` (see the module docstring), seeded by ``seed``."""
    from ihrcf_env.config.sensors import CameraConfig
    from ihrcf_env.config.world import WorldConfig
    from ihrcf_env.core.profiles import StaticProfile
    from ihrcf_env.sim.sensors.base import BodyState
    from ihrcf_env.sim.sensors.camera import DownCamera
    from ihrcf_env.sim.sensors.tag_camera import ProjectedTagCamera
    from ihrcf_env.sim.world import World

    if quality not in QUALITIES:
        raise ValueError(f"quality must be one of {QUALITIES}, got {quality!r}")
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < FRAMES_PER_TRACK:
        raise ValueError(f"frames must be an integer >= {FRAMES_PER_TRACK}, got {frames!r}")
    rng = np.random.default_rng(seed)
    cam_cfg = CameraConfig(quality=quality)
    world = World(WorldConfig(camera=cam_cfg))
    try:
        world.reset(StaticProfile(), horizon_s=1.0, altitude=1.0)
        cid = world.client
        deck = world.deck
        rig = world.config.rig
        tag_size = world.config.deck.tag_size
        zeros = (0.0,) * N_BASIS
        dummy = DetectorModel({q: QualityParams(zeros, zeros, zeros, zeros) for q in QUALITIES})
        far_cfg = replace(cam_cfg, far=45.0)
        cams = {
            "near": (
                DownCamera(cid, cam_cfg, rig),
                ProjectedTagCamera(cid, cam_cfg, rig, deck, tag_size, dummy),
            ),
            "far": (
                DownCamera(cid, far_cfg, rig),
                ProjectedTagCamera(cid, far_cfg, rig, deck, tag_size, dummy),
            ),
        }
        detector = TagDetector(world.config.deck.tag_id, "subpix")
        home, _ = deck.pose()
        half_thickness = world.config.deck.thickness / 2
        cam_off = np.asarray(rig.camera_position, dtype=np.float64)
        tan_half = math.tan(cam_cfg.fov / 2)
        rows: dict[str, list[Any]] = {k: [] for k in ("c", "q", "cos", "nr", "blur", "det", "track")}
        n_far = n_obl = max(1, frames // 10)
        plan = ["track"] * (frames // FRAMES_PER_TRACK) + ["far"] * n_far + ["oblique"] * n_obl
        total = len(plan)
        done = 0
        for track_id, kind in enumerate(plan):
            n_frames = FRAMES_PER_TRACK if kind == "track" else 1
            down, proj = cams["far" if kind == "far" else "near"]
            down.reset(rng)
            proj.reset(rng, episode=down.episode)
            R_wd = _euler(rng.uniform(-0.23, 0.23), rng.uniform(-0.23, 0.23), rng.uniform(-0.1, 0.1))
            R_wb = _euler(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-math.pi, math.pi))
            if kind == "track":
                depth = math.exp(rng.uniform(math.log(0.4), math.log(3.0)))  # log-uniform
                wide = rng.random() < 0.35
                xn = rng.uniform(-1.15, 1.15, 2) if wide else rng.uniform(-0.7, 0.7, 2)
                still = rng.random() < 0.3
                v = _ball(rng, rng.uniform(0.0, 0.01 if still else 1.5))
                w_max = 0.01 if still else (0.2 if rng.random() < 0.5 else 3.0)
                w = _ball(rng, rng.uniform(0.0, w_max))
            else:
                xn = rng.uniform(-0.3, 0.3, 2)
                v = w = np.zeros(3)
                if kind == "far":
                    depth = rng.uniform(6.0, 40.0)
                else:
                    depth = rng.uniform(0.7, 3.0)
                    axis = np.array([*rng.standard_normal(2), 0.0])
                    R_wd = _rotvec(axis / np.linalg.norm(axis) * math.radians(rng.uniform(30.0, 88.0)))
            deck_rate = 0.2 if kind == "track" and still else 1.0
            v_deck, w_deck = rng.normal(0.0, 0.02 * deck_rate, 3), rng.normal(0.0, 0.03 * deck_rate, 3)
            R_wc = R_wb @ R_BODY_CAM
            eye = home - R_wc @ (depth * np.array([xn[0] * tan_half, xn[1] * tan_half, 1.0]))
            pos0 = eye - R_wb @ cam_off
            for k in range(n_frames):
                t = k * CONTROL_DT
                Rb = _rotvec(w * t) @ R_wb
                pb = pos0 + v * t
                Rd = _rotvec(w_deck * t) @ R_wd
                pd = home + v_deck * t
                p.resetBasePositionAndOrientation(
                    world.quad.body, pb.tolist(), quat_from_matrix(Rb).tolist(), physicsClientId=cid
                )
                p.resetBasePositionAndOrientation(
                    deck.body,
                    (pd - Rd[:, 2] * half_thickness).tolist(),
                    quat_from_matrix(Rd).tolist(),
                    physicsClientId=cid,
                )
                deck.update_visuals()
                state = BodyState(
                    time=t,
                    position=pb,
                    rotation=Rb,
                    quaternion=quat_from_matrix(Rb),
                    velocity=v,
                    angular_velocity=w,
                    acceleration=np.zeros(3),
                )
                f, _ = proj.features(state)
                if f is None:  # outside the depth range: nothing to pair
                    continue
                image = down.read(state, CONTROL_DT, rng)["image"]
                found = detector.detect(image)
                rows["c"].append(f.corners)
                rows["q"].append(f.quiet_zone)
                rows["cos"].append(f.cos_view)
                rows["nr"].append(np.array(f.noise_ratio))
                rows["blur"].append(f.blur_px)
                rows["det"].append(found if found is not None else np.full((4, 2), np.nan))
                rows["track"].append(track_id)
            done += 1
            if progress is not None:
                progress(done, total)
    finally:
        world.close()
    return DetectorSamples(
        corners=np.array(rows["c"]),
        quiet_zone=np.array(rows["q"]),
        cos_view=np.array(rows["cos"]),
        noise_ratio=np.array(rows["nr"]),
        blur_px=np.array(rows["blur"]),
        detected=np.array(rows["det"]),
        track=np.array(rows["track"], dtype=np.int64),
        width=cam_cfg.width,
        height=cam_cfg.height,
    )


def save_samples(samples: DetectorSamples, path: str | Path) -> None:
    """Write collected frames to an ``.npz`` file (for analysis; :func:`load_samples` reads it)."""
    np.savez_compressed(
        path,
        corners=samples.corners,
        quiet_zone=samples.quiet_zone,
        cos_view=samples.cos_view,
        noise_ratio=samples.noise_ratio,
        blur_px=samples.blur_px,
        detected=samples.detected,
        track=samples.track,
        size=np.array([samples.width, samples.height]),
    )


def load_samples(path: str | Path) -> DetectorSamples:
    """The frames written by :func:`save_samples`."""
    with np.load(path) as d:
        w, h = (int(v) for v in d["size"])
        return DetectorSamples(
            corners=d["corners"],
            quiet_zone=d["quiet_zone"],
            cos_view=d["cos_view"],
            noise_ratio=d["noise_ratio"],
            blur_px=d["blur_px"],
            detected=d["detected"],
            track=d["track"],
            width=w,
            height=h,
        )


def fit_detector_model(
    frames: int = 1200,
    seed: int = 0,
    progress: Callable[[str, int, int], None] | None = None,
    samples_dir: str | Path | None = None,
) -> DetectorModel:
    """Collect frames of both qualities (:func:`collect_samples`, seeds ``seed`` and ``seed + 1``)
    and fit the model; its ``fit`` record holds the settings, timings and the fit reports. With
    ``samples_dir`` the frames are also written there (``<quality>.npz``, :func:`save_samples`)."""
    from ihrcf_env._version import __version__
    from ihrcf_env.config.sensors import CameraConfig

    collected: dict[str, DetectorSamples] = {}
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    for i, quality in enumerate(QUALITIES):
        t1 = time.perf_counter()
        cb = None if progress is None else (lambda d, n, q=quality: progress(q, d, n))
        collected[quality] = collect_samples(quality, frames, seed + i, cb)
        if samples_dir is not None:
            Path(samples_dir).mkdir(parents=True, exist_ok=True)
            save_samples(collected[quality], Path(samples_dir) / f"{quality}.npz")
        timings[quality] = round(time.perf_counter() - t1, 1)
    t2 = time.perf_counter()
    params, reports = fit_detector_params(collected)
    for quality, seconds in timings.items():
        reports[quality]["render_seconds"] = seconds
    reports["pooled"]["fit_seconds"] = round(time.perf_counter() - t2, 1)
    cam = CameraConfig()
    fit = {
        "command": f"{FIT_COMMAND} --seed {seed} --frames {frames}",
        "created_with": f"ihrcf_env {__version__}",
        "seed": seed,
        "frames_per_quality": frames,
        "camera": {
            "width": cam.width,
            "height": cam.height,
            "fov": cam.fov,
            "distortion": list(cam.distortion),
        },
        "detector": "TagDetector(refine='subpix')",
        "seconds": round(time.perf_counter() - t0, 1),
        "reports": reports,
    }
    return DetectorModel(params, fit=fit)


__all__ = [
    "CONTROL_DT",
    "FRAMES_PER_TRACK",
    "collect_samples",
    "fit_detector_model",
    "load_samples",
    "save_samples",
]
