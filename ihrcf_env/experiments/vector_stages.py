"""Where a step of the native vector env goes: ``python -m ihrcf_env.experiments.vector_stages``.

Times ``gym.make_vec(id, num_envs=N)`` (random seeded actions, as the vector benchmark) with a
timer around each function that makes up a stage of its step (installed for the run and removed
after it). A stage's time is its own: the time of the timed functions it calls is counted in
their stages. Each stage is of one kind:

* ``arrays``: numpy over all the envs at once (one call per vector step or physics tick), whose
  cost per env falls as N grows;
* ``per env``: Python run once per env, world or frame (its cost per env does not fall with N);
* ``mixed``: both in one function (e.g. the tick loop of the numpy physics with its per-world
  reads).

Per N it prints a Markdown table of the stages (ms per vector step, microseconds per env-step,
share), the single env's microseconds per step (its default PyBullet physics, as the vector benchmark)
and the vector env's ratio to it per core, and two
upper bounds on that ratio with this code: if every ``per env`` and ``mixed`` stage cost nothing
(the array work alone), and if every ``arrays`` and ``mixed`` stage cost nothing (the per-env work
alone). The timers add about a microsecond per timed call; the figures depend on the machine.
"""

from __future__ import annotations

import argparse
import functools
import time
from collections import defaultdict
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
from threadpoolctl import threadpool_limits

import ihrcf_env
from ihrcf_env._warnings import older_version_allowed
from ihrcf_env.core.estimators.pipeline import DeckPoseEstimator
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.envs.landing_v1 import DeckLandingV1Env
from ihrcf_env.experiments.vector_speed import single_speed
from ihrcf_env.sim.batched import loop
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor
from ihrcf_env.sim.batched.external import ExternalInputs
from ihrcf_env.sim.batched.ranging import BatchedToF
from ihrcf_env.sim.batched.tag_camera import BatchedTagCamera
from ihrcf_env.vector import env as vector
from ihrcf_env.vector.env import DeckLandingVectorEnv
from ihrcf_env.wrappers.estimator_stage import EstimatorStage
from ihrcf_env.wrappers.landing_obs import LandingObservation

ARRAYS, PER_ENV, MIXED = "arrays", "per env", "mixed"
KINDS = (ARRAYS, PER_ENV, MIXED)
#: Largest N of a run.
MAX_ENVS = 1024


@dataclass(frozen=True)
class Stage:
    """One stage: its label, kind (:data:`KINDS`) and the functions timed for it, as
    (module or class, attribute name)."""

    label: str
    kind: str
    targets: tuple[tuple[ModuleType | type, str], ...]


#: The stages of a vector step, in the order printed (the last one: the vector env's own code).
STAGES: tuple[Stage, ...] = (
    Stage("physics: autopilot", ARRAYS, ((BatchedVelocityController, "compute"),)),
    Stage("physics: rigid bodies", ARRAYS, ((BatchedQuadrotor, "step"),)),
    Stage("physics: tick loop, world states gathered", MIXED, ((vector, "advance"),)),
    Stage("physics: navigation and wind set-up", MIXED, ((ExternalInputs, "__init__"),)),
    Stage("physics: deck poses", PER_ENV, ((loop, "_deck_poses"),)),
    Stage(
        "physics: states written back, autopilots",
        PER_ENV,
        ((loop, "_write_back"), (loop, "_gather_autopilots"), (loop, "_scatter_autopilots")),
    ),
    Stage("sensors: camera cast, batched", ARRAYS, ((BatchedTagCamera, "read"),)),
    Stage("sensors: camera cast, per world", PER_ENV, ((loop, "_prefetch_camera"),)),
    Stage("sensors: ToF cast, batched", ARRAYS, ((BatchedToF, "cone_returns"), (BatchedToF, "true_ranges"))),
    Stage("sensors: ToF cast, per world", PER_ENV, ((loop, "_prefetch_ranges"), (loop, "prefetch"))),
    Stage("task: actions applied", PER_ENV, ((DeckLandingEnv, "begin_step"),)),
    Stage(
        "task: each env's step (sensor reads, reward, info)",
        PER_ENV,
        ((DeckLandingEnv, "end_step"), (DeckLandingV1Env, "end_step"), (LandingObservation, "take_step")),
    ),
    Stage("task: each env's reset", PER_ENV, ((LandingObservation, "reset_raw"),)),
    Stage("estimators: each env's frame", PER_ENV, ((EstimatorStage, "prepare"),)),
    Stage("estimators: each env's (IHRCF, ATDA, fused filter)", PER_ENV, ((DeckPoseEstimator, "update"),)),
    Stage("observation: each env's", PER_ENV, ((LandingObservation, "complete"),)),
    Stage(
        "observation: each env's step and reset (the rest)",
        PER_ENV,
        ((LandingObservation, "observe_step"), (LandingObservation, "reset")),
    ),
    Stage("info: stacked", PER_ENV, ((vector, "stack_infos"),)),
    Stage("vector env: rows, autoreset", PER_ENV, ((DeckLandingVectorEnv, "step"),)),
)


class _Clock:
    """Own time per stage label: a timed call's time minus that of the timed calls inside it."""

    def __init__(self) -> None:
        self.own: dict[str, float] = defaultdict(float)
        self._inner: list[float] = []

    def wrap(self, label: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            self._inner.append(0.0)
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.perf_counter() - t0
                self.own[label] += dt - self._inner.pop()
                if self._inner:
                    self._inner[-1] += dt

        return timed


@contextmanager
def stage_timers(stages: Sequence[Stage] = STAGES) -> Iterator[_Clock]:
    """The timers of ``stages`` installed (each target replaced by a timed wrapper) while inside;
    the originals restored on exit. A target that does not exist raises AttributeError naming it."""
    clock = _Clock()
    saved: list[tuple[ModuleType | type, str, Any]] = []
    try:
        for stage in stages:
            for owner, name in stage.targets:
                if name not in vars(owner):
                    raise AttributeError(f"stage {stage.label!r}: {owner.__name__}.{name} does not exist")
                original = vars(owner)[name]
                saved.append((owner, name, original))
                setattr(owner, name, clock.wrap(stage.label, original))
        yield clock
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


@dataclass(frozen=True)
class Breakdown:
    """One run: N, the vector step's wall time (s per vector step) and each stage's own time (s
    per vector step), with the single env's time per step (s)."""

    num_envs: int
    step_s: float
    stages: dict[str, float]
    single_s: float

    def kind_s(self, kind: str) -> float:
        """Time (s per vector step) of the stages of ``kind``."""
        return sum(self.stages.get(s.label, 0.0) for s in STAGES if s.kind == kind)

    @property
    def ratio(self) -> float:
        """The vector env's env-steps per second over the single env's (one core each)."""
        return self.single_s * self.num_envs / self.step_s

    def bound(self, kind: str) -> float:
        """The ratio if only the stages of ``kind`` took time (inf when they take none)."""
        t = self.kind_s(kind)
        return self.single_s * self.num_envs / t if t > 0 else float("inf")


def breakdown(
    env_id: str, num_envs: int, steps: int, warmup: int, single_steps: int, seed: int = 0, **options: Any
) -> Breakdown:
    """Time ``steps`` vector steps (after ``warmup``) of ``gym.make_vec(env_id, num_envs, **options)``
    with the stage timers, and ``single_steps`` steps of the single env with the same options but
    its default physics (PyBullet's, the vector benchmark's reference)."""
    single_options = {k: v for k, v in options.items() if k != "physics"}
    with older_version_allowed():
        single = single_speed(env_id, steps=single_steps, seed=seed, **single_options)
        env = gym.make_vec(env_id, num_envs=num_envs, **options)
    try:
        env.action_space.seed(seed)
        env.reset(seed=seed)
        for _ in range(warmup):
            env.step(env.action_space.sample())
        actions = [env.action_space.sample() for _ in range(steps)]
        with stage_timers() as clock:
            t0 = time.perf_counter()
            for a in actions:
                env.step(a)
            wall = time.perf_counter() - t0
    finally:
        env.close()
    own = {label: t / steps for label, t in clock.own.items()}
    return Breakdown(num_envs, wall / steps, own, 1.0 / single)


def markdown(b: Breakdown) -> list[str]:
    """The lines of one run's table and its summary."""
    n = b.num_envs
    lines = [
        f"N = {n}: {b.step_s * 1e3:.1f} ms per vector step, {b.step_s / n * 1e6:.0f} us per env-step; "
        f"single env {b.single_s * 1e6:.0f} us per step; ratio {b.ratio:.2f}",
        "",
        "| stage | kind | ms per vector step | us per env-step | share |",
        "|---|---|---|---|---|",
    ]
    for s in STAGES:
        t = b.stages.get(s.label, 0.0)
        if t > 0:
            lines.append(f"| {s.label} | {s.kind} | {t * 1e3:.2f} | {t / n * 1e6:.1f} | {t / b.step_s:.0%} |")
    timed = sum(b.stages.values())
    lines.append(f"| untimed (the benchmark loop) | - | {(b.step_s - timed) * 1e3:.2f} | - | - |")
    lines += [
        "",
        "| kind | ms per vector step | ratio if only this kind took time |",
        "|---|---|---|",
    ]
    for kind in KINDS:
        lines.append(f"| {kind} | {b.kind_s(kind) * 1e3:.2f} | {b.bound(kind):.2f} |")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    ap = argparse.ArgumentParser(prog="python -m ihrcf_env.experiments.vector_stages", description=__doc__)
    ap.add_argument("--id", default=ihrcf_env.LANDING_V1_ID, choices=ihrcf_env.VECTOR_IDS, help="env id")
    ap.add_argument(
        "--num-envs", type=int, nargs="+", default=[32, 128], help=f"N of each run, 1..{MAX_ENVS}"
    )
    ap.add_argument("--steps", type=int, default=40, help="timed vector steps per run")
    ap.add_argument("--warmup", type=int, default=5, help="untimed vector steps first")
    ap.add_argument("--single-steps", type=int, default=300, help="timed steps of the single env")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    ap.add_argument("--physics", default="numpy", choices=("numpy", "pybullet"))
    ap.add_argument("--markdown", default=None, help="also write the tables to this file")
    args = ap.parse_args(argv)
    for n in args.num_envs:
        if not 1 <= n <= MAX_ENVS:
            ap.error(f"argument --num-envs: 1..{MAX_ENVS}, got {n}")
    for name in ("steps", "single_steps"):
        if getattr(args, name) < 1:
            ap.error(f"argument --{name.replace('_', '-')}: >= 1, got {getattr(args, name)}")
    if args.warmup < 0:
        ap.error(f"argument --warmup: >= 0, got {args.warmup}")
    options = {"camera_model": args.camera_model, "physics": args.physics}
    out = [
        f"{args.id} ({', '.join(f'{k}={v}' for k, v in options.items())}), random actions, "
        f"{args.steps} vector steps timed per N (numpy {np.__version__})",
        "",
    ]
    print(out[0], flush=True)
    for n in args.num_envs:
        with threadpool_limits(limits=1):  # as the vector benchmark: one BLAS thread, both sides
            b = breakdown(args.id, n, args.steps, args.warmup, args.single_steps, **options)
        lines = [*markdown(b), ""]
        print("\n".join(lines), flush=True)
        out += lines
    if args.markdown:
        with open(args.markdown, "w", encoding="utf-8") as f:
            f.write("\n".join(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "KINDS",
    "MAX_ENVS",
    "STAGES",
    "Breakdown",
    "Stage",
    "breakdown",
    "main",
    "markdown",
    "stage_timers",
]
