"""The autopilot's wind envelope: how far a steady or gusty wind pushes the drone off a held position.

The drone hovers above a static deck with a zero velocity command (position hold) while a
:class:`~ihrcf_env.sim.disturbances.Wind` of a fixed mean speed blows on it; the autopilot flies on
the state given by ``WorldConfig.navigation`` (the truth by default). After ``settle_s`` seconds
the largest horizontal distance from the starting point is recorded. :func:`envelope` repeats this
over mean wind speeds and directions and reports the strongest wind held within each tolerance.

Run as ``python -m ihrcf_env.experiments.wind_envelope`` to print the table.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ihrcf_env.config.vehicle import VelocityGains
from ihrcf_env.config.wind import WindParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.world import World


@dataclass(frozen=True)
class HoldResult:
    """Position hold in one wind: offsets are horizontal distances (m) from the start position."""

    mean_speed: float  # m/s
    turbulence: float
    max_offset: float  # m, largest after settling, over all runs
    mean_offset: float  # m, time-average after settling, over all runs
    max_tilt: float  # rad, largest tilt after settling


def hold_in_wind(
    mean_speed: float,
    turbulence: float = 0.0,
    seeds: Sequence[int] = (0,),
    settle_s: float = 10.0,
    measure_s: float = 10.0,
    altitude: float = 2.0,
    config: WorldConfig | None = None,
) -> HoldResult:
    """Hover with a zero command in a wind of ``mean_speed`` (m/s) and ``turbulence`` (Dryden scale,
    0: steady) for ``settle_s + measure_s`` seconds, once per seed (each seed draws the wind
    direction and the gusts). ``altitude`` (m) is the start height above the deck."""
    cfg = config if config is not None else WorldConfig(camera=None, gains=VelocityGains(wind_hold=True))
    world = World(cfg)
    try:
        wind = Wind(WindParams(mean_speed_min=mean_speed, mean_speed_max=mean_speed, turbulence=turbulence))
        world.add_disturbance(wind)
        n_settle = int(round(settle_s * cfg.control_hz))
        n_measure = max(int(round(measure_s * cfg.control_hz)), 1)
        worst = total = tilt = 0.0
        for seed in seeds:
            world.reset(StaticProfile(), horizon_s=settle_s + measure_s + 1.0, altitude=altitude)
            world.reset_random(np.random.default_rng(seed))
            start, _ = world.drone_pose()
            world.set_velocity_setpoint(np.zeros(4))
            for _ in range(n_settle):
                world.step()
            for _ in range(n_measure):
                world.step()
                pos, R = world.drone_pose()
                d = math.hypot(pos[0] - start[0], pos[1] - start[1])
                worst, total = max(worst, d), total + d
                tilt = max(tilt, math.acos(max(-1.0, min(1.0, float(R[2, 2])))))
        return HoldResult(mean_speed, turbulence, worst, total / (n_measure * len(seeds)), tilt)
    finally:
        world.close()


@dataclass(frozen=True)
class Envelope:
    """:func:`envelope`'s table and the strongest winds held within each tolerance."""

    results: tuple[HoldResult, ...]
    tolerances: tuple[float, ...]  # m
    held: dict[float, float]  # tolerance (m) -> strongest mean wind (m/s) held within it (-1: none)

    def text(self) -> str:
        lines = [f"turbulence {self.results[0].turbulence:g}", "wind m/s  max m  mean m  tilt deg"]
        for r in self.results:
            tilt = math.degrees(r.max_tilt)
            lines.append(f"{r.mean_speed:8.1f}  {r.max_offset:5.3f}  {r.mean_offset:6.3f}  {tilt:8.1f}")
        for tol, speed in self.held.items():
            held = f"held within {tol:g} m up to {speed:g} m/s" if speed >= 0 else f"never within {tol:g} m"
            lines.append(held)
        return "\n".join(lines)


def envelope(
    speeds: Sequence[float] = (0.0, 2.0, 5.0, 8.0, 10.0, 12.0, 14.0, 15.0, 16.0, 18.0, 20.0, 22.0),
    turbulence: float = 0.0,
    seeds: Sequence[int] = (0,),
    tolerances: Sequence[float] = (0.3, 1.0),
    settle_s: float = 10.0,
    measure_s: float = 10.0,
    config: WorldConfig | None = None,
) -> Envelope:
    """:func:`hold_in_wind` at each mean wind speed (m/s, increasing); a tolerance's wind is the
    last speed before the first one whose offset exceeds it."""
    results = tuple(hold_in_wind(s, turbulence, seeds, settle_s, measure_s, config=config) for s in speeds)
    held: dict[float, float] = {}
    for tol in tolerances:
        best = -1.0
        for r in results:
            if r.max_offset > tol:
                break
            best = r.mean_speed
        held[float(tol)] = best
    return Envelope(results, tuple(float(t) for t in tolerances), held)


if __name__ == "__main__":  # pragma: no cover
    print(envelope().text())
    print()
    print(envelope(turbulence=1.0, seeds=(0, 1, 2)).text())

__all__ = [
    "Envelope",
    "HoldResult",
    "envelope",
    "hold_in_wind",
]
