"""Speed of the JAX backend: env-steps per second per core against the single PyBullet env.

``python -m ihrcf_env.experiments.jax_speed`` measures, in one run on one core (``taskset`` or
``XLA_FLAGS=--xla_cpu_multi_thread_eigen=false`` is the caller's choice; the run reports the
threads JAX may use):

* the single PyBullet env (``gym.make(id, **options)``, the reference) stepped with random
  actions: env-steps/s;
* the JAX backend's functional step (pure JAX, as a trainer runs it: ``lax.scan`` over steps of
  the envs vmapped in chunks of :data:`~ihrcf_env.vector.jax_batch.CHUNK`, the envs that ended
  reset in the same step, random actions drawn in JAX, every observation summed into the result
  so that none of its computation is compiled away) for each ``N``, in
  float64 and float32: compile time (s), env-steps/s and the ratio to the PyBullet env;
* the Gymnasium vector env front (``gym.make_vec(..., backend="jax")``, numpy in and out) for the
  same ``N``: env-steps/s;
* XLA's cost analysis of one step of one env (floating-point operations and bytes accessed), from
  which a paper estimate for one GPU is printed with its assumptions.

The table is markdown (``--markdown FILE`` writes it). Figures are of this machine and run.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["SpeedRow", "functional_rate", "main", "pybullet_rate", "rollout_fn"]

#: The N measured by default.
DEFAULT_NUMS = (1, 32, 256, 1024, 4096)
#: The paper GPU: peak float64 / float32 FLOP/s and memory bandwidth (B/s) of an NVIDIA A100.
GPU_PEAK = {"float64": 9.7e12, "float32": 19.5e12}
GPU_BANDWIDTH = 1.55e12
#: The fraction of the peak a branch-heavy, small-matrix step reaches on a GPU (an assumption).
GPU_EFFICIENCY = 0.05


@dataclass(frozen=True)
class SpeedRow:
    """One measurement: ``kind`` (``"functional"`` or ``"front"``), N, dtype, compile time (s),
    env-steps/s; for the functional rows measured in their own process, ``cores`` (the cores and
    devices the batch ran on), the compile time from a warm persistent cache (s) and the peak
    resident memory of the process (MB)."""

    kind: str
    num_envs: int
    dtype: str
    compile_s: float
    steps_per_s: float
    cores: int = 1
    warm_s: float = float("nan")
    peak_mb: float = float("nan")


def rollout_fn(
    fenv: Any, num_envs: int, steps: int, max_steps: int = 600, mesh: Any = None
) -> Callable[[Any], Any]:
    """A jitted function ``key -> (total reward, episodes ended, observation checksum)`` that resets
    ``num_envs`` envs and runs ``steps`` steps of all of them with random actions, through the
    trainer's batched step (:func:`~ihrcf_env.vector.jax_rollout.batch_step`: the envs that ended
    reset in the same step, the estimator stage once per env and step, episodes of at most
    ``max_steps`` steps, the batch over the devices of ``mesh``). The first reset is the scan's
    first step with every env forced to reset, so the step compiles once. Every observation (the
    steps' and the resets') is summed into the checksum: a rollout whose observations were unused
    would let XLA drop everything only they depend on (the estimators), and time a step no trainer
    runs."""
    import jax
    import jax.numpy as jnp

    from ihrcf_env.vector.jax_rollout import batch_step, placeholder_state

    shape = fenv.action_space.shape
    step = batch_step(fenv, max_steps, mesh=mesh)

    def run(key: Any) -> Any:
        f = reward_dtype(fenv.params)
        state = placeholder_state(fenv, num_envs)

        def one(carry: Any, xs: Any) -> Any:
            state, total, ended, check = carry
            k, first = xs
            ka, ks = jax.random.split(k)
            actions = jax.random.uniform(ka, (num_envs, *shape), minval=-1.0, maxval=1.0)
            force = jnp.broadcast_to(first, (num_envs,))
            obs, state, reward, done, _ = step(jax.random.split(ks, num_envs), state, actions, force)
            live = ~force
            return (
                state,
                total + jnp.where(live, reward, 0).sum().astype(f),
                ended + (done & live).sum().astype(jnp.int32),
                check + obs.astype(f).sum(),
            ), None

        zero = jnp.zeros((), f)
        firsts = jnp.arange(steps + 1) == 0
        init = (state, zero, jnp.zeros((), jnp.int32), zero)
        (_, total, ended, check), _ = jax.lax.scan(one, init, (jax.random.split(key, steps + 1), firsts))
        return total, ended, check

    return jax.jit(run)


def reward_dtype(params: Any) -> Any:
    import jax.numpy as jnp

    leaves = [x for x in _leaves(params) if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating)]
    return leaves[0].dtype if leaves else jnp.float32


def _leaves(tree: Any) -> list[Any]:
    import jax

    return list(jax.tree_util.tree_leaves(tree))


def functional_rate(
    fenv: Any, num_envs: int, steps: int, dtype: str, max_steps: int = 600, mesh: Any = None
) -> SpeedRow:
    """Compile time and env-steps/s of :func:`rollout_fn` (the second call is timed; every output
    is read back, so nothing it claims to time is left undone)."""
    import jax

    with jax.enable_x64(dtype == "float64"):
        fn = rollout_fn(fenv, num_envs, steps, max_steps, mesh)
        t0 = time.perf_counter()
        np.asarray(jax.device_get(fn(jax.random.PRNGKey(0))))
        first_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        np.asarray(jax.device_get(fn(jax.random.PRNGKey(1))))
        run_s = time.perf_counter() - t0
    # the first call also ran the steps: its compile time is what is left after the run
    cores = 1 if mesh is None else int(mesh.devices.size)
    return SpeedRow("functional", num_envs, dtype, max(0.0, first_s - run_s), num_envs * steps / run_s, cores)


def measure_in_process(
    env_id: str, level: str, num_envs: int, steps: int, dtype: str, cores: int, cache: str
) -> SpeedRow:
    """:func:`functional_rate` in a new Python process on ``cores`` cores (as many devices), with the
    persistent compilation cache in ``cache``, twice: cold (an empty cache) and warm (the first
    run's cache). The row holds the cold compile time, the warm one, the warm run's env-steps/s and
    the larger of the two processes' peak resident memory."""
    import json
    import subprocess
    import sys

    results = []
    for _ in range(2):
        cmd = [
            sys.executable, "-m", "ihrcf_env.experiments.jax_speed", "--one", str(num_envs), dtype,
            str(cores), "--env-id", env_id, "--level", level, "--steps", str(steps),
        ]  # fmt: skip
        env = {**os.environ, "IHRCF_JAX_CACHE": cache}
        out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
        if out.returncode != 0:
            raise RuntimeError(
                f"the measurement of N={num_envs} {dtype} on {cores} core(s) failed:\n{out.stderr[-2000:]}"
            )
        results.append(json.loads(out.stdout.strip().splitlines()[-1]))
    cold, warm = results
    return SpeedRow(
        "functional", num_envs, dtype, cold["compile_s"], warm["steps_per_s"], cores, warm["compile_s"],
        max(cold["peak_mb"], warm["peak_mb"]),
    )  # fmt: skip


def _one(args: argparse.Namespace) -> int:
    """The child of :func:`measure_in_process`: one configuration, a JSON line on stdout."""
    import json
    import resource

    n, dtype, cores = int(args.one[0]), args.one[1], int(args.one[2])
    allowed = sorted(os.sched_getaffinity(0))
    if cores > len(allowed):
        raise SystemExit(f"--one: {cores} cores asked, this process may use {len(allowed)}")
    os.sched_setaffinity(0, allowed[:cores])
    from ihrcf_env.vector.jax_devices import env_mesh, request_host_devices

    request_host_devices(cores)
    from ihrcf_env.fast.cache import enable_compilation_cache
    from ihrcf_env.vector.checks import time_limit
    from ihrcf_env.vector.jax_make import make_functional

    enable_compilation_cache()
    max_steps = time_limit(args.env_id, None) or 600
    fenv = make_functional(args.env_id, dtype=dtype, max_steps=max_steps, level=args.level)
    row = functional_rate(fenv, n, args.steps, dtype, max_steps, env_mesh(cores) if cores > 1 else None)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"compile_s": row.compile_s, "steps_per_s": row.steps_per_s, "peak_mb": peak_mb}))
    return 0


def front_rate(make: Callable[[int, str], Any], num_envs: int, steps: int, dtype: str) -> SpeedRow:
    """Compile time (the first reset and step) and env-steps/s of a vector env front made by
    ``make(num_envs, dtype)``, stepped with random actions."""
    env = make(num_envs, dtype)
    try:
        rng = np.random.default_rng(0)
        t0 = time.perf_counter()
        env.reset(seed=0)
        env.step(rng.uniform(-1, 1, env.action_space.shape))
        compile_s = time.perf_counter() - t0
        actions = rng.uniform(-1, 1, (steps, *env.action_space.shape))
        t0 = time.perf_counter()
        for a in actions:
            env.step(a)
        run_s = time.perf_counter() - t0
    finally:
        env.close()
    return SpeedRow("front", num_envs, dtype, compile_s, num_envs * steps / run_s)


def pybullet_rate(env_id: str, options: dict[str, Any], steps: int) -> float:
    """Env-steps/s of the single PyBullet env with random actions (resetting when an episode ends)."""
    import gymnasium as gym

    env = gym.make(env_id, **options)
    try:
        rng = np.random.default_rng(0)
        env.reset(seed=0)
        t0 = time.perf_counter()
        for _ in range(steps):
            _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
            if term or trunc:
                env.reset()
        return steps / (time.perf_counter() - t0)
    finally:
        env.close()


def cost_per_env_step(fenv: Any, dtype: str) -> tuple[float, float]:
    """XLA's estimate of (FLOPs, bytes accessed) of one step of one env with its observation."""
    import jax

    with jax.enable_x64(dtype == "float64"):
        params = jax.tree_util.tree_map(lambda x: jax.numpy.asarray(x), fenv.params)
        key = jax.random.PRNGKey(0)
        k1, k2 = jax.random.split(key)
        _, state = fenv.reset_from(fenv.draw(k1, params), k2, params)
        action = jax.numpy.zeros(fenv.action_space.shape)
        compiled = jax.jit(fenv.step).lower(key, state, action, params).compile()
        cost = compiled.cost_analysis()
    if isinstance(cost, list):
        cost = cost[0] if cost else {}
    cost = cost or {}
    return float(cost.get("flops", float("nan"))), float(cost.get("bytes accessed", float("nan")))


def gpu_estimate(flops: float, bytes_accessed: float, dtype: str) -> float:
    """Paper env-steps/s of one GPU (:data:`GPU_PEAK`, :data:`GPU_BANDWIDTH` at
    :data:`GPU_EFFICIENCY`), bounded by compute or memory traffic, whichever is slower."""
    compute = GPU_PEAK[dtype] * GPU_EFFICIENCY / flops
    memory = GPU_BANDWIDTH * GPU_EFFICIENCY / bytes_accessed
    return min(compute, memory)


def table(rows: Sequence[SpeedRow], reference: float) -> str:
    """Markdown table of ``rows`` with the ratio to the PyBullet env's ``reference`` steps/s, per
    core and in all."""
    lines = [
        "| interface | N | dtype | cores | compile cold (s) | compile warm (s) | peak memory (MB) | "
        "env-steps/s | x single PyBullet env | per core |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        warm = "" if np.isnan(r.warm_s) else f"{r.warm_s:.1f}"
        peak = "" if np.isnan(r.peak_mb) else f"{r.peak_mb:,.0f}"
        ratio = r.steps_per_s / reference
        lines.append(
            f"| {r.kind} | {r.num_envs} | {r.dtype} | {r.cores} | {r.compile_s:.1f} | {warm} | {peak} | "
            f"{r.steps_per_s:,.0f} | {ratio:.1f} | {ratio / r.cores:.1f} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env-id", default="ihrcf_env/DeckLanding-v2")
    ap.add_argument("--level", default="moderate")
    ap.add_argument("--nums", type=int, nargs="+", default=list(DEFAULT_NUMS), help="numbers of envs")
    ap.add_argument("--cores", type=int, nargs="+", default=None, help="cores (default: 1 and all usable)")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run (per env)")
    ap.add_argument("--dtypes", nargs="+", default=["float32", "float64"], choices=["float64", "float32"])
    ap.add_argument("--no-front", action="store_true", help="skip the vector env front")
    ap.add_argument("--pybullet-steps", type=int, default=300)
    ap.add_argument("--markdown", default=None, help="write the table to this file")
    ap.add_argument("--one", nargs=3, metavar=("N", "DTYPE", "CORES"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        return _one(args)
    import tempfile

    from ihrcf_env.vector.jax_devices import host_cores

    for name, values in (("--nums", args.nums), ("--cores", args.cores or [1])):
        if any(v < 1 for v in values):
            ap.error(f"{name} must be positive ints, got {values}")
    if args.steps < 1:
        ap.error(f"--steps must be a positive int, got {args.steps}")
    cores = args.cores or sorted({1, host_cores()})
    if max(cores) > host_cores():
        ap.error(f"--cores {max(cores)}: this process may use {host_cores()} core(s)")
    for c in cores:
        for n in args.nums:
            if n % c:
                ap.error(f"--nums {n} does not split over --cores {c}")

    import jax

    import ihrcf_env  # noqa: F401  (registers the ids)
    from ihrcf_env.vector.jax_make import JAX_DEFAULTS, make_functional

    options = {"level": args.level, **JAX_DEFAULTS}
    usable = os.sched_getaffinity(0)
    os.sched_setaffinity(0, sorted(usable)[:1])  # the reference on one core
    try:
        reference = pybullet_rate(args.env_id, options, args.pybullet_steps)
    finally:
        os.sched_setaffinity(0, usable)  # the measurements' processes may use every core again
    print(f"single PyBullet env ({args.env_id}, {options}): {reference:,.0f} env-steps/s", flush=True)
    rows: list[SpeedRow] = []
    costs: dict[str, tuple[float, float]] = {}
    for dtype in args.dtypes:
        for c in cores:
            for n in args.nums:
                with tempfile.TemporaryDirectory() as cache:
                    row = measure_in_process(args.env_id, args.level, n, args.steps, dtype, c, cache)
                rows.append(row)
                print(
                    f"functional N={n:5d} {dtype} {c} core(s): compile {row.compile_s:6.1f} s cold, "
                    f"{row.warm_s:5.1f} s warm, peak {row.peak_mb:6,.0f} MB, "
                    f"{row.steps_per_s:10,.0f} steps/s",
                    flush=True,
                )
        fenv = make_functional(args.env_id, dtype=dtype, level=args.level)
        costs[dtype] = cost_per_env_step(fenv, dtype)
        if not args.no_front:
            import gymnasium as gym

            def make(n: int, dt: str) -> Any:
                return gym.make_vec(
                    args.env_id, num_envs=n, vectorization_mode="vector_entry_point", backend="jax", dtype=dt,
                    level=args.level,
                )  # fmt: skip

            for n in args.nums:
                row = front_rate(make, n, max(10, args.steps // 4), dtype)
                rows.append(row)
                print(
                    f"front      N={n:5d} {dtype}: first step {row.compile_s:6.1f} s  "
                    f"{row.steps_per_s:12,.0f} steps/s"
                )
    text = [
        f"- machine: {platform.platform()}, {os.cpu_count()} CPUs, "
        f"JAX {jax.__version__} on {jax.devices()[0].platform}",
        f"- task: `{args.env_id}` level `{args.level}`, {args.steps} steps per timed run, every observation "
        "summed into the result",
        f"- single PyBullet env (one core): {reference:,.0f} env-steps/s",
        "",
        table(rows, reference),
        "",
    ]
    for dtype, (flops, nbytes) in costs.items():
        est = gpu_estimate(flops, nbytes, dtype)
        text.append(
            f"- {dtype}: XLA estimates {flops:,.0f} FLOPs and {nbytes:,.0f} bytes per env-step; "
            f"paper estimate for one A100 at {GPU_EFFICIENCY:.0%} of its peak: {est:,.0f} env-steps/s "
            "(an assumption, not measured)"
        )
    out = "\n".join(text)
    print(out)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(out + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
