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
    env-steps/s."""

    kind: str
    num_envs: int
    dtype: str
    compile_s: float
    steps_per_s: float


def rollout_fn(fenv: Any, num_envs: int, steps: int) -> Callable[[Any, Any], Any]:
    """A jitted function ``(key, params) -> (total reward, episodes ended, observation checksum)``
    that resets ``num_envs`` envs and runs ``steps`` steps of all of them with random actions,
    resetting the envs that ended in the same step (only those:
    :func:`~ihrcf_env.vector.jax_batch.autoreset_step`, as the trainers step it). Every
    observation (the steps' and the resets') is summed into the checksum: a rollout whose
    observations were unused would let XLA drop everything only they depend on (the estimators),
    and time a step no trainer runs."""
    import jax
    import jax.numpy as jnp

    from ihrcf_env.vector.jax_batch import autoreset_step

    shape = fenv.action_space.shape

    def reset_one(key: Any, params: Any) -> Any:
        k1, k2 = jax.random.split(key)
        return fenv.reset_from(fenv.draw(k1, params), k2, params)

    def run(key: Any, params: Any) -> Any:
        k0, key = jax.random.split(key)
        obs, state = jax.vmap(reset_one, in_axes=(0, None))(jax.random.split(k0, num_envs), params)
        f = reward_dtype(params)

        def one(carry: Any, k: Any) -> Any:
            state, total, ended, check = carry
            ka, ks = jax.random.split(k)
            actions = jax.random.uniform(ka, (num_envs, *shape), minval=-1.0, maxval=1.0)
            obs, state, reward, done, _ = autoreset_step(
                lambda k, s, a: fenv.step(k, s, a, params),
                lambda k: reset_one(k, params),
                jax.random.split(ks, num_envs),
                state,
                actions,
            )
            return (
                state,
                total + reward.sum().astype(f),
                ended + done.sum().astype(jnp.int32),
                check + obs.astype(f).sum(),
            ), None

        zero = jnp.zeros((), f)
        init = (state, zero, jnp.zeros((), jnp.int32), obs.astype(f).sum())
        (state, total, ended, check), _ = jax.lax.scan(one, init, jax.random.split(key, steps))
        return total, ended, check

    return jax.jit(run)


def reward_dtype(params: Any) -> Any:
    import jax.numpy as jnp

    leaves = [x for x in _leaves(params) if hasattr(x, "dtype") and jnp.issubdtype(x.dtype, jnp.floating)]
    return leaves[0].dtype if leaves else jnp.float32


def _leaves(tree: Any) -> list[Any]:
    import jax

    return list(jax.tree_util.tree_leaves(tree))


def functional_rate(fenv: Any, num_envs: int, steps: int, dtype: str) -> SpeedRow:
    """Compile time and env-steps/s of :func:`rollout_fn` (the second call is timed)."""
    import jax

    with jax.enable_x64(dtype == "float64"):
        params = jax.tree_util.tree_map(lambda x: jax.numpy.asarray(x), fenv.params)
        fn = rollout_fn(fenv, num_envs, steps)
        key = jax.random.PRNGKey(0)
        t0 = time.perf_counter()
        jax.block_until_ready(fn(key, params))
        compile_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        jax.block_until_ready(fn(jax.random.PRNGKey(1), params))
        run_s = time.perf_counter() - t0
    # the first call also ran the steps: its compile time is what is left after the run
    return SpeedRow("functional", num_envs, dtype, max(0.0, compile_s - run_s), num_envs * steps / run_s)


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
    """XLA's estimate of (FLOPs, bytes accessed) of one step of one env."""
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
    """Markdown table of ``rows`` with the ratio to the PyBullet env's ``reference`` steps/s."""
    lines = [
        "| interface | N | dtype | compile (s) | env-steps/s | x single PyBullet env |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.kind} | {r.num_envs} | {r.dtype} | {r.compile_s:.1f} | {r.steps_per_s:,.0f} | "
            f"{r.steps_per_s / reference:.1f} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env-id", default="ihrcf_env/DeckLanding-v2")
    ap.add_argument("--level", default="moderate")
    ap.add_argument("--nums", type=int, nargs="+", default=list(DEFAULT_NUMS), help="numbers of envs")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run (per env)")
    ap.add_argument("--dtypes", nargs="+", default=["float64", "float32"], choices=["float64", "float32"])
    ap.add_argument("--no-front", action="store_true", help="skip the vector env front")
    ap.add_argument("--pybullet-steps", type=int, default=300)
    ap.add_argument("--markdown", default=None, help="write the table to this file")
    ap.add_argument(
        "--deck-forecast", action="store_true", help="with the forecast block (deck_forecast=True)"
    )
    args = ap.parse_args(argv)

    import jax

    import ihrcf_env  # noqa: F401  (registers the ids)
    from ihrcf_env.vector.jax_make import JAX_DEFAULTS, make_functional

    extra: dict[str, Any] = {"deck_forecast": True} if args.deck_forecast else {}
    options = {"level": args.level, **JAX_DEFAULTS, **extra}
    reference = pybullet_rate(args.env_id, options, args.pybullet_steps)
    print(f"single PyBullet env ({args.env_id}, {options}): {reference:,.0f} env-steps/s")
    rows: list[SpeedRow] = []
    costs: dict[str, tuple[float, float]] = {}
    for dtype in args.dtypes:
        fenv = make_functional(args.env_id, dtype=dtype, level=args.level, **extra)
        costs[dtype] = cost_per_env_step(fenv, dtype)
        for n in args.nums:
            row = functional_rate(fenv, n, args.steps, dtype)
            rows.append(row)
            print(
                f"functional N={n:5d} {dtype}: compile {row.compile_s:6.1f} s  "
                f"{row.steps_per_s:12,.0f} steps/s"
            )
        if not args.no_front:
            import gymnasium as gym

            def make(n: int, dt: str) -> Any:
                return gym.make_vec(
                    args.env_id,
                    num_envs=n,
                    vectorization_mode="vector_entry_point",
                    backend="jax",
                    dtype=dt,
                    level=args.level,
                    **extra,
                )

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
        f"- task: `{args.env_id}` level `{args.level}`{' with deck_forecast' if extra else ''}, "
        f"{args.steps} steps per timed run",
        f"- single PyBullet env: {reference:,.0f} env-steps/s",
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
