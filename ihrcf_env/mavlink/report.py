"""What a vehicle's run did: its episodes (:class:`EpisodeRecord`), times, messages and counters
(:class:`VehicleReport`)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field


@dataclass
class EpisodeRecord:
    """One finished episode: seed, outcome (the env's ``info["outcome"]``, or ``"truncated"``),
    its simulated duration (s) and, after a touchdown, the relative vertical speed (m/s), the
    relative tilt (rad) and the offset from the tag centre (m)."""

    seed: int
    outcome: str
    time: float
    speed: float | None = None
    tilt: float | None = None
    offset: float | None = None
    reason: str = ""

    def line(self) -> str:
        """One line: seed, outcome, time and the touchdown figures."""
        td = (
            f"speed {self.speed:.3f} m/s  tilt {math.degrees(self.tilt):5.2f} deg  offset {self.offset:.3f} m"
            if self.speed is not None and self.tilt is not None and self.offset is not None
            else "no touchdown"
        )
        why = f"  ({self.reason})" if self.reason else ""
        return f"seed {self.seed:5d}  {self.outcome:9s} t {self.time:6.2f} s  {td}{why}"


@dataclass
class VehicleReport:
    """What a run did: its episodes, the simulated and wall time (s), the wall time spent inside
    ``env.step`` (s), the messages sent by type and the vehicle's counters (rejected setpoints,
    failsafes, bad packets, ...)."""

    episodes: list[EpisodeRecord] = field(default_factory=list)
    sim_time: float = 0.0
    wall_time: float = 0.0
    env_time: float = 0.0
    steps: int = 0
    sent: Counter[str] = field(default_factory=Counter)
    counts: Counter[str] = field(default_factory=Counter)

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall second of the run."""
        return self.sim_time / self.wall_time if self.wall_time > 0 else math.nan


def format_rates(report: VehicleReport, names: Sequence[str] | None = None) -> list[str]:
    """One line per message type sent: count, rate on the simulated clock and on the wall clock."""
    lines = []
    for name in names or sorted(report.sent):
        n = report.sent.get(name, 0)
        sim = n / report.sim_time if report.sim_time > 0 else math.nan
        wall = n / report.wall_time if report.wall_time > 0 else math.nan
        lines.append(f"  {name:22s} {n:7d}  {sim:7.2f} Hz simulated  {wall:8.1f} /s wall")
    return lines


__all__ = ["EpisodeRecord", "VehicleReport", "format_rates"]
