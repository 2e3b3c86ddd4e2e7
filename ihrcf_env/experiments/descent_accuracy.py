"""Deck-pose accuracy through scripted descents, per altitude band: ``python -m
ihrcf_env.experiments.descent_accuracy``.

For each level, the scripted landing (:class:`~ihrcf_env.control.landing.ScriptedLanding` on
``ihrcf_env/DeckLanding-v2``, the ``projected`` camera by default) flies seeded episodes on the
level's moving deck and, for the **static floor**, the same seeds over a static deck
(``deck_profile="static"``: the same sensors, noise, faults and wind). On every new camera frame
in which the tag is detected, each estimate is compared with the true deck pose in the body frame
at the instant it stands for: the fused filter's output is the pose at the frame's arrival (the
observation's time), IHRCF's and ATDA's the pose at the frame's exposure. Reported per level,
altitude band (the drone's height above the deck origin, true) and estimator: the mean absolute
lateral error (body x-y, mm) and depth error (body z, mm) of the deck origin, the mean angle
(deg) between the estimated and true deck normals, all over the valid estimates, and the share
(%) of the frames with the tag in view on which the estimate is valid.

Besides the env's own estimators, variants of the fused filter (:data:`VARIANTS`: other
:class:`~ihrcf_env.core.estimators.FusedParams` of the env's fused filter) run in the shadow of
the env's one on the very same frames; the drone flies on the env's own estimates, so every
variant sees the same trajectory. The most frequent reasons of the fused filters' invalid
estimates with the tag in view below 2 m are counted as well. Seeds default to ``1000, 1001,
...`` (not the protocol's test seeds).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections import Counter, deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

import ihrcf_env
from ihrcf_env.core.estimators import FusedParams, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.fused import FusedEstimator
from ihrcf_env.experiments.policies import make_env_for

__all__ = [
    "BANDS",
    "LEVEL_NAMES",
    "VARIANTS",
    "BandStats",
    "DescentAccuracy",
    "descent_accuracy",
    "main",
    "markdown",
]

#: Altitude bands (m above the deck origin, lower bound inclusive).
BANDS: tuple[tuple[float, float], ...] = ((0.0, 0.45), (0.45, 1.0), (1.0, 2.0), (2.0, 4.0))
LEVEL_NAMES: tuple[str, ...] = ("calm", "moderate", "rough")
#: Shadow variants of the fused filter: name -> change of the env's fused parameters.
VARIANTS: dict[str, Callable[[FusedParams], FusedParams]] = {
    "fused+deck": lambda p: dataclasses.replace(p, deck_model="oscillator"),
}
_REASON_BAND = 2.0  # m: invalid reasons are counted below this height


@dataclass
class BandStats:
    """Sums over the frames with the tag in view of one (estimator, band)."""

    frames: int = 0
    valid: int = 0
    lateral: float = 0.0  # m, sum of |error|
    depth: float = 0.0  # m
    angle: float = 0.0  # rad

    def add(self, est: PoseEstimate, position: NDArray[np.float64], normal: NDArray[np.float64]) -> None:
        """One frame: ``est`` against the true body-frame deck ``position`` (m) and ``normal``."""
        self.frames += 1
        if not est.valid:
            return
        self.valid += 1
        e = np.asarray(est.position) - position
        self.lateral += math.hypot(float(e[0]), float(e[1]))
        self.depth += abs(float(e[2]))
        c = float(np.clip(np.asarray(est.rotation)[:, 2] @ normal, -1.0, 1.0))
        self.angle += math.acos(c)

    def summary(self) -> tuple[float, float, float, float]:
        """(lateral mm, depth mm, normal deg, valid %); NaN where there is nothing to average."""
        v = max(self.valid, 1)
        nan = self.valid == 0
        return (
            math.nan if nan else 1e3 * self.lateral / v,
            math.nan if nan else 1e3 * self.depth / v,
            math.nan if nan else math.degrees(self.angle / v),
            math.nan if self.frames == 0 else 100.0 * self.valid / self.frames,
        )


@dataclass
class DescentAccuracy:
    """The statistics of one level on one deck (moving or static): ``stats[estimator][band]``,
    the fused filters' invalid reasons below 2 m, episodes and their outcomes."""

    level: str
    static: bool
    stats: dict[str, list[BandStats]] = field(default_factory=dict)
    reasons: dict[str, Counter[str]] = field(default_factory=dict)
    outcomes: Counter[str] = field(default_factory=Counter)


def _band(height: float) -> int | None:
    for i, (lo, hi) in enumerate(BANDS):
        if lo <= height < hi:
            return i
    return None


def _shadow(fused: FusedEstimator, params: FusedParams) -> FusedEstimator:
    """A fused filter built like ``fused`` with ``params``."""
    return FusedEstimator(
        fused.touch_pixels, fused.rig, fused.tag_size, fused.K, fused.dist, fused.max_residual, params
    )


def _short_reason(reason: str) -> str:
    """A reason without its numbers (so that equal causes count together)."""
    out = "".join("#" if ch.isdigit() else ch for ch in reason.split(" (")[0])
    while "##" in out or "#.#" in out:
        out = out.replace("##", "#").replace("#.#", "#")
    return out[:80]


def descent_accuracy(
    level: str,
    seeds: Sequence[int],
    static: bool = False,
    camera_model: str = "projected",
    variants: Mapping[str, Callable[[FusedParams], FusedParams]] | None = None,
) -> DescentAccuracy:
    """The scripted landing's estimates on ``level`` over ``seeds`` (module docstring); ``static``:
    over a static deck (the floor); ``variants``: shadow fused filters (default :data:`VARIANTS`)."""
    variants = VARIANTS if variants is None else variants
    kwargs: dict[str, Any] = {"level": level, "camera_model": camera_model}
    if static:
        kwargs["deck_profile"] = "static"
    env, policy = make_env_for(ihrcf_env.LANDING_V2_ID, kwargs, "scripted")
    out = DescentAccuracy(level, static)
    try:
        stage = env.get_wrapper_attr("stage")
        fused = stage.sources.get("fused")
        shadows: dict[str, FusedEstimator] = {}
        if isinstance(fused, FusedEstimator):
            shadows = {name: _shadow(fused, change(fused.params)) for name, change in variants.items()}
        names = [*stage.sources, *shadows]
        # fused filters output the pose at the frame's arrival, the others at its exposure
        at_arrival = {n for n in names if n in shadows or isinstance(stage.sources.get(n), FusedEstimator)}
        out.stats = {n: [BandStats() for _ in BANDS] for n in names}
        out.reasons = {n: Counter() for n in names if n in at_arrival}
        for seed in seeds:
            obs, info = env.reset(seed=int(seed))
            policy.reset()
            for s in shadows.values():
                s.reset()
            truth: deque[tuple[float, NDArray[np.float64], NDArray[np.float64]]] = deque(maxlen=64)
            last: SensorFrame | None = stage.last_frame
            while True:
                obs, _, terminated, truncated, info = env.step(policy.act(obs))
                now = float(info["time"])
                pos = np.asarray(info["deck_position_body"], dtype=np.float64)
                normal = np.asarray(info["deck_rotation_body"], dtype=np.float64)[:, 2]
                truth.append((now, pos, normal))
                frame = stage.last_frame
                if frame is not None and frame is not last:
                    last = frame
                    estimates = dict(stage.last_estimates or {})
                    for name, s in shadows.items():
                        estimates[name] = s.update(frame)
                    for name in out.reasons:
                        src = shadows.get(name, stage.sources.get(name))
                        for what in getattr(src, "diagnostics", {}).get("reinitialised", ()):
                            out.reasons[name][f"[event] {what} re-initialised"] += 1
                    height = float(info["drone_position_world"][2] - info["deck_position_world"][2])
                    band = _band(height)
                    if frame.corners is not None and band is not None:
                        exposure = float(frame.time)
                        for name, est in estimates.items():
                            at = now if name in at_arrival else exposure
                            _, p_true, n_true = min(truth, key=lambda x: abs(x[0] - at))
                            out.stats[name][band].add(est, p_true, n_true)
                            if name in out.reasons and not est.valid and height < _REASON_BAND:
                                out.reasons[name][_short_reason(est.reason)] += 1
                if terminated or truncated:
                    break
            out.outcomes[str(info.get("outcome", "timeout"))] += 1
    finally:
        env.close()
    return out


def _fmt(x: float, digits: int = 1) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def markdown(results: Sequence[tuple[DescentAccuracy, DescentAccuracy]], seeds: Sequence[int]) -> list[str]:
    """The tables of (moving, static) results per level."""
    lines = [
        f"Seeds {list(seeds)}; scripted landing, per camera frame with the tag in view; moving deck "
        "/ static deck (the floor). MAE over the valid estimates: lateral and depth of the deck "
        "origin (mm), angle of the deck normal (deg); valid: share of the frames with the tag in "
        "view (%).",
        "",
        "| level | band (m) | estimator | lateral (mm) | depth (mm) | normal (deg) | valid (%) | frames |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for moving, static in results:
        for b, (lo, hi) in enumerate(BANDS):
            for name in moving.stats:
                m = moving.stats[name][b].summary()
                s = static.stats[name][b].summary() if name in static.stats else (math.nan,) * 4
                cells = " | ".join(
                    f"{_fmt(a, d)} / {_fmt(c, d)}" for a, c, d in zip(m, s, (1, 1, 2, 0), strict=True)
                )
                n = moving.stats[name][b].frames
                ns = static.stats[name][b].frames if name in static.stats else 0
                lines.append(f"| {moving.level} | {lo:g}-{hi:g} | {name} | {cells} | {n} / {ns} |")
    lines += [
        "",
        "Invalid fused estimates with the tag in view below 2 m (moving deck) and the most frequent "
        "reasons ([event]: the filter's restarts, counted per frame):",
        "",
    ]
    lines += ["| level | estimator | invalid | reasons |", "|---|---|---|---|"]
    for moving, _ in results:
        for name, counter in moving.reasons.items():
            top = "; ".join(f"{r} ({k})" for r, k in counter.most_common(4))
            invalid = sum(k for r, k in counter.items() if not r.startswith("[event]"))
            lines.append(f"| {moving.level} | {name} | {invalid} | {top or '-'} |")
    lines += ["", "Outcomes (moving / static): " + "; ".join(
        f"{m.level}: {dict(m.outcomes)} / {dict(s.outcomes)}" for m, s in results
    )]  # fmt: skip
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    ap = argparse.ArgumentParser(prog="python -m ihrcf_env.experiments.descent_accuracy", description=__doc__)
    ap.add_argument("--levels", nargs="+", default=list(LEVEL_NAMES), choices=LEVEL_NAMES)
    ap.add_argument("--seeds", type=int, default=8, help="seeds per level (1..100)")
    ap.add_argument("--first-seed", type=int, default=1000, help="first seed (default 1000)")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    ap.add_argument("--markdown", default=None, help="also write the tables to this file")
    args = ap.parse_args(argv)
    if not 1 <= args.seeds <= 100:
        ap.error(f"argument --seeds: 1..100, got {args.seeds}")
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    results = []
    for level in args.levels:
        pair = (
            descent_accuracy(level, seeds, False, args.camera_model),
            descent_accuracy(level, seeds, True, args.camera_model),
        )
        results.append(pair)
        print(f"{level}: done", flush=True)
    lines = markdown(results, seeds)
    print("\n".join(lines), flush=True)
    if args.markdown:
        with open(args.markdown, "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
