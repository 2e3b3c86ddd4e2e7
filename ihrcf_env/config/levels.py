"""The graded levels of ``ihrcf_env/DeckLanding-v2``: documented bundles of sea, wind and sensing.

Each :class:`Level` sets the defaults of a group of options (any of them can still be given): the
deck on the ``"ship"`` profile in a WMO sea state at a Froude length scale
(:mod:`ihrcf_env.core.ship`), the mean wind range with Dryden gusts
(:class:`~ihrcf_env.config.wind.WindParams`), and the wind-holding autopilot with ground
effect for every level. The sea states and scales are those the paper's Stewart platform can
reproduce (``docs/deck-motion.md``); the wind ranges follow the Beaufort scale: ``calm`` up to a
gentle breeze (Beaufort 0-3), ``moderate`` a fresh breeze (8-12 m/s, Beaufort 5, an ordinary day
at sea), ``rough`` a strong breeze (12-15 m/s, Beaufort 6). Sensing degrades with the weather:
``calm`` has no faults, ``moderate`` loses 5 % of the camera frames in bursts (glare, spray on the
lens), ``rough`` 10 % and one ToF sensor fails (reads invalid) at a random time of the episode. (Faults
acting on detected corners only, such as ``tag_occlusion``, are left out: a level applies to both
camera models.)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Level:
    """One level: WMO ``sea_state`` at Froude ``length_scale``, wind mean speed in
    [``wind_min``, ``wind_max``] (m/s) with gusts of Dryden scale ``turbulence``, and the sensor
    ``faults`` (the ``faults`` option, :mod:`ihrcf_env.sim.faults`)."""

    name: str
    description: str
    sea_state: int
    length_scale: float
    wind_min: float
    wind_max: float
    turbulence: float = 1.0
    faults: dict[str, Any] = field(default_factory=dict)

    def defaults(self) -> dict[str, Any]:
        """The ``make_config`` option defaults this level sets."""
        return {
            "faults": dict(self.faults),
            "deck_profile": "ship",
            "ship": {"sea_state": self.sea_state, "length_scale": self.length_scale},
            "wind": {
                "mean_speed_min": self.wind_min,
                "mean_speed_max": self.wind_max,
                "turbulence": self.turbulence,
            },
        }


LEVELS: dict[str, Level] = {
    "calm": Level(
        "calm", "sea state 3, wind 0-5 m/s", sea_state=3, length_scale=30.0, wind_min=0.0, wind_max=5.0
    ),
    "moderate": Level(
        "moderate",
        "sea state 4, wind 8-12 m/s, bursts of lost camera frames",
        sea_state=4,
        length_scale=30.0,
        wind_min=8.0,
        wind_max=12.0,
        faults={"camera_dropout": {"loss_rate": 0.05, "mean_burst": 3}},
    ),
    "rough": Level(
        "rough",
        "sea state 5, wind 12-15 m/s, more lost frames, one ToF sensor failing",
        sea_state=5,
        length_scale=40.0,
        wind_min=12.0,
        wind_max=15.0,
        faults={
            "camera_dropout": {"loss_rate": 0.10, "mean_burst": 3},
            "tof_dead": {"count": 1, "onset": (0.0, 30.0)},
        },
    ),
}
#: The level of ``ihrcf_env/DeckLanding-v2`` when none is given.
DEFAULT_LEVEL = "moderate"
#: Seeds of the benchmark protocol's test episodes (train and tune on other seeds).
TEST_SEEDS: range = range(100_000, 100_100)

__all__ = [
    "DEFAULT_LEVEL",
    "LEVELS",
    "TEST_SEEDS",
    "Level",
]
