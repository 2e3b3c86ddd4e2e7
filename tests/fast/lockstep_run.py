"""The lockstep run shared by the lockstep tests: one episode of the PyBullet env (v2, projected
camera) and of the JAX step on the same episode draws and per-step noise, under a scripted action
sequence, float64."""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ihrcf_env import tasks
from ihrcf_env.config.make import make_config
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.envs.landing_v1 import DeckLandingV2Env
from ihrcf_env.fast.episode import host_episode, host_streams
from ihrcf_env.fast.imu import READ_DRAWS, read_draws
from ihrcf_env.fast.params import StepParams, make_params
from ihrcf_env.fast.state import ReadDraws, StepDraws
from ihrcf_env.fast.step import reset_from_with, step_with

#: Most control steps run (20 Hz); the episode ends at its touchdown.
STEPS = 300
#: The scripted descent speeds up after this step (20 Hz: 5 s of slow flight first).
SLOW_STEPS = 100


def action(k: int) -> np.ndarray:
    """The scripted action of step ``k``: a slow descent with lateral and yaw commands for
    :data:`SLOW_STEPS` steps, then down onto the deck, holding over its centre."""
    if k <= SLOW_STEPS:
        return np.array(
            [0.3 * math.sin(0.2 * k), 0.25 * math.cos(0.13 * k), -0.12, 0.15 * math.sin(0.05 * k)]
        )
    return np.array([0.0, 0.0, -0.6, 0.0])


@cache
def params(level: str) -> StepParams:
    cfg = make_config(
        task="landing-v2", level=level, camera_model="projected", camera_output="corners", raw=True
    )
    return make_params(cfg)


@cache
def _compiled() -> tuple[Any, Any]:
    return jax.jit(reset_from_with, static_argnums=2), jax.jit(step_with, static_argnums=3)


def _reads(p: StepParams, gens: dict[str, np.random.Generator], samples: int) -> ReadDraws:
    """One reading's draws from the env's generators, in its order (``samples`` ToF samples)."""
    m = p.tof.samples
    z, u = np.zeros((m, 4)), np.zeros((m, 4))
    for i in range(samples):
        z[i] = gens["tof"].standard_normal(4)
        u[i] = gens["tof"].random(4)
    imu = read_draws(p.imu, gens["imu"]) if p.imu is not None else np.zeros(READ_DRAWS)
    n = gens["camera"].standard_normal((4, 2))
    cu = gens["camera"].random()
    du = gens["dropout"].random() if p.camera is not None and p.camera.dropout is not None else 0.0
    return ReadDraws(z, u, imu, n, np.float64(cu), np.float64(du))


def _tof_samples(p: StepParams, tick0: int, tick1: int) -> int:
    tps = p.tof.ticks_per_sample
    if tps is None:
        return 1
    return math.floor((tick1 + 1e-6) / tps) - math.floor((tick0 + 1e-6) / tps)


def run(level: str, seed: int, steps: int = STEPS) -> dict[str, np.ndarray]:
    """Both backends over one episode: per control step while both fly, the reference's and the
    JAX step's (pairs on axis 1) drone and deck poses, ranges and flags, tag status and corners,
    navigation velocity, camera age and rewards; then each backend's touchdown time (s) and
    success (``"ref_end"``, ``"jax_end"``; the JAX run goes on for up to two steps after the
    reference's touchdown)."""
    p = params(level)
    env = DeckLandingV2Env(p.config)
    reset_j, step_j = _compiled()
    out: dict[str, list[Any]] = {}

    def put(key: str, ref: Any, got: Any) -> None:
        out.setdefault(key, []).append((np.asarray(ref, np.float64), np.asarray(got, np.float64)))

    try:
        obs, info = env.reset(seed=seed)
        streams = SeedStreams.from_generator(np.random.default_rng(np.random.SeedSequence(seed)))
        ep = host_episode(p, streams)
        gens = host_streams(p, streams)
        if p.nav is not None:
            gens["navigation"].standard_normal((3, 3))  # the errors' start (in the episode)
        _, st = reset_j(ep, _reads(p, gens, 1), p)
        S = p.substeps
        jax_end: tuple[float, int] | None = None  # (touchdown time s, outcome code) once it ended

        def jax_step(k: int) -> Any:
            nonlocal st, jax_end
            tick0 = int(st.tick)
            nav = gens["navigation"].standard_normal((S, 6)) if p.nav is not None else np.zeros((S, 6))
            draws = StepDraws(nav, _reads(p, gens, _tof_samples(p, tick0, tick0 + S)))
            _, st, r_j, done, inf = step_j(draws, st, jnp.asarray(action(k)), p)
            if bool(done):
                code = int(st.flight.code)
                td = (tick0 + int(st.flight.tick)) * p.dt if code else np.nan
                jax_end = (td, int(inf.outcome))
            return r_j, inf

        k = 0
        for k in range(1, steps + 1):
            obs, reward, term, _, info = env.step(action(k))
            if jax_end is not None:  # the JAX episode ended first (its touchdown a tick earlier)
                if term:
                    break
                continue
            r_j, inf = jax_step(k)
            if term or jax_end is not None:
                if term:
                    break
                continue
            raw, truth = inf.raw, inf.truth
            put("reward", reward, r_j)
            put("drone_position", info["drone_position_world"], truth.drone_position_world)
            put("drone_quaternion", info["drone_quaternion_world"], truth.drone_quaternion_world)
            put("deck_position", info["deck_position_world"], truth.deck_position_world)
            put("deck_quaternion", info["deck_quaternion_world"], truth.deck_quaternion_world)
            put("ranges", obs["ranges"], raw.ranges)
            put("ranges_valid", obs["ranges_valid"], raw.ranges_valid)
            put("tag_status", obs["tag_status"], raw.tag_status)
            put("tag_corners", obs["tag_corners"], raw.tag_corners)
            put("nav_velocity", obs["nav_velocity"], raw.nav_velocity)
            put("imu_quaternion", obs["imu"]["quaternion"], raw.imu_quaternion)
            put("camera_age", obs["camera_age"][0], raw.camera_age)
        # the JAX step until its own touchdown (a contact may fall one physics tick later)
        for k2 in range(k + 1, k + 3):
            if jax_end is not None:
                break
            jax_step(k2)
        ref_td = info["touchdown"]["time"] if "touchdown" in info else np.nan
        out["ref_end"] = [(ref_td, 1.0 if info["outcome"] == "success" else 0.0)]
        end = jax_end if jax_end is not None else (np.nan, -1)
        out["jax_end"] = [(end[0], 1.0 if end[1] == tasks.SUCCESS else 0.0)]
    finally:
        env.close()
    return {k: np.array(v) for k, v in out.items()}


def angle_between(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) between unit quaternions (..., 4) (x, y, z, w), accurate for small
    angles."""
    d = np.minimum(np.linalg.norm(q1 - q2, axis=-1), np.linalg.norm(q1 + q2, axis=-1))
    return 4.0 * np.arcsin(np.minimum(d / 2.0, 1.0))
