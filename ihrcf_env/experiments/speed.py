"""Speed figures: the wrapped env per camera mode, the cost of each component, vector-env scaling.

All at the paper's experiment (drone hovering 1 m above the deck on the ``"paper"`` profile, zero
velocity commands, 20 Hz control, 240 Hz physics, 512x512 camera, the ideal preset unless given).
Wall times come from ``time.perf_counter``; a few warm-up steps are not counted. The figures depend
on the machine and on what else runs on it: the benchmark CLI pins itself to one core.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.threads import one_blas_thread

WRAPPED = "ihrcf_env/DeckHover-v0"
#: The wrapped env's camera modes: label -> gym.make kwargs (all estimators, 1 m hover).
CAMERA_MODES: dict[str, dict[str, Any]] = {
    "rendered 512, image kept": {"keep_image": True},
    "rendered 512, tag window": {"keep_image": False},
    "projected": {"camera_model": "projected"},
}


@dataclass(frozen=True)
class Speed:
    """Steps per second of one configuration and its real-time factor (simulated s per wall s)."""

    label: str
    steps_per_s: float
    real_time_factor: float


def steps_per_second(
    env: gym.Env, steps: int, warmup: int = 5, options: dict[str, Any] | None = None
) -> float:
    """Env steps per wall-clock second of ``env`` (already made; reset here with seed 0 and
    ``options``) under zero actions, ``warmup`` steps not counted. Does not close ``env``."""
    env.reset(seed=0, options=options)
    a = np.zeros(4, dtype=np.float32)  # the deck-landing action: hold position
    for _ in range(warmup):
        env.step(a)
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(a)
    return steps / (time.perf_counter() - t0)


def _hover_kwargs(control_hz: int) -> dict[str, Any]:
    return {"deck_profile": "paper", "control_hz": control_hz, "start_altitude_jitter": 0.0}


def wrapped_speed(
    label: str,
    kwargs: Mapping[str, Any],
    steps: int = 300,
    control_hz: int = 20,
    warmup: int = 5,
) -> Speed:
    """Steps/s of the wrapped env (``ihrcf_env/DeckHover-v0``, flat observation unless the kwargs
    keep the image) with ``kwargs``, zero actions, at the 1 m hover."""
    kw = {**_hover_kwargs(control_hz), **kwargs}
    if not kw.get("keep_image", False):
        kw.setdefault("flatten", True)
    env = gym.make(WRAPPED, max_episode_steps=None, horizon_s=(steps + warmup) / control_hz + 5, **kw)
    try:
        sps = steps_per_second(env, steps, warmup, {"altitude": 1.0, "offset": (0.0, 0.0), "yaw": 0.0})
    finally:
        env.close()
    return Speed(label, sps, sps / control_hz)


def mode_speeds(steps: int = 300, sensor_preset: str = "ideal") -> list[Speed]:
    """:func:`wrapped_speed` of every :data:`CAMERA_MODES` entry, in one run (ratios comparable)."""
    return [
        wrapped_speed(label, {**kw, "sensor_preset": sensor_preset}, steps)
        for label, kw in CAMERA_MODES.items()
    ]


@contextmanager
def _all_cores() -> Iterator[None]:
    """Undo a one-core pinning (the benchmark's) while the block runs."""
    if not hasattr(os, "sched_getaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    try:
        os.sched_setaffinity(0, set(range(os.cpu_count() or 1)))
        yield
    finally:
        os.sched_setaffinity(0, before)


def _make_projected(control_hz: int) -> Callable[[], gym.Env]:
    def make() -> gym.Env:  # the worker imports this module, which registers the envs
        return gym.make(
            WRAPPED,
            camera_model="projected",
            flatten=True,
            max_episode_steps=None,
            **_hover_kwargs(control_hz),
        )

    return make


def vector_scaling(steps: int = 600, workers: int = 2, control_hz: int = 20) -> dict[str, float]:
    """Environment steps per second of ``workers`` projected envs in a ``gym.vector.AsyncVectorEnv``
    (one process each) against one env in this process; ``factor`` = vector / single. Uses all
    cores (the one-core pinning is lifted while it runs)."""
    make = _make_projected(control_hz)
    single = make()
    try:
        sps_single = steps_per_second(single, steps)
    finally:
        single.close()
    with _all_cores():
        with one_blas_thread():
            vec = gym.vector.AsyncVectorEnv([make] * workers)
        try:
            vec.reset(seed=0)
            actions = np.zeros((workers, 4), dtype=np.float32)
            for _ in range(5):
                vec.step(actions)
            t0 = time.perf_counter()
            n = max(1, steps // workers)
            for _ in range(n):
                vec.step(actions)
            sps_vec = n * workers / (time.perf_counter() - t0)
        finally:
            vec.close()
    return {
        "workers": float(workers),
        "single_steps_per_s": sps_single,
        "vector_steps_per_s": sps_vec,
        "factor": sps_vec / sps_single,
    }


def projected_step_costs(
    steps: int = 300, control_hz: int = 20, sensor_preset: str = "ideal"
) -> dict[str, float]:
    """Mean ms per control step of the parts of the projected wrapped env's step at the 1 m hover,
    timed inside it (warm caches, as a learner runs it): ``env`` (the raw env's step: physics,
    sensors, reward, info), each estimator's update in the wrapper's order (IHRCF's 3-D corners and
    ATDA's IPPE solutions are shared with the fused filter), ``wrapper`` (the rest: the sensor frame,
    the flat observation, the ground truth, gymnasium's wrappers) and ``total``. The parts are timed
    by wrapping those methods of this one env instance (it is closed afterwards)."""
    from ihrcf_env.wrappers.estimates import DeckPoseObservation

    kw = {
        **_hover_kwargs(control_hz),
        "camera_model": "projected",
        "flatten": True,
        "sensor_preset": sensor_preset,
    }
    env = gym.make(WRAPPED, max_episode_steps=None, horizon_s=(steps + 10) / control_hz + 5, **kw)
    spent: dict[str, float] = {}

    def timed(obj: Any, method: str, name: str) -> None:
        inner = getattr(obj, method)

        def call(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            out = inner(*args, **kwargs)
            spent[name] = spent.get(name, 0.0) + time.perf_counter() - t0
            return out

        setattr(obj, method, call)

    try:
        wrapper: Any = env
        while not isinstance(wrapper, DeckPoseObservation):
            wrapper = wrapper.env
        timed(wrapper.env, "step", "env")
        for name, source in wrapper.estimator.sources.items():
            timed(source, "update", name)
        env.reset(seed=0, options={"altitude": 1.0, "offset": (0.0, 0.0), "yaw": 0.0})
        a = np.zeros(4, dtype=np.float32)
        for _ in range(10):
            env.step(a)
        spent.clear()
        t0 = time.perf_counter()
        for _ in range(steps):
            env.step(a)
        total = time.perf_counter() - t0
    finally:
        env.close()
    out = {name: 1e3 * t / steps for name, t in spent.items()}
    out["wrapper"] = 1e3 * total / steps - sum(out.values())
    out["total"] = 1e3 * total / steps
    return out


def component_costs(frames: int = 100, sensor_preset: str = "ideal") -> dict[str, float]:
    """Mean ms per control step of each component at the 1 m hover (512x512 camera, ``sensor_preset``):

    ``physics`` (``World.step``: 12 physics steps, deck drive, autopilot, Python), ``tof``, ``imu``,
    ``render`` (the full frame), ``detect`` (the tag in the full frame), ``window`` (rendering the
    tag's window + detecting there), ``projected`` (the projected camera model), and each estimator
    (``ihrcf``, ``atda``, ``fused``) on the full-frame corners, in that order: IHRCF's 3-D corners
    and ATDA's IPPE solutions are computed once per frame and shared (``SensorFrame.memo``), so the
    fused filter's figure is its own work on top of them, as in the wrapped env."""
    from ihrcf_env.config.make import make_config
    from ihrcf_env.core.estimators import ImuSample, SensorFrame
    from ihrcf_env.sim.sensors.base import TAG_CAMERA
    from ihrcf_env.sim.world import World
    from ihrcf_env.wrappers import estimator_from_calibration

    cfg = make_config(sensor_preset=sensor_preset, **_hover_kwargs(20))
    projected = make_config(sensor_preset=sensor_preset, camera_model="projected", **_hover_kwargs(20))
    rendered_window = make_config(sensor_preset=sensor_preset, camera_output="corners", **_hover_kwargs(20))
    worlds = [World(cfg.world), World(projected.world), World(rendered_window.world)]
    try:
        profile = cfg.task.deck.make_profile(np.random.default_rng(0))
        rngs = [np.random.default_rng(0) for _ in worlds]
        for w, r in zip(worlds, rngs, strict=True):
            w.reset(profile, frames / 20 + 5, altitude=1.0)
            w.reset_random(r)
        main, proj, win = worlds
        deck, obs = cfg.world.deck, cfg.observation
        assert obs.calibration is not None  # resolved by make_config (not raw)
        est = estimator_from_calibration(
            obs.calibration, deck.tag_size, deck.tag_id, fused_params=obs.fused_params
        )
        rng = rngs[0]
        spent: dict[str, list[float]] = {}

        def timed(name: str, fn: Callable[[], Any]) -> Any:
            t0 = time.perf_counter()
            out = fn()
            spent.setdefault(name, []).append(time.perf_counter() - t0)
            return out

        dt = 1.0 / 20
        state = main.sensing.body_state
        for _ in range(frames + 3):
            timed("physics", main.step)
            proj.step()
            win.step()
            tof = timed("tof", lambda: main.sensors["tof"].read(state(), dt, rng))
            imu = timed("imu", lambda: main.sensors["imu"].read(state(), dt, rng))
            main.deck.update_visuals()
            image = timed("render", lambda: main.sensors["camera"].read(state(), dt, rng))["image"]
            corners = timed("detect", lambda img=image: est.detector.detect(img))  # type: ignore[misc]
            timed("window", lambda: win.sensors[TAG_CAMERA].read(win.sensing.body_state(), dt, rngs[2]))
            timed("projected", lambda: proj.sensors[TAG_CAMERA].read(proj.sensing.body_state(), dt, rngs[1]))
            frame = SensorFrame(
                time=main.time,
                corners=corners,
                ranges=np.asarray(tof["ranges"], dtype=np.float64),
                ranges_valid=np.asarray(tof["ranges_valid"]).astype(bool),
                imu=ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"]),
            )
            for name, source in est.sources.items():
                timed(name, lambda s=source, f=frame: s.update(f))  # type: ignore[misc]
    finally:
        for w in worlds:
            w.close()
    return {name: 1e3 * float(np.mean(t[3:])) for name, t in spent.items() if not math.isnan(t[0])}


def raw_speed(size: int, steps: int, control_hz: int = 20) -> tuple[float, float]:
    """(env steps per second, real-time factor) of the raw env with zero velocity actions, camera
    ``size`` x ``size`` px rendered every control step (0: no camera)."""
    kw = {"camera": False} if size == 0 else {"camera_width": size, "camera_height": size}
    env = gym.make("ihrcf_env/DeckHoverRaw-v0", control_hz=control_hz, max_episode_steps=steps + 10, **kw)
    try:
        sps = steps_per_second(env, steps)
    finally:
        env.close()
    return sps, sps / control_hz


def estimation_ms(frames: int) -> float | None:
    """Mean wall time (ms) of one frame through detection + IHRCF + ATDA + fused (a separate
    estimator fed the same rendered 512x512 frames, ranges and IMU as the env's), or None without a
    shipped calibration."""
    from ihrcf_env.core.calibration import Calibration, default_calibration_path
    from ihrcf_env.core.estimators import ImuSample
    from ihrcf_env.wrappers import estimator_from_calibration

    if not default_calibration_path().is_file():
        return None
    env = gym.make("ihrcf_env/DeckHoverRaw-v0", max_episode_steps=frames + 10)
    try:
        deck = env.unwrapped.config.world.deck  # type: ignore[attr-defined]
        est = estimator_from_calibration(
            Calibration.load(default_calibration_path()), deck.tag_size, deck.tag_id
        )
        raw, info = env.reset(seed=0)
        samples = []
        for _ in range(frames):
            imu = raw["imu"]
            t0 = time.perf_counter()
            frame = est.frame(
                raw["image"],
                raw["ranges"],
                raw["ranges_valid"].astype(bool),
                time=float(info["time"]),
                imu=ImuSample(imu["quaternion"], imu["angular_velocity"], imu["linear_acceleration"]),
            )
            est.update(frame)
            samples.append(time.perf_counter() - t0)
            raw, _, _, _, info = env.step(np.zeros(4, dtype=np.float32))
    finally:
        env.close()
    return 1e3 * float(np.mean(samples))


__all__ = [
    "CAMERA_MODES",
    "WRAPPED",
    "Speed",
    "component_costs",
    "estimation_ms",
    "mode_speeds",
    "projected_step_costs",
    "raw_speed",
    "steps_per_second",
    "vector_scaling",
    "wrapped_speed",
]
