"""The native vector env against the single env, episode by episode:
``python -m ihrcf_env.experiments.vector_equivalence``.

Flies the scripted landing (:class:`~ihrcf_env.control.policies.ScriptedLanding`, one controller
per env) in one vector env of N envs reset with seed ``s`` (env ``i`` takes ``s + i``) until each
env's first episode has ended, then, seed by seed, in single envs made with the same options.
Compares per episode the outcome, the length and the observation at every step, and prints a
Markdown table: how many episodes agree, how many observation sequences are equal bit for bit,
and the largest absolute difference of an observation. Each sub-env runs its own estimators, as
the single env does, so the two are expected to agree bit for bit (in closed loop a difference in
the last place of an observation could change an action, after which the two runs would part).
"""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import ihrcf_env
from ihrcf_env._warnings import older_version_allowed
from ihrcf_env.config.levels import LEVELS, TEST_SEEDS
from ihrcf_env.control.policies import ScriptedLanding

#: Most episodes of one run (one vector env holds them all).
MAX_EPISODES = 1024


@dataclass(frozen=True)
class Episode:
    """One env's first episode: its observations (steps + 1, obs dim), outcome and length."""

    observations: NDArray[np.float32]
    outcome: str

    @property
    def steps(self) -> int:
        return len(self.observations) - 1


@dataclass(frozen=True)
class Comparison:
    """The single envs' episodes against the vector env's, seed by seed."""

    episodes: int
    same_outcome: int
    same_length: int
    bitwise: int
    within_1e6: int
    max_difference: float
    outcomes: dict[str, int]  # the vector env's


def _outcome(info: dict[str, Any], i: int) -> str:
    """The outcome of env ``i`` in a vector env's stacked ``info`` ("flying" when it has none)."""
    if "outcome" in info and bool(info["_outcome"][i]):
        return str(info["outcome"][i])
    return "flying"


def vector_episodes(env_id: str, n: int, seed: int, **options: Any) -> list[Episode]:
    """Each env's first episode in one vector env of ``n`` envs (``reset(seed=seed)``)."""
    with older_version_allowed():
        vec = gym.make_vec(env_id, num_envs=n, **options)
    try:
        policies = [ScriptedLanding.from_env(e) for e in vec.envs]  # type: ignore[attr-defined]
        for p in policies:
            p.reset()
        obs, _ = vec.reset(seed=seed)
        seen: list[list[NDArray[np.float32]]] = [[obs[i].copy()] for i in range(n)]
        outcomes = [""] * n
        active = np.ones(n, dtype=bool)
        zero = np.zeros(vec.single_action_space.shape or (), dtype=np.float32)
        while active.any():
            actions = np.stack([policies[i].act(obs[i]) if active[i] else zero for i in range(n)])
            obs, _, terminated, truncated, info = vec.step(actions)
            for i in np.flatnonzero(active):
                seen[i].append(obs[i].copy())
                if terminated[i] or truncated[i]:
                    outcomes[i] = _outcome(info, int(i))
                    active[i] = False
    finally:
        vec.close()
    return [Episode(np.stack(s), o) for s, o in zip(seen, outcomes, strict=True)]


def single_episode(env_id: str, seed: int, **options: Any) -> Episode:
    """The scripted landing's episode in ``gym.make(env_id, **options)`` reset with ``seed``."""
    with older_version_allowed():
        env = gym.make(env_id, **options)
    try:
        policy = ScriptedLanding.from_env(env)
        policy.reset()
        obs, _ = env.reset(seed=seed)
        seen = [np.asarray(obs).copy()]
        while True:
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            seen.append(np.asarray(obs).copy())
            if terminated or truncated:
                return Episode(np.stack(seen), str(info.get("outcome", "flying")))
    finally:
        env.close()


def compare(vector: Sequence[Episode], single: Sequence[Episode]) -> Comparison:
    """Seed-by-seed agreement of two lists of episodes (observations over their common steps)."""
    same_outcome = same_length = bitwise = within = 0
    largest = 0.0
    for a, b in zip(vector, single, strict=True):
        same_outcome += a.outcome == b.outcome
        same_length += a.steps == b.steps
        k = min(len(a.observations), len(b.observations))
        diff = float(np.max(np.abs(a.observations[:k].astype(np.float64) - b.observations[:k]), initial=0.0))
        exact = a.steps == b.steps and np.array_equal(a.observations, b.observations)
        bitwise += exact
        within += a.steps == b.steps and diff <= 1e-6
        largest = max(largest, diff)
    return Comparison(
        len(vector),
        same_outcome,
        same_length,
        bitwise,
        within,
        largest,
        dict(Counter(e.outcome for e in vector)),
    )


def markdown(rows: Sequence[tuple[str, Comparison]]) -> list[str]:
    """The table: one row per set of single envs compared."""
    lines = [
        "| single env made with | same outcome | same length | observations bit for bit | within 1e-6 "
        "| largest observation difference | vector env's outcomes |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, c in rows:
        counts = ", ".join(f"{k} {v}" for k, v in sorted(c.outcomes.items()))
        lines.append(
            f"| {label} | {c.same_outcome}/{c.episodes} | {c.same_length}/{c.episodes} | "
            f"{c.bitwise}/{c.episodes} | {c.within_1e6}/{c.episodes} | {c.max_difference:.3g} | {counts} |"
        )
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code (1 when an episode's outcome or length differs from its
    single env)."""
    ap = argparse.ArgumentParser(
        prog="python -m ihrcf_env.experiments.vector_equivalence", description=__doc__
    )
    ap.add_argument("--id", default=ihrcf_env.LANDING_V2_ID, choices=ihrcf_env.VECTOR_IDS, help="env id")
    ap.add_argument("--level", default="moderate", choices=sorted(LEVELS), help="DeckLanding-v2's level")
    ap.add_argument(
        "--episodes", type=int, default=100, help=f"episodes (envs of the vector env), 1..{MAX_EPISODES}"
    )
    ap.add_argument("--seed", type=int, default=TEST_SEEDS.start, help="seed of env 0 (env i: seed + i)")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    args = ap.parse_args(argv)
    if not 1 <= args.episodes <= MAX_EPISODES:
        ap.error(f"argument --episodes: 1..{MAX_EPISODES}, got {args.episodes}")
    if args.seed < 0:
        ap.error(f"argument --seed: >= 0, got {args.seed}")
    options: dict[str, Any] = {"camera_model": args.camera_model}
    if args.id == ihrcf_env.LANDING_V2_ID:
        options["level"] = args.level
    vector = vector_episodes(args.id, args.episodes, args.seed, **options)
    made = ", ".join(f"{k}={v}" for k, v in options.items())
    head = (
        f"{args.id} ({made}), scripted landing, seeds {args.seed}..{args.seed + args.episodes - 1}: "
        f"one vector env of {args.episodes} against single envs"
    )
    print(head, flush=True)
    single = [single_episode(args.id, args.seed + i, **options) for i in range(args.episodes)]
    c = compare(vector, single)
    print("\n".join(markdown([("the same options", c)])))
    bad = c.same_outcome < c.episodes or c.same_length < c.episodes
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "MAX_EPISODES",
    "Comparison",
    "Episode",
    "compare",
    "main",
    "markdown",
    "single_episode",
    "vector_episodes",
]
