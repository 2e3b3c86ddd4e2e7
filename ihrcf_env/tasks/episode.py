"""The landing and hover tasks' episode draws: the start, the deck motion and the wind of an episode
from its named random streams (:class:`~ihrcf_env.core.seeding.SeedStreams`), backend-neutral
(numpy, no simulator).

The PyBullet env (:class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv`) and the JAX backend's host
side (:mod:`ihrcf_env.fast.episode`) both call these functions, so seed ``s`` gives both the same
episode quantities: the start (stream ``"start"``: altitude, offset, yaw, the deck's start time),
the deck motion (``"deck"``: the profile, redrawn while a random sea exceeds the legs' stroke) and
the wind (``"wind"``: mean speed and direction, and the seed of the gust sequence). They live below
the env layer because they are the task's distribution, not the simulator's: a config
(:class:`~ihrcf_env.config.landing.DeckLandingConfig`) and a generator in, numbers out.

Frames: world z up; offsets (x, y) world m; yaw rad about world z; times s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.task import ARENA_MARGIN, MIN_START_ALTITUDE
from ihrcf_env.core.checks import check_real, check_reals
from ihrcf_env.core.profiles import PAPER_DURATION, MotionProfile, ShiftedProfile
from ihrcf_env.core.ship import fits

__all__ = [
    "MAX_DECK_DRAWS",
    "RANDOM_PROFILES",
    "RESET_OPTIONS",
    "STROKE_CHECK_DT",
    "TAG_EXTENT",
    "Start",
    "WindDraw",
    "draw_deck",
    "draw_start",
    "draw_wind",
    "gust_normals",
    "start_radius",
]

#: The keys ``reset(options=...)`` may fix.
RESET_OPTIONS = ("altitude", "offset", "yaw", "deck_time")
#: Deck profiles drawn at random per episode (a draw the legs cannot follow is drawn again).
RANDOM_PROFILES = ("ship", "sea_state")
#: Draws of a random sea per reset before giving up.
MAX_DECK_DRAWS = 20
#: Time step (s) of the check that a drawn sea stays within the legs' stroke.
STROKE_CHECK_DT = 0.05
#: Half of the tag's printed extent around its centre (m) per metre of ``tag_size``: the black
#: square (8 cells) plus the one-cell white border the detector needs, i.e. 10/8 / 2.
TAG_EXTENT = 10.0 / 8.0 / 2.0


class Start(NamedTuple):
    """An episode's start: ``altitude`` (m above the deck origin), horizontal ``offset`` (x, y)
    (m, world, from the deck origin), ``yaw`` (rad) and ``deck_time`` (s into the deck's profile)."""

    altitude: float
    offset: tuple[float, float]
    yaw: float
    deck_time: float


class WindDraw(NamedTuple):
    """The wind's episode draws from the ``"wind"`` stream, in their order: the uniforms on [0, 1)
    of the mean speed and of the direction, and the seed of the gust sequence's generator."""

    u_speed: float
    u_direction: float
    gust_seed: int


def start_radius(config: DeckLandingConfig, altitude: float) -> float:
    """Largest start offset (m) at ``altitude`` (m above the deck origin) of a landing task:
    ``start_offset``, or less so that the tag and its white border stay ``view_margin`` inside the
    image whatever the yaw (the inscribed circle of the view); 0 if even a centred start cannot see
    it. Without a landing goal or a camera: ``start_offset``."""
    limit = config.task.start.offset
    cam = config.world.camera
    goal = config.task.landing
    if cam is None or goal is None or not goal.start_in_view:
        return limit
    tan_half = math.tan(cam.fov / 2) * min(1.0, cam.width / cam.height)
    depth = altitude + float(config.world.rig.camera_position[2])  # the camera sits below the centre
    half_view = depth * tan_half
    tag = config.world.deck.tag_size * TAG_EXTENT * math.sqrt(2.0)
    return float(min(limit, max(0.0, half_view - tag - goal.view_margin)))


def draw_start(
    config: DeckLandingConfig,
    rng: np.random.Generator,
    options: Mapping[str, Any] | None = None,
    disc: bool = False,
) -> Start:
    """The start of a new episode, drawn from ``rng`` (the ``"start"`` stream; always drawn, so
    ``options`` do not shift the stream), then ``options`` (:data:`RESET_OPTIONS`; ValueError
    naming an unknown key or a bad value).

    The hover task's draw: altitude ``start_altitude +- start_altitude_jitter``, an offset uniform
    in ``+-start_offset`` per axis, a yaw uniform in ``+-start_yaw`` and, with
    ``random_deck_start``, the deck's start time uniform in [0, 130) s. With ``disc`` (the landing
    tasks) two more uniforms follow and the offset is uniform over the disc of
    :func:`start_radius` instead (unless ``options["offset"]`` fixes it)."""
    opts = dict(options) if options is not None else {}
    unknown = sorted(map(str, set(opts) - set(RESET_OPTIONS)))
    if unknown:
        raise ValueError(f"reset options has unknown keys {unknown}; known: {', '.join(RESET_OPTIONS)}")
    task = config.task
    start = task.start
    alt = start.altitude + rng.uniform(-1, 1) * start.altitude_jitter
    off = rng.uniform(-1, 1, 2) * start.offset
    yaw = rng.uniform(-1, 1) * start.yaw
    deck_time = rng.uniform(0.0, PAPER_DURATION) if task.deck.random_start else 0.0
    if "altitude" in opts:
        top = config.max_start_altitude
        alt = check_real("options['altitude']", opts["altitude"], "m", low=MIN_START_ALTITUDE, high=top)
    if "offset" in opts:
        limit = task.arena.half_width - ARENA_MARGIN
        off = np.array(check_reals("options['offset']", opts["offset"], 2, "m", low=-limit, high=limit))
    if "yaw" in opts:
        yaw = check_real("options['yaw']", opts["yaw"], "rad", low=-4 * math.pi, high=4 * math.pi)
    if "deck_time" in opts:
        deck_time = check_real("options['deck_time']", opts["deck_time"], "s", low=0.0, high=1e6)
    offset = (float(off[0]), float(off[1]))
    if disc:
        u, phi = rng.uniform(), rng.uniform(0.0, 2.0 * math.pi)
        if "offset" not in opts:
            r = start_radius(config, float(alt)) * math.sqrt(u)
            offset = (r * math.cos(phi), r * math.sin(phi))
    return Start(float(alt), offset, float(yaw), float(deck_time))


def draw_deck(
    config: DeckLandingConfig, rng: np.random.Generator, deck_time: float
) -> tuple[MotionProfile, bool]:
    """This episode's deck motion from ``rng`` (the ``"deck"`` stream), started at ``deck_time``
    (s), and whether its stroke was checked over ``horizon_s`` here. A random sea
    (:data:`RANDOM_PROFILES`) is drawn again, from the same stream, while the draw would take a leg
    beyond its stroke within ``horizon_s``; ValueError if :data:`MAX_DECK_DRAWS` draws all do."""
    deck = config.task.deck
    random_sea = deck.profile in RANDOM_PROFILES
    for _ in range(MAX_DECK_DRAWS if random_sea else 1):
        profile = deck.make_profile(rng)
        if deck_time:
            profile = ShiftedProfile(profile, deck_time)
        if not random_sea:
            return profile, False
        if fits(profile, config.world.stewart, deck.horizon_s, dt=STROKE_CHECK_DT):
            return profile, True
    raise ValueError(
        f"deck_profile {deck.profile!r}: {MAX_DECK_DRAWS} draws of this sea all exceed the Stewart "
        "legs' stroke within horizon_s: choose a calmer sea state, a larger length_scale, a larger "
        "platform (stewart) or a shorter horizon_s"
    )


def draw_wind(rng: np.random.Generator) -> WindDraw:
    """The wind's episode draws from ``rng`` (the ``"wind"`` stream): the mean speed is
    ``mean_speed_min + (mean_speed_max - mean_speed_min) u_speed`` and the direction
    ``2 pi u_direction`` (rad, world, the direction the air moves to), as
    ``rng.uniform(low, high)`` computes them."""
    u_speed = float(rng.random())
    u_direction = float(rng.random())
    return WindDraw(u_speed, u_direction, int(rng.integers(2**63)))


def gust_normals(gust_seed: int, count: int) -> np.ndarray:
    """The first ``count`` rows (count, 3) of standard normals of the gust sequence of
    ``gust_seed``: row 0 starts the gusts at their stationary distribution, row ``k`` drives the
    step to sample ``k`` (in the order the wind draws them block by block)."""
    return np.random.default_rng(gust_seed).standard_normal((int(count), 3))
