"""The landing tasks' validated parts: start, arena, deck motion, thresholds, rewards.

Frozen dataclasses; each checks its own fields in ``__post_init__`` with :mod:`ihrcf_env.core.checks`
(physical bounds included), the messages naming the ``gym.make`` option. They are built by
:func:`ihrcf_env.config.make.make_config`, the one place options are read. SI units, radians.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ihrcf_env.core.checks import (
    check_bool,
    check_fields,
    check_non_negative,
    check_positive,
    check_real,
    check_reals,
    check_str,
    from_fields,
    set_field,
)
from ihrcf_env.core.profiles import PROFILE_NAMES, MotionProfile, make_profile, sea_state_amplitudes
from ihrcf_env.core.ship import DEFAULT_LENGTH_SCALE, ShipOptions

#: Seconds of deck motion checked against the legs' stroke at reset when ``horizon_s`` is None.
DEFAULT_HORIZON_S = 600.0
#: Longest ``horizon_s`` (s): the check samples the profile at 20 Hz over the whole horizon.
MAX_HORIZON_S = 3600.0
#: Lowest start altitude above the deck origin (m): legs 0.10 m below the centre plus a tilted deck.
MIN_START_ALTITUDE = 0.3
#: Below about this altitude (m) the 0.40 m tag leaves the default camera's view.
TAG_VIEW_ALTITUDE = 0.45
#: The highest start stays this far (m) below ``arena_ceiling``.
CEILING_MARGIN = 0.5
#: ``arena_half_width`` exceeds the start offset and the deck's half size by at least this (m).
ARENA_MARGIN = 0.5
#: Largest arena half width and ceiling (m).
MAX_ARENA = 1000.0
#: Largest reward weight: larger ones overflow returns summed over long episodes.
MAX_WEIGHT = 1e6
#: Largest velocity command (m/s, rad/s) per unit action.
MAX_COMMAND = 20.0


@dataclass(frozen=True)
class StartDistribution:
    """Seeded start of an episode relative to the deck frame origin: altitude uniform in
    ``altitude +- altitude_jitter`` (m), horizontal offset uniform in ``+-offset`` per world axis
    (m; the landing task draws it over a disc), yaw uniform in ``+-yaw`` (rad); ``trimmed``: the
    drone starts as an autopilot already holding position in the wind would be, leaning into it
    (:meth:`~ihrcf_env.sim.world.World.trim`). Options ``start_altitude``,
    ``start_altitude_jitter``, ``start_offset``, ``start_yaw``, ``start_trimmed``."""

    altitude: float = 1.0
    altitude_jitter: float = 0.05
    offset: float = 0.1
    yaw: float = 0.2
    trimmed: bool = False

    def __post_init__(self) -> None:
        set_field(self, "altitude", check_real("start_altitude", self.altitude, "m", low=0.0, high=MAX_ARENA))
        jitter = check_non_negative("start_altitude_jitter", self.altitude_jitter, "m", high=MAX_ARENA)
        set_field(self, "altitude_jitter", jitter)
        set_field(self, "offset", check_non_negative("start_offset", self.offset, "m", high=MAX_ARENA))
        set_field(self, "yaw", check_real("start_yaw", self.yaw, "rad", low=0.0, high=math.pi))
        set_field(self, "trimmed", check_bool("start_trimmed", self.trimmed))
        if self.lowest < MIN_START_ALTITUDE:
            raise ValueError(
                f"start_altitude - start_altitude_jitter = {self.altitude:g} - {self.altitude_jitter:g} m "
                f"is below the lowest allowed start, {MIN_START_ALTITUDE} m above the deck: the drone's "
                f"legs reach 0.10 m below its centre and a tilted deck rises under it, so an episode "
                f"could end at its first step (note: below ~{TAG_VIEW_ALTITUDE} m the tag also leaves "
                f"the camera's view)"
            )

    @property
    def lowest(self) -> float:
        return self.altitude - self.altitude_jitter

    @property
    def highest(self) -> float:
        return self.altitude + self.altitude_jitter


@dataclass(frozen=True)
class Arena:
    """The drone crashes ("left the arena") beyond ``+-half_width`` (m) in world x or y, or above
    ``ceiling`` (m, world z). Options ``arena_half_width``, ``arena_ceiling``."""

    half_width: float = 5.0
    ceiling: float = 6.0

    def __post_init__(self) -> None:
        set_field(
            self, "half_width", check_positive("arena_half_width", self.half_width, "m", high=MAX_ARENA)
        )
        set_field(self, "ceiling", check_positive("arena_ceiling", self.ceiling, "m", high=MAX_ARENA))


@dataclass(frozen=True)
class Thresholds:
    """Touchdown on the deck is a success if the approach speed along the deck normal is below
    ``success_speed`` (m/s) and the drone-deck tilt below ``success_tilt`` (rad); a tilt over
    ``crash_tilt`` (rad) in flight is a crash."""

    success_speed: float = 0.5
    success_tilt: float = math.radians(10.0)
    crash_tilt: float = math.radians(60.0)

    def __post_init__(self) -> None:
        speed = check_positive("Thresholds.success_speed", self.success_speed, "m/s", high=MAX_COMMAND)
        set_field(self, "success_speed", speed)
        for name in ("success_tilt", "crash_tilt"):
            set_field(
                self, name, check_positive(f"Thresholds.{name}", getattr(self, name), "rad", high=math.pi)
            )
        if not self.success_tilt < self.crash_tilt:
            raise ValueError(
                f"Thresholds need success_tilt < crash_tilt, got {self.success_tilt}, {self.crash_tilt}"
            )


def _check_weights(obj: object, name: Callable[[str], str]) -> None:
    fields = obj.__dataclass_fields__  # type: ignore[attr-defined]
    check_fields(obj, name, dict.fromkeys(fields, (0.0, MAX_WEIGHT)))


@dataclass(frozen=True)
class RewardWeights:
    """Hover task's per-step reward ``-position_xy |e_xy| - position_z max(e_z, 0) - velocity |v_rel|
    - attitude tilt - action |a|^2``, plus ``+success`` / ``-crash`` at the end (all in [0, 1e6])."""

    position_xy: float = 1.0
    position_z: float = 0.2
    velocity: float = 0.1
    attitude: float = 0.1
    action: float = 0.01
    success: float = 100.0
    crash: float = 100.0

    def __post_init__(self) -> None:
        _check_weights(self, lambda n: f"RewardWeights.{n}")


@dataclass(frozen=True)
class RewardWeightsV1:
    """Weights of the landing reward (:mod:`ihrcf_env.envs.landing_v1`): ``distance`` (1/m),
    ``height`` (1/m), ``speed`` (s/m) of the potential; ``time`` (1/s) and ``action`` (1/s) per
    second of flight; ``success``, ``crash`` and ``near_miss`` (<= crash) once. All in [0, 1e6]."""

    distance: float = 10.0
    height: float = 5.0
    speed: float = 5.0
    time: float = 1.0
    action: float = 0.2
    success: float = 100.0
    crash: float = 100.0
    near_miss: float = 20.0

    def __post_init__(self) -> None:
        _check_weights(self, lambda n: f"reward_weights[{n!r}]")
        if self.near_miss > self.crash:
            raise ValueError(
                f"reward_weights['near_miss'] ({self.near_miss}) must not exceed reward_weights['crash'] "
                f"({self.crash})"
            )


ProfileSpec = str | Callable[[float], Any] | MotionProfile


@dataclass(frozen=True)
class DeckMotion:
    """How the deck moves. Options ``deck_profile``, ``sea_state_amplitudes`` (only with
    ``"sea_state"``), ``ship`` (:class:`~ihrcf_env.core.ship.ShipOptions` or a dict of its fields,
    only with ``"ship"``: sea state, vessel, heading, speed, Froude scale), ``random_deck_start``
    (start at a seeded time in [0, 130) s of the profile) and ``horizon_s`` (seconds of motion
    checked against the legs' stroke at reset; beyond it the deck stops rather than fail
    mid-episode)."""

    profile: ProfileSpec = "paper"
    sea_state_amplitudes: Mapping[str, float] | None = None
    random_start: bool = False
    horizon_s: float = DEFAULT_HORIZON_S
    ship: ShipOptions | None = None

    def __post_init__(self) -> None:
        prof = self.profile
        if isinstance(prof, str):
            check_str("deck_profile", prof, PROFILE_NAMES)
        elif not (isinstance(prof, MotionProfile) or callable(prof)):
            raise TypeError(
                f"deck_profile must be one of {PROFILE_NAMES}, a MotionProfile or a callable "
                f"t -> (offset (3,), rpy (3,)), got {type(prof).__name__} {prof!r}"
            )
        if self.sea_state_amplitudes is not None:
            if prof != "sea_state":
                raise ValueError(
                    f"sea_state_amplitudes is only used with deck_profile='sea_state', got "
                    f"deck_profile={prof!r}: drop it or choose 'sea_state'"
                )
            sea_state_amplitudes(self.sea_state_amplitudes)  # types, names, signs
            set_field(self, "sea_state_amplitudes", dict(self.sea_state_amplitudes))
        if self.ship is not None:
            if prof != "ship":
                raise ValueError(
                    f"ship is only used with deck_profile='ship', got deck_profile={prof!r}: drop it or "
                    "choose 'ship'"
                )
            set_field(self, "ship", from_fields("ship", ShipOptions, self.ship))
        set_field(self, "random_start", check_bool("random_deck_start", self.random_start))
        h = check_positive("horizon_s", self.horizon_s, "s", high=MAX_HORIZON_S)
        set_field(self, "horizon_s", h)

    @property
    def length_scale(self) -> float:
        """The deck's Froude scale (model/full size): the ship's, else the default platform's."""
        return self.ship.length_scale if self.ship is not None else DEFAULT_LENGTH_SCALE

    def make_profile(self, rng: np.random.Generator) -> MotionProfile:
        """This episode's profile (a sea state draws its periods and phases from ``rng``)."""
        return make_profile(self.profile, rng, self.sea_state_amplitudes, ship=self.ship)


@dataclass(frozen=True)
class LandingGoal:
    """What the landing task (``DeckLanding-v1``) adds: ``success_radius`` (m, horizontal, drone
    centre to tag centre), ``start_in_view`` (clip the start offset so the tag is in view),
    ``view_margin`` (m kept between the tag and the image border at the start, for the deck's
    motion) and the reward weights."""

    success_radius: float = 0.15
    start_in_view: bool = True
    view_margin: float = 0.1
    reward: RewardWeightsV1 = field(default_factory=RewardWeightsV1)

    def __post_init__(self) -> None:
        set_field(
            self, "success_radius", check_positive("success_radius", self.success_radius, "m", high=1.0)
        )
        set_field(self, "start_in_view", check_bool("start_in_view", self.start_in_view))
        set_field(self, "view_margin", check_non_negative("view_margin", self.view_margin, "m", high=10.0))


@dataclass(frozen=True)
class TaskConfig:
    """A task: start, arena, deck motion, outcome thresholds, hover reward, velocity action scale
    (``max_velocity``: m/s, m/s, m/s, rad/s per unit action) and, for the landing task, ``landing``
    (None for the hover task)."""

    start: StartDistribution = field(default_factory=StartDistribution)
    arena: Arena = field(default_factory=Arena)
    deck: DeckMotion = field(default_factory=DeckMotion)
    thresholds: Thresholds = field(default_factory=Thresholds)
    reward: RewardWeights = field(default_factory=RewardWeights)
    max_velocity: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    landing: LandingGoal | None = None

    def __post_init__(self) -> None:
        mv = check_reals("max_velocity", self.max_velocity, 4, "m/s, m/s, m/s, rad/s", high=MAX_COMMAND)
        if min(mv) <= 0:
            raise ValueError(f"max_velocity must be 4 positive numbers (m/s, m/s, m/s, rad/s), got {mv!r}")
        set_field(self, "max_velocity", mv)
        if self.start.offset + ARENA_MARGIN > self.arena.half_width:
            raise ValueError(
                f"start_offset {self.start.offset:g} m must stay {ARENA_MARGIN} m inside arena_half_width "
                f"{self.arena.half_width:g} m"
            )


__all__ = [
    "ARENA_MARGIN",
    "CEILING_MARGIN",
    "DEFAULT_HORIZON_S",
    "MAX_ARENA",
    "MAX_COMMAND",
    "MAX_HORIZON_S",
    "MAX_WEIGHT",
    "MIN_START_ALTITUDE",
    "TAG_VIEW_ALTITUDE",
    "Arena",
    "DeckMotion",
    "LandingGoal",
    "ProfileSpec",
    "RewardWeights",
    "RewardWeightsV1",
    "StartDistribution",
    "TaskConfig",
    "Thresholds",
]
