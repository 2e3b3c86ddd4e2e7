"""Speed of the native vector env (``gym.make_vec(id, num_envs=N)``) against the single env.

Both are timed the same way: ``warmup`` steps not counted, then a fixed number of steps timed with
``time.perf_counter``, random (seeded) or zero actions. The single env is reset when an episode
ends and that reset counts as one step, as the vector env's next-step autoreset spends one ``step``
on it, so both loops run the same episodes. ``P`` processes (:func:`process_speed`) each make and
step their own vector env of N, pinned to their own core where the OS allows it, start together and
report the aggregate env steps per second over the span from the first start to the last end. The
figures depend on the machine and on what else runs on it; a machine whose speed drifts is better
measured in rounds (:class:`PairedSpeed`): each configuration timed right after the single env,
the ratio taken within the round, the median over the rounds reported.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import ihrcf_env
from ihrcf_env._warnings import older_version_allowed
from ihrcf_env.core.threads import one_blas_thread

#: Actions of the timed loops: ``"random"`` (seeded samples of the action space) or ``"zero"``.
ACTIONS = ("random", "zero")
#: How long a process waits for the others to be ready (s).
BARRIER_TIMEOUT_S = 600.0


@dataclass(frozen=True)
class VectorSpeed:
    """Env steps per second of ``processes`` vector envs of ``num_envs`` envs each, on ``cores``
    cores (each process pinned to one of them, or ``processes`` capped by the cores if unpinned)."""

    num_envs: int
    processes: int
    cores: int
    env_steps_per_s: float

    def ratio(self, single_steps_per_s: float) -> float:
        """Env steps per second per core over the single env's steps per second (one core)."""
        return self.env_steps_per_s / self.cores / single_steps_per_s


@dataclass(frozen=True)
class PairedSpeed:
    """One configuration timed in rounds, each round beside a timing of the single env:
    ``speed`` with the median env steps per second over the rounds, ``ratios`` each round's
    per-core ratio to that round's single env."""

    speed: VectorSpeed
    ratios: tuple[float, ...]

    @classmethod
    def of(cls, runs: Sequence[VectorSpeed], singles: Sequence[float]) -> PairedSpeed:
        """The rounds' ``runs`` of one configuration and the single env's steps/s of each round."""
        if not runs or len(runs) != len(singles):
            raise ValueError(f"one single-env figure per round: {len(runs)} runs, {len(singles)} figures")
        median = statistics.median(r.env_steps_per_s for r in runs)
        first = runs[0]
        speed = VectorSpeed(first.num_envs, first.processes, first.cores, median)
        return cls(speed, tuple(r.ratio(s) for r, s in zip(runs, singles, strict=True)))

    @property
    def ratio(self) -> float:
        """The median of the rounds' ratios."""
        return statistics.median(self.ratios)


def _check_actions(actions: str) -> str:
    if actions not in ACTIONS:
        raise ValueError(f"actions must be one of {ACTIONS}, got {actions!r}")
    return actions


def _actor(space: gym.Space[Any], actions: str, seed: int) -> Callable[[], Any]:
    """The action source of a timed loop: seeded samples of ``space`` or its zero."""
    space.seed(seed)
    if actions == "random":
        return space.sample
    zero = np.zeros_like(space.sample())
    return lambda: zero


def single_speed(
    env_id: str = ihrcf_env.LANDING_V1_ID,
    steps: int = 300,
    warmup: int = 5,
    actions: str = "random",
    seed: int = 0,
    **options: Any,
) -> float:
    """Steps per second of ``gym.make(env_id, **options)`` (module docstring: resets counted)."""
    _check_actions(actions)
    with older_version_allowed():  # v1 is timed on purpose
        env = gym.make(env_id, **options)
    try:
        act = _actor(env.action_space, actions, seed)
        env.reset(seed=seed)
        done = False

        def one() -> None:
            nonlocal done
            if done:
                env.reset()
                done = False
                return
            _, _, terminated, truncated, _ = env.step(act())
            done = bool(terminated or truncated)

        for _ in range(warmup):
            one()
        t0 = time.perf_counter()
        for _ in range(steps):
            one()
        return steps / (time.perf_counter() - t0)
    finally:
        env.close()


def _time_vector(
    env_id: str,
    num_envs: int,
    steps: int,
    warmup: int,
    actions: str,
    seed: int,
    options: dict[str, Any],
    ready: Callable[[], Any] | None = None,
) -> tuple[float, float]:
    """(start, end) (``time.perf_counter``, s) of ``steps`` timed steps of a fresh vector env;
    ``ready()`` is called after the warm-up, just before the timing."""
    with older_version_allowed():  # v1 is timed on purpose
        env = gym.make_vec(env_id, num_envs=num_envs, **options)
    try:
        act = _actor(env.action_space, actions, seed)
        env.reset(seed=seed)
        for _ in range(warmup):
            env.step(act())
        if ready is not None:
            ready()
        t0 = time.perf_counter()  # CLOCK_MONOTONIC on Linux: one clock for every process
        for _ in range(steps):
            env.step(act())
        return t0, time.perf_counter()
    finally:
        env.close()


def vector_speed(
    env_id: str = ihrcf_env.LANDING_V1_ID,
    num_envs: int = 8,
    steps: int = 20,
    warmup: int = 3,
    actions: str = "random",
    seed: int = 0,
    **options: Any,
) -> VectorSpeed:
    """Env steps per second (``num_envs`` per vector step) of one vector env in this process."""
    _check_actions(actions)
    t0, t1 = _time_vector(env_id, num_envs, steps, warmup, actions, seed, options)
    return VectorSpeed(num_envs, 1, 1, num_envs * steps / (t1 - t0))


def _worker(
    core: int | None,
    barrier: Any,
    args: tuple[str, int, int, int, str, int, dict[str, Any]],
    out: Any,
) -> None:
    """One process of :func:`process_speed`: pin, make, warm up, wait for the others, time."""
    if core is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {core})
    try:
        out.put(_time_vector(*args, ready=lambda: barrier.wait(timeout=BARRIER_TIMEOUT_S)))
    except BaseException:
        barrier.abort()  # the others stop waiting
        raise


def process_speed(
    env_id: str = ihrcf_env.LANDING_V1_ID,
    num_envs: int = 8,
    processes: int = 2,
    steps: int = 20,
    warmup: int = 3,
    actions: str = "random",
    seed: int = 0,
    cores: Sequence[int] | None = None,
    **options: Any,
) -> VectorSpeed:
    """Aggregate env steps per second of ``processes`` spawned processes each stepping its own
    vector env of ``num_envs`` (process ``k`` seeded ``seed + k * num_envs``, pinned to
    ``cores[k % len(cores)]``; ``cores`` None: not pinned)."""
    _check_actions(actions)
    if processes < 1:
        raise ValueError(f"processes must be >= 1, got {processes!r}")
    ctx = mp.get_context("spawn")  # no fork of a process that may hold physics clients
    barrier, out = ctx.Barrier(processes), ctx.Queue()
    procs = []
    for k in range(processes):
        core = None if not cores else cores[k % len(cores)]
        args = (env_id, num_envs, steps, warmup, actions, seed + k * num_envs, dict(options))
        procs.append(ctx.Process(target=_worker, args=(core, barrier, args, out), daemon=True))
    with one_blas_thread():
        for p in procs:
            p.start()
    spans: list[tuple[float, float]] = []
    try:
        while len(spans) < processes:
            try:
                spans.append(out.get(timeout=0.5))
            except queue.Empty:
                bad = [p.exitcode for p in procs if p.exitcode not in (0, None)]
                if bad:
                    raise RuntimeError(f"a benchmark process failed (exit code {bad[0]})") from None
    finally:
        for p in procs:
            if len(spans) < processes:  # failed or interrupted: do not wait for the others
                p.terminate()
            p.join(timeout=60)
    start, end = min(s for s, _ in spans), max(e for _, e in spans)
    n_cores = len(set(cores)) if cores else (os.cpu_count() or 1)
    used = min(processes, n_cores)
    return VectorSpeed(num_envs, processes, used, processes * num_envs * steps / (end - start))


def markdown_table(single_steps_per_s: float, rows: Sequence[VectorSpeed | PairedSpeed]) -> list[str]:
    """The table's lines: the single env first (N and processes "-"), then one row per run; a
    :class:`PairedSpeed` row shows the median of its rounds' ratios and their range."""
    lines = [
        "| N | processes | env-steps/s | per core | ratio to single (per core) | rounds' range |",
        "|---|---|---|---|---|---|",
        f"| single env | 1 | {single_steps_per_s:.1f} | {single_steps_per_s:.1f} | 1.00 | - |",
    ]
    for row in rows:
        r = row.speed if isinstance(row, PairedSpeed) else row
        ratio = row.ratio if isinstance(row, PairedSpeed) else r.ratio(single_steps_per_s)
        spread = (
            f"{min(row.ratios):.2f}-{max(row.ratios):.2f}"
            if isinstance(row, PairedSpeed) and len(row.ratios) > 1
            else "-"
        )
        lines.append(
            f"| {r.num_envs} | {r.processes} | {r.env_steps_per_s:.1f} | "
            f"{r.env_steps_per_s / r.cores:.1f} | {ratio:.2f} | {spread} |"
        )
    return lines


__all__ = [
    "ACTIONS",
    "BARRIER_TIMEOUT_S",
    "PairedSpeed",
    "VectorSpeed",
    "markdown_table",
    "process_speed",
    "single_speed",
    "vector_speed",
]
