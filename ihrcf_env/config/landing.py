"""The whole resolved configuration of a deck env: :class:`DeckLandingConfig`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ihrcf_env.config.levels import LEVELS
from ihrcf_env.config.observation import ObservationConfig
from ihrcf_env.config.task import ARENA_MARGIN, CEILING_MARGIN, TaskConfig
from ihrcf_env.config.wind import Disturbance, WindParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.checks import check_int, check_str, describe, set_field
from ihrcf_env.core.estimators.detector import apriltag_ids
from ihrcf_env.core.profiles import check_sea_state_amplitudes

__all__ = ["MAX_CHASE_SIZE", "RENDER_MODES", "TASK_NAMES", "DeckLandingConfig"]

#: Largest chase-view image side (px).
MAX_CHASE_SIZE = 4096
RENDER_MODES: tuple[str, ...] = ("human", "rgb_array")
#: The deck tasks: the hover experiment and the landing tasks v1 and v2.
TASK_NAMES: tuple[str, ...] = ("hover", "landing-v1", "landing-v2")


@dataclass(frozen=True)
class DeckLandingConfig:
    """The whole configuration of a :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`:
    ``world``, ``task``, ``observation``, the rendering, the disturbances and the wind, and the
    ``task_name`` (a key of :data:`TASK_NAMES`) and ``level`` (of ``"landing-v2"``; None
    otherwise) they were made for."""

    world: WorldConfig = field(default_factory=WorldConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    render_mode: str | None = None
    chase_size: tuple[int, int] = (640, 480)
    disturbances: tuple[Disturbance, ...] = ()
    wind: WindParams | None = None
    task_name: str = "hover"
    level: str | None = None

    def __post_init__(self) -> None:
        check_str("task_name", self.task_name, TASK_NAMES)
        if self.level is not None:
            check_str("level", self.level, tuple(LEVELS))
        if self.render_mode is not None:
            check_str("render_mode", self.render_mode, RENDER_MODES)
        size = self.chase_size
        if not (isinstance(size, Sequence | np.ndarray) and not isinstance(size, str) and len(size) == 2):
            raise TypeError(f"chase_size must be (width, height) in pixels, got {size!r}")
        w = check_int("chase_size[0]", size[0], low=1, high=MAX_CHASE_SIZE)
        h = check_int("chase_size[1]", size[1], low=1, high=MAX_CHASE_SIZE)
        set_field(self, "chase_size", (w, h))
        if isinstance(self.disturbances, str | Disturbance) or not isinstance(self.disturbances, Sequence):
            raise TypeError(f"disturbances must be a sequence of Disturbance, got {self.disturbances!r}")
        for d in self.disturbances:
            if not isinstance(d, Disturbance):
                raise TypeError(
                    f"disturbances: {d!r} is not a Disturbance "
                    "(reset(rng) and __call__(t, position, velocity))"
                )
        set_field(self, "disturbances", tuple(self.disturbances))
        if self.wind is not None and not isinstance(self.wind, WindParams):
            raise TypeError(f"wind must be WindParams or None, got {describe(self.wind)}")
        self._check_geometry()

    def _check_geometry(self) -> None:
        deck = self.world.deck
        check_int("tag_id", deck.tag_id, low=0, high=apriltag_ids() - 1)
        task = self.task
        if task.arena.half_width < deck.size / 2 + ARENA_MARGIN:
            raise ValueError(
                f"arena_half_width {task.arena.half_width:g} m must exceed the deck's half size "
                f"({deck.size / 2:g} m) by {ARENA_MARGIN} m"
            )
        top = self.max_start_altitude
        if task.start.highest > top:
            raise ValueError(
                f"start_altitude + start_altitude_jitter = {task.start.highest:g} m above the deck would "
                f"start within {CEILING_MARGIN} m of arena_ceiling {task.arena.ceiling:g} m (the deck "
                f"origin reaches up to {self.deck_reach:.3f} m): the highest start allowed is "
                f"{top:.3f} m; lower start_altitude or raise arena_ceiling"
            )
        if task.deck.profile == "sea_state":
            check_sea_state_amplitudes(task.deck.sea_state_amplitudes, self.world.stewart)

    @property
    def deck_reach(self) -> float:
        """Upper bound (m, world z) of the deck origin: top joints at most ``max_leg`` above the base
        joints, the origin at most ``joint_depth`` above their centroid."""
        g = self.world.stewart
        return g.base_height + g.max_leg + g.joint_depth

    @property
    def max_start_altitude(self) -> float:
        """Highest start altitude above the deck origin (m) that stays clear of the ceiling."""
        return self.task.arena.ceiling - CEILING_MARGIN - self.deck_reach
