"""When sensors sample and when their readings arrive, on the simulator's physics ticks.

Two timing models beside the default one (every sensor read once per control step, the camera
every ``control_hz / camera_hz`` steps):

* **Own clock** (:class:`SampleClock`): a sensor ranging or sampling at its own rate (the
  VL53L1X's timing budget, an IMU's output data rate) samples at ``k / rate_hz`` s, each instant
  moved to the first physics tick at or after it; the observation shows the last sample taken.
* **Delay line** (:class:`DelayLine`): a camera frame exposed at one control step reaches the
  observation ``latency`` s later, at the first control step at or after exposure + latency.

Pure Python + numpy (the :class:`~ihrcf_env.sim.world.World` calls them); see ``docs/sensors.md``,
"Timing and latency".
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.sim.sensors.base import tag_reading

#: Tolerance (physics ticks) of the tick arithmetic: an instant within it of a tick is on the tick.
_TICK_EPS = 1e-6
#: ``tag_reason`` of a tag-corner reading before the first frame of an episode has arrived.
NO_FRAME_YET = "no camera frame yet"


class SampleClock:
    """The sample instants of a sensor of rate ``rate_hz`` (Hz) on physics ticks of ``physics_hz``
    (``rate_hz <= physics_hz``, so two samples never share a tick). Sample ``k`` is taken at the
    first tick at or after ``k / rate_hz`` s."""

    def __init__(self, rate_hz: float, physics_hz: int) -> None:
        if not (0.0 < rate_hz <= physics_hz):
            raise ValueError(f"a sensor rate must be in (0, physics_hz = {physics_hz}] Hz, got {rate_hz!r}")
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz  # s
        self._ticks_per_sample = physics_hz / self.rate_hz
        self.next = 0  # index of the next sample not yet taken

    def reset(self) -> None:
        self.next = 0

    def tick_of(self, k: int) -> int:
        """The physics tick of sample ``k``."""
        return math.ceil(k * self._ticks_per_sample - _TICK_EPS)

    def last_index(self, tick: int) -> int:
        """The index of the last sample whose tick is at or before ``tick``."""
        return math.floor((tick + _TICK_EPS) / self._ticks_per_sample)

    def pending(self, first: int, last: int) -> list[int]:
        """The ticks in ``[first, last]`` of the samples not yet taken, in order."""
        k0 = max(self.next, self.last_index(first - 1) + 1)
        return [self.tick_of(k) for k in range(k0, self.last_index(last) + 1)]

    def taken(self, tick: int) -> None:
        """The sample at ``tick`` (or the last one at or before it) has been taken."""
        self.next = self.last_index(tick) + 1


class DelayLine:
    """Readings in flight from their exposure to their delivery ``latency`` s later, on physics
    ticks of ``physics_hz``."""

    def __init__(self, latency: float, physics_hz: int) -> None:
        self.latency = float(latency)
        self._latency_ticks = self.latency * physics_hz
        self._line: deque[tuple[int, dict[str, NDArray]]] = deque()
        self.exposed_at = -1  # tick of the last exposure

    def reset(self) -> None:
        self._line.clear()
        self.exposed_at = -1

    def push(self, tick: int, reading: Mapping[str, NDArray]) -> None:
        """A reading exposed at ``tick``."""
        self._line.append((tick, dict(reading)))
        self.exposed_at = tick

    def deliver(self, tick: int) -> list[tuple[int, dict[str, NDArray]]]:
        """The readings due at ``tick`` (exposed ``latency`` s or more before it), oldest first."""
        out = []
        while self._line and tick - self._line[0][0] >= self._latency_ticks - _TICK_EPS:
            out.append(self._line.popleft())
        return out

    def __len__(self) -> int:
        return len(self._line)


def no_frame_reading(name: str, width: int, height: int) -> dict[str, NDArray]:
    """What a camera sensor ``name`` shows before its first frame arrives: a black image
    (``"camera"``) or no tag corners, with the reason :data:`NO_FRAME_YET` (the tag camera)."""
    if name == "camera":
        return {"image": np.zeros((height, width, 3), np.uint8)}
    return tag_reading(None, NO_FRAME_YET)


__all__ = [
    "NO_FRAME_YET",
    "DelayLine",
    "SampleClock",
    "no_frame_reading",
]
