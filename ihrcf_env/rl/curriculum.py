"""A start curriculum for learning ``ihrcf_env/DeckLanding-v1`` (no torch: usable with any library).

A learner dropped 1.5-3 m above a moving deck rarely touches down softly on the tag by chance; PPO
then settles on hovering until the time limit (the safe local optimum) before it ever sees a
success. :class:`StartCurriculum` is a reverse curriculum over the start (Florensa et al. 2017,
"Reverse curriculum generation"): at ``level`` 0 episodes start low and near the tag
(``easy_altitude``, ``easy_offset``), and as the level rises to 1 the start distribution widens to
the env's own (v1: 1.5-3 m, up to 1 m off, clipped to keep the tag in view). A fraction
``full_fraction`` of the episodes always starts from the env's own distribution. Only the start
changes: the deck, wind, sensors, reward and success test are the task's. Evaluate on the env
without the wrapper.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.config.task import MIN_START_ALTITUDE


class StartCurriculum(gym.Wrapper[Any, Any, Any, Any]):
    """Draws the start altitude (m above the deck origin) and horizontal offset (m) of each episode
    between an easy start and the env's own (module docstring) and passes them as reset options.

    ``level`` in [0, 1] (:meth:`set_curriculum_level`); altitude uniform in the interval
    interpolated from ``easy_altitude`` to the env's ``start_altitude +- start_altitude_jitter``;
    offset uniform over a disc whose radius goes from ``easy_offset`` to ``start_offset``, never
    beyond the env's in-view radius (v1's ``start_radius``). Its random stream is seeded from
    ``reset(seed=)`` (apart from the env's, whose draws it does not shift)."""

    def __init__(
        self,
        env: gym.Env,
        easy_altitude: tuple[float, float] = (0.4, 0.8),
        easy_offset: float = 0.1,
        full_fraction: float = 0.25,
        level: float = 0.0,
    ):
        super().__init__(env)
        base = env.unwrapped
        for attr in ("goal", "start_radius"):
            if not hasattr(base, attr):
                raise TypeError(f"env must be a DeckLanding-v1 env (no {attr!r}), got {type(base).__name__}")
        start = base.config.task.start  # type: ignore[attr-defined]
        try:
            lo, hi = (float(v) for v in easy_altitude)
        except (TypeError, ValueError):
            raise TypeError(f"easy_altitude must be two numbers (m), got {easy_altitude!r}") from None
        top = start.altitude + start.altitude_jitter
        if not MIN_START_ALTITUDE <= lo <= hi <= top:
            raise ValueError(
                f"easy_altitude must satisfy {MIN_START_ALTITUDE} <= low <= high <= {top:g} m, "
                f"got {easy_altitude!r}"
            )
        if isinstance(easy_offset, bool) or not isinstance(easy_offset, int | float):
            raise TypeError(f"easy_offset must be a number (m), got {easy_offset!r}")
        if isinstance(full_fraction, bool) or not isinstance(full_fraction, int | float):
            raise TypeError(f"full_fraction must be a number, got {full_fraction!r}")
        if not 0.0 <= easy_offset <= start.offset:
            raise ValueError(f"easy_offset must be in [0, {start.offset:g}] m, got {easy_offset!r}")
        if not 0.0 <= full_fraction <= 1.0:
            raise ValueError(f"full_fraction must be in [0, 1], got {full_fraction!r}")
        self.easy_altitude = (lo, hi)
        self.full_altitude = (start.altitude - start.altitude_jitter, top)
        self.easy_offset, self.full_offset = float(easy_offset), float(start.offset)
        self.full_fraction = float(full_fraction)
        self.level = 0.0
        self.set_curriculum_level(level)
        self._rng: np.random.Generator | None = None

    def set_curriculum_level(self, level: float) -> None:
        """Set the level (0: easy starts only, 1: the env's own starts)."""
        if not 0.0 <= float(level) <= 1.0:
            raise ValueError(f"level must be in [0, 1], got {level!r}")
        self.level = float(level)

    def draw_start(self, rng: np.random.Generator) -> dict[str, Any] | None:
        """Reset options (``altitude``, ``offset``) of one start at the current level; None for the
        env's own start."""
        u = self.level
        if u >= 1.0 or rng.uniform() < self.full_fraction:
            return None
        (a0, a1), (b0, b1) = self.easy_altitude, self.full_altitude
        alt = rng.uniform(a0 + u * (b0 - a0), a1 + u * (b1 - a1))
        radius = min(
            self.easy_offset + u * (self.full_offset - self.easy_offset),
            float(self.env.unwrapped.start_radius(alt)),  # type: ignore[attr-defined]
        )
        r, phi = radius * math.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * math.pi)
        return {"altitude": float(alt), "offset": (r * math.cos(phi), r * math.sin(phi))}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng([0 if seed is None else int(seed), 0x5EED])
        start = self.draw_start(self._rng)
        opts = dict(options or {})
        if start is not None and not {"altitude", "offset"} & set(opts):
            opts.update(start)
        obs, info = self.env.reset(seed=seed, options=opts or None)
        info["curriculum_level"] = self.level
        return obs, info


def curriculum_env(make: Callable[[], gym.Env]) -> StartCurriculum:
    """``StartCurriculum(make())`` with the default curriculum (a picklable env factory)."""
    return StartCurriculum(make())


__all__ = [
    "StartCurriculum",
    "curriculum_env",
]
