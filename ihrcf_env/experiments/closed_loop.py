"""Closed-loop comparison of two camera models: the same landings flown on each, estimator validity
by height above the deck.

The paired validation (:mod:`ihrcf_env.experiments.camera_validation`) puts the same states through
both camera models. In closed loop the controller acts on what each model gives, the trajectories
part, and the landings spend their time in different places; this experiment measures whether what
a controller *sees* still agrees. Each episode (one seed) of ``ihrcf_env/DeckLanding-v1`` is flown
by the scripted landing (:class:`~ihrcf_env.control.policies.ScriptedLanding`, on the fused
estimate, never ground truth) once per camera model; every step records the true height of the
camera above the deck (``info["deck_position_body"]``, m) and whether each estimator was valid
(``info[f"{name}_reason"] == ""``). Per height band and estimator it reports each model's valid
fraction over all steps in the band and the difference with a 90 % bootstrap interval whose samples
are the seeds (paired: a seed's two episodes start from the same state), since steps within an
episode are strongly correlated.

Because one seed gives both models the same start, deck motion and wind, the comparison is
paired; the figures are in the generated results and ``docs/camera-models.md``.

``python -m ihrcf_env.experiments.closed_loop [--episodes N] [--seed S] [--sensor-preset P]`` prints
the Markdown table.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.policies import ScriptedLanding

#: Height bands (m, camera above the deck), [low, high).
BANDS: tuple[tuple[float, float], ...] = (
    (0.0, 0.45),
    (0.45, 0.6),
    (0.6, 0.8),
    (0.8, 1.0),
    (1.0, 1.5),
    (1.5, 2.0),
    (2.0, 3.5),
)
ESTIMATORS: tuple[str, ...] = ("ihrcf", "atda", "fused")
BOOTSTRAP = 4000


@dataclass
class LoopRun:
    """The landings of one camera model: per seed the outcome and, per step, the height (m) and each
    estimator's validity."""

    camera_model: str
    outcomes: dict[int, str] = field(default_factory=dict)
    heights: dict[int, NDArray[np.float64]] = field(default_factory=dict)
    valid: dict[int, dict[str, NDArray[np.bool_]]] = field(default_factory=dict)

    def counts(
        self, seeds: Sequence[int], band: tuple[float, float], estimator: str
    ) -> tuple[NDArray, NDArray]:
        """Per seed: steps in ``band`` and steps in it with ``estimator`` valid, (len(seeds),) each."""
        lo, hi = band
        steps, ok = np.zeros(len(seeds)), np.zeros(len(seeds))
        for i, s in enumerate(seeds):
            inside = (self.heights[s] >= lo) & (self.heights[s] < hi)
            steps[i] = inside.sum()
            ok[i] = (inside & self.valid[s][estimator]).sum()
        return steps, ok


def fly(
    camera_model: str,
    seeds: Sequence[int],
    sensor_preset: str = "realistic",
    env_id: str = "ihrcf_env/DeckLanding-v1",
    **env_kwargs: Any,
) -> LoopRun:
    """Fly the scripted landing once per seed with ``camera_model`` (further ``gym.make`` arguments in
    ``env_kwargs``) and record every step."""
    run = LoopRun(camera_model)
    env = gym.make(env_id, camera_model=camera_model, sensor_preset=sensor_preset, **env_kwargs)
    try:
        policy = ScriptedLanding.from_env(env)
        for seed in seeds:
            obs, info = env.reset(seed=int(seed))
            policy.reset()
            heights: list[float] = []
            valid: dict[str, list[bool]] = {e: [] for e in ESTIMATORS}
            while True:
                obs, _, terminated, truncated, info = env.step(policy.act(obs))
                heights.append(-float(info["deck_position_body"][2]))
                for e in ESTIMATORS:
                    valid[e].append(info.get(f"{e}_reason", "missing") == "")
                if terminated or truncated:
                    break
            run.outcomes[seed] = str(info.get("outcome", "flying"))
            run.heights[seed] = np.array(heights)
            run.valid[seed] = {e: np.array(v, dtype=bool) for e, v in valid.items()}
    finally:
        env.close()
    return run


@dataclass(frozen=True)
class BandComparison:
    """One band and estimator: valid fractions (over all steps in the band) of runs ``a`` and ``b``,
    their step counts, and ``b - a`` with a 90 % paired bootstrap interval over seeds (NaN where a
    run has no step in the band)."""

    band: tuple[float, float]
    estimator: str
    steps_a: int
    steps_b: int
    valid_a: float
    valid_b: float
    difference: float
    interval: tuple[float, float]


def _fraction(ok: NDArray, steps: NDArray) -> float:
    total = float(steps.sum())
    return float(ok.sum()) / total if total > 0 else math.nan


def compare(
    a: LoopRun, b: LoopRun, bands: Sequence[tuple[float, float]] = BANDS, seed: int = 0
) -> list[BandComparison]:
    """:class:`BandComparison` of every band and estimator over the seeds both runs flew."""
    seeds = sorted(set(a.heights) & set(b.heights))
    if not seeds:
        raise ValueError("the two runs share no seed")
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(seeds), (BOOTSTRAP, len(seeds)))
    out = []
    for band in bands:
        for e in ESTIMATORS:
            na, va = a.counts(seeds, band, e)
            nb, vb = b.counts(seeds, band, e)
            fa, fb = _fraction(va, na), _fraction(vb, nb)
            with np.errstate(invalid="ignore", divide="ignore"):
                boot = vb[picks].sum(1) / nb[picks].sum(1) - va[picks].sum(1) / na[picks].sum(1)
            boot = boot[np.isfinite(boot)]
            lo, hi = (float(x) for x in np.percentile(boot, [5, 95])) if len(boot) else (math.nan, math.nan)
            out.append(BandComparison(band, e, int(na.sum()), int(nb.sum()), fa, fb, fb - fa, (lo, hi)))
    return out


def markdown(a: LoopRun, b: LoopRun, rows: Sequence[BandComparison]) -> str:
    """The comparison as a Markdown table (percent), preceded by the outcomes."""
    seeds = sorted(set(a.heights) & set(b.heights))

    def landed(r: LoopRun) -> str:
        return f"{sum(r.outcomes[s] == 'success' for s in seeds)}/{len(seeds)}"

    lines = [
        f"{len(seeds)} seeds; landed: {a.camera_model} {landed(a)}, {b.camera_model} {landed(b)}",
        "",
        f"| height (m) | estimator | {a.camera_model} valid % (steps) | {b.camera_model} valid % (steps) "
        "| difference (points) | 90 % interval |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.band[0]:g}-{r.band[1]:g} | {r.estimator} | {100 * r.valid_a:.1f} ({r.steps_a}) "
            f"| {100 * r.valid_b:.1f} ({r.steps_b}) | {100 * r.difference:+.1f} "
            f"| {100 * r.interval[0]:+.1f} to {100 * r.interval[1]:+.1f} |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m ihrcf_env.experiments.closed_loop",
        description="Scripted landings flown with each camera model: estimator validity by height.",
    )
    ap.add_argument("--episodes", type=int, default=40, help="seeds (default 40)")
    ap.add_argument("--seed", type=int, default=100, help="first seed (default 100)")
    ap.add_argument("--sensor-preset", default="realistic", choices=("ideal", "realistic"))
    ap.add_argument(
        "--models",
        nargs=2,
        default=["rendered", "projected"],
        choices=("rendered", "projected"),
        help="the two camera models (default: rendered projected)",
    )
    args = ap.parse_args(argv)
    if args.episodes < 1:
        ap.error("--episodes must be >= 1")
    seeds = list(range(args.seed, args.seed + args.episodes))
    a, b = (fly(m, seeds, args.sensor_preset) for m in args.models)
    print(markdown(a, b, compare(a, b)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

__all__ = [
    "BANDS",
    "BOOTSTRAP",
    "ESTIMATORS",
    "BandComparison",
    "LoopRun",
    "compare",
    "fly",
    "main",
    "markdown",
]
