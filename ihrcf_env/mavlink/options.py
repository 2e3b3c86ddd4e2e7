"""The vehicle's options (:class:`VehicleOptions`), checked once, where they are made."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ihrcf_env.mavlink.link import check_endpoint
from ihrcf_env.mavlink.target import PROFILES, TARGETS

#: Where the vehicle sends by default (PX4 SITL's offboard API port).
DEFAULT_OUT = "udpout:127.0.0.1:14540"


@dataclass(frozen=True)
class VehicleOptions:
    """The vehicle's options, checked once here (ValueError naming the option).

    Attributes:
        endpoints: pymavlink connection strings (``udpout:HOST:PORT``, ``udpin:HOST:PORT``).
        speed: simulated seconds per wall second (> 0); None: as fast as it runs.
        episodes: episodes to run before :meth:`MavlinkVehicle.run` returns; None: one, then
            stay up until stopped.
        seed: the first episode's seed (then seed + 1, ...).
        target: ``LANDING_TARGET``'s source: an estimator of the env or ``"truth"``.
        profile: ``"px4"`` or ``"ardupilot"`` (:mod:`ihrcf_env.mavlink.target`).
        system_id, component_id: the vehicle's MAVLink ids.
        auto_arm: arm at each episode's start (no client needed; for benchmarks).
        duration: stop after this many simulated seconds of the vehicle clock (None: no limit).
    """

    endpoints: tuple[str, ...] = (DEFAULT_OUT,)
    speed: float | None = 1.0
    episodes: int | None = None
    seed: int = 0
    target: str = "fused"
    profile: str = "px4"
    system_id: int = 1
    component_id: int = 1
    auto_arm: bool = False
    duration: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.endpoints, str) or not self.endpoints:
            raise ValueError(
                f"endpoints must be a non-empty sequence of connection strings, got {self.endpoints!r}"
            )
        object.__setattr__(self, "endpoints", tuple(self.endpoints))
        for e in self.endpoints:
            try:
                check_endpoint(e)
            except ValueError as err:
                raise ValueError(f"endpoints: {err}") from None
        if self.speed is not None and not (
            isinstance(self.speed, int | float)
            and not isinstance(self.speed, bool)
            and math.isfinite(self.speed)
            and 0 < self.speed <= 1e6
        ):
            raise ValueError(
                f"speed must be a number in (0, 1e6] or None (as fast as it runs), got {self.speed!r}"
            )
        if self.episodes is not None and not (isinstance(self.episodes, int) and self.episodes >= 1):
            raise ValueError(f"episodes must be an integer >= 1 or None, got {self.episodes!r}")
        if not (isinstance(self.seed, int) and 0 <= self.seed <= 2**32 - 1):
            raise ValueError(f"seed must be an integer in [0, 2**32 - 1], got {self.seed!r}")
        if self.target not in TARGETS:
            raise ValueError(f"target must be one of {TARGETS}, got {self.target!r}")
        if self.profile not in PROFILES:
            raise ValueError(f"profile must be one of {PROFILES}, got {self.profile!r}")
        for name in ("system_id", "component_id"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 1 <= v <= 255):
                raise ValueError(f"{name} must be an integer in [1, 255], got {v!r}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be a positive number of seconds or None, got {self.duration!r}")


__all__ = ["DEFAULT_OUT", "VehicleOptions"]
