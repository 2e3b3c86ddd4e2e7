"""The scripted landing's outcomes on both backends over the same seeds.

``python -m ihrcf_env.experiments.backend_outcomes --level moderate --episodes 200`` flies the
package's scripted landing (:class:`~ihrcf_env.control.policies.ScriptedLanding` on the fused
estimate) on ``ihrcf_env/DeckLanding-v2`` with the projected camera from seeds ``seed ..
seed + episodes - 1``: on the PyBullet env (one episode per seed, the reference) and on the JAX
backend (``gym.make_vec(..., backend="jax")``, env ``i`` reset with seed ``seed + i``: the same
start, deck motion and wind; the sensor noise differs). It prints each backend's success rate with
its 95 % Wilson interval, the outcome counts, and whether the intervals overlap. ``--cache DIR``
keeps the PyBullet episodes' outcomes (one JSON file per level, seed range and policy), so a run
that stopped resumes.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.control.policies import LANDING_CONFIGS, ScriptedLanding
from ihrcf_env.core.metrics import wilson_interval
from ihrcf_env.experiments.episode import run_episode

__all__ = ["BackendOutcomes", "jax_outcomes", "main", "pybullet_outcomes"]

ENV_ID = "ihrcf_env/DeckLanding-v2"
#: The camera both backends fly (the JAX backend has only this one).
CAMERA: dict[str, Any] = {"camera_model": "projected", "camera_output": "corners"}


@dataclass(frozen=True)
class BackendOutcomes:
    """The outcome of each seed's first episode on one backend."""

    backend: str
    outcomes: tuple[str, ...]

    @property
    def successes(self) -> int:
        return sum(o == "success" for o in self.outcomes)

    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.successes, len(self.outcomes))

    def line(self) -> str:
        lo, hi = self.interval()
        n = len(self.outcomes)
        counts = ", ".join(f"{k} x{v}" for k, v in sorted(Counter(self.outcomes).items()))
        return f"| {self.backend} | {self.successes}/{n} ({lo:.0%}-{hi:.0%}) | {counts} |"


def pybullet_outcomes(level: str, seeds: Sequence[int], cache: Path | None = None) -> BackendOutcomes:
    """The scripted landing's outcome per seed on the PyBullet env (cached per seed in ``cache``)."""
    done: dict[str, str] = {}
    path = None
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        path = cache / f"pybullet-{level}-{seeds[0]}-{seeds[-1]}.json"
        if path.exists():
            done = json.loads(path.read_text())
    env = gym.make(ENV_ID, level=level, **CAMERA)
    try:
        policy = ScriptedLanding.from_env(env)
        for s in seeds:
            if str(s) in done:
                continue
            done[str(s)] = run_episode(env, policy, s).outcome
            if path is not None:
                path.write_text(json.dumps(done))
    finally:
        env.close()
    return BackendOutcomes("pybullet", tuple(done[str(s)] for s in seeds))


def jax_outcomes(level: str, seeds: Sequence[int], dtype: str = "float64") -> BackendOutcomes:
    """The scripted landing's outcome of each seed's first episode on the JAX backend (one env per
    seed, all stepped together; an env's later episodes are not counted)."""
    n = len(seeds)
    if list(seeds) != list(range(seeds[0], seeds[0] + n)):
        raise ValueError("seeds: consecutive integers (env i is reset with seeds[0] + i)")
    env: Any = gym.make_vec(
        ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", backend="jax", dtype=dtype, level=level
    )
    try:
        config = env.config
        landing = LANDING_CONFIGS[config.task_name]
        policies = [
            ScriptedLanding(
                env.obs_slices,
                env.obs_scales,
                int(config.world.control_hz),
                tuple(float(v) for v in config.task.max_velocity),
                config.world.rig,
                landing,
            )
            for _ in range(n)
        ]
        obs, _ = env.reset(seed=int(seeds[0]))
        for p in policies:
            p.reset()
        result: list[str | None] = [None] * n
        for _ in range(env.max_episode_steps or 10**6):
            actions = np.stack([p.act(o) for p, o in zip(policies, obs, strict=True)])
            obs, _, term, trunc, info = env.step(actions)
            for i in np.flatnonzero(term | trunc):
                if result[i] is None:
                    result[i] = str(info["outcome"][i]) if term[i] else "timeout"
            if all(r is not None for r in result):
                break
        return BackendOutcomes("jax", tuple(r or "timeout" for r in result))
    finally:
        env.close()


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--level", nargs="+", default=["calm", "moderate", "rough"])
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--cache", default=None, help="folder keeping the PyBullet episodes' outcomes")
    ap.add_argument("--markdown", default=None, help="write the table to this file")
    args = ap.parse_args(argv)
    import ihrcf_env  # noqa: F401  (registers the ids)

    seeds = list(range(args.seed, args.seed + args.episodes))
    lines = ["| level | backend | success (95 % interval) | outcomes |", "|---|---|---|---|"]
    for level in args.level:
        t0 = time.perf_counter()
        jx = jax_outcomes(level, seeds)
        t1 = time.perf_counter()
        pb = pybullet_outcomes(level, seeds, Path(args.cache) if args.cache else None)
        t2 = time.perf_counter()
        (a, b), (c, d) = jx.interval(), pb.interval()
        agree = "overlap" if a <= d and c <= b else "DISJOINT"
        lines.append(f"| {level} " + pb.line())
        lines.append(f"| {level} " + jx.line())
        print(f"{level}: jax {t1 - t0:.0f} s, pybullet {t2 - t1:.0f} s; Wilson intervals {agree}")
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
