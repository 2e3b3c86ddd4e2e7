"""Touchdown and outcome classification, success and termination of the deck-landing tasks.

Pure functions of :class:`~ihrcf_env.tasks.state.TaskState` / :class:`~ihrcf_env.tasks.state.
TouchdownState` arrays, written against the inputs' array namespace (numpy or ``jax.numpy``),
elementwise over any leading batch axes, without Python branching on array values. The outcome
of a step is one integer code (:data:`OUTCOME_NAMES`): 0 flying, 1 success, higher a crash and
its cause.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from ihrcf_env.tasks._math import dot3, hypot, namespace
from ihrcf_env.tasks.state import CONTACT_BASE, CONTACT_GROUND, NO_CONTACT, TaskState, TouchdownState

__all__ = [
    "ArenaLike",
    "ThresholdsLike",
    "FLYING",
    "SUCCESS",
    "CRASH_GROUND",
    "CRASH_BASE",
    "CRASH_OFF_DECK",
    "CRASH_SPEED",
    "CRASH_TOUCHDOWN_TILT",
    "CRASH_OFF_TAG",
    "CRASH_TILT",
    "CRASH_ARENA",
    "OUTCOME_NAMES",
    "classify",
    "describe",
    "is_crash",
    "is_success",
    "is_terminal",
    "outcome_name",
    "relative_tilt",
    "tag_offset",
    "tilt",
    "touchdown_state",
]

#: Outcome codes (index into :data:`OUTCOME_NAMES`).
FLYING, SUCCESS = 0, 1
#: Crash codes: touched the ground, touched the platform's base, touched down outside the deck,
#: too fast at touchdown, too tilted at touchdown, touched down too far from the tag (landing
#: tasks), tilted over the crash limit in flight, left the arena.
CRASH_GROUND, CRASH_BASE, CRASH_OFF_DECK, CRASH_SPEED = 2, 3, 4, 5
CRASH_TOUCHDOWN_TILT, CRASH_OFF_TAG, CRASH_TILT, CRASH_ARENA = 6, 7, 8, 9
#: Names of the outcome codes.
OUTCOME_NAMES: tuple[str, ...] = (
    "flying",
    "success",
    "hit_ground",
    "hit_base",
    "off_deck",
    "touchdown_speed",
    "touchdown_tilt",
    "off_tag",
    "tilt",
    "arena",
)


class ThresholdsLike(Protocol):
    """The outcome limits (:class:`~ihrcf_env.envs.task_config.Thresholds`)."""

    @property
    def success_speed(self) -> float: ...  # m/s
    @property
    def success_tilt(self) -> float: ...  # rad
    @property
    def crash_tilt(self) -> float: ...  # rad


class ArenaLike(Protocol):
    """The arena's bounds (:class:`~ihrcf_env.envs.task_config.Arena`)."""

    @property
    def half_width(self) -> float: ...  # m, world x and y
    @property
    def ceiling(self) -> float: ...  # m, world z


def outcome_name(code: int) -> str:
    """``"flying"``, ``"success"`` or ``"crash"`` for an outcome code (a Python int)."""
    return "flying" if code == FLYING else ("success" if code == SUCCESS else "crash")


def describe(
    code: int,
    touchdown: TouchdownState,
    state: TaskState,
    thresholds: ThresholdsLike,
    success_radius: float | None = None,
) -> str:
    """A sentence saying why one episode crashed (``""`` unless ``code`` is a crash), with the
    figures of the failed check; ``touchdown`` and ``state`` of one drone (0-d fields)."""
    speed = abs(float(touchdown.relative_vertical_speed))
    texts = {
        CRASH_GROUND: lambda: "hit the ground",
        CRASH_BASE: lambda: "hit the base",
        CRASH_OFF_DECK: lambda: "touched down outside the deck",
        CRASH_SPEED: lambda: f"vertical speed {speed:.2f} m/s at touchdown",
        CRASH_TOUCHDOWN_TILT: lambda: (
            f"tilt {math.degrees(float(touchdown.relative_tilt)):.1f} deg at touchdown"
        ),
        CRASH_OFF_TAG: lambda: (
            f"touched down {float(tag_offset(state)):.2f} m from the tag centre (> {success_radius:g} m)"
        ),
        CRASH_TILT: lambda: f"tilt over {math.degrees(thresholds.crash_tilt):.0f} deg",
        CRASH_ARENA: lambda: "left the arena",
    }
    text = texts.get(int(code))
    return text() if text is not None else ""


def is_terminal(code: Any) -> Any:
    """True where the outcome ends the episode (a success or a crash)."""
    return code != FLYING


def is_success(code: Any) -> Any:
    """True where the outcome is a success."""
    return code == SUCCESS


def is_crash(code: Any) -> Any:
    """True where the outcome is a crash."""
    return code > SUCCESS


def relative_tilt(drone_rotation: Any, deck_rotation: Any) -> Any:
    """Angle (rad, in [0, pi]) between the drone's z axis and the deck normal (``(..., 3, 3)``
    world-from-body and world-from-deck rotations)."""
    xp = namespace(drone_rotation, deck_rotation)
    c = dot3(drone_rotation[..., :, 2], deck_rotation[..., :, 2])
    return xp.acos(xp.maximum(-1.0, xp.minimum(1.0, c)))


def tilt(drone_rotation: Any) -> Any:
    """Angle (rad) between the drone's z axis and the world's vertical."""
    xp = namespace(drone_rotation)
    return xp.acos(xp.maximum(-1.0, xp.minimum(1.0, drone_rotation[..., 2, 2])))


def tag_offset(state: TaskState) -> Any:
    """Horizontal distance (m) of the drone's centre from the tag centre (the deck origin)."""
    xp = namespace(state.drone_position, state.deck_position)
    d = state.drone_position - state.deck_position
    return hypot(xp, d[..., 0], d[..., 1])


def touchdown_state(
    state: TaskState, contact: Any, approach_velocity: Any, deck_half_extent: float
) -> TouchdownState:
    """The touchdown record of a contact (code ``contact``) in ``state``, the drone having approached
    at ``approach_velocity`` (world, m/s: its velocity before the contact solver changed it);
    ``deck_half_extent`` (m) is half the side of the deck's square top surface."""
    xp = namespace(state.drone_position, approach_velocity)
    R = state.deck_rotation
    d = state.drone_position - state.deck_position
    local_x = R[..., 0, 0] * d[..., 0] + R[..., 1, 0] * d[..., 1] + R[..., 2, 0] * d[..., 2]
    local_y = R[..., 0, 1] * d[..., 0] + R[..., 1, 1] * d[..., 1] + R[..., 2, 1] * d[..., 2]
    v_rel = approach_velocity - state.deck_point_velocity
    return TouchdownState(
        contact=xp.asarray(contact),
        relative_vertical_speed=dot3(v_rel, R[..., :, 2]),
        relative_tilt=relative_tilt(state.drone_rotation, R),
        on_deck=(xp.abs(local_x) <= deck_half_extent) & (xp.abs(local_y) <= deck_half_extent),
    )


def classify(
    state: TaskState,
    touchdown: TouchdownState,
    thresholds: ThresholdsLike,
    arena: ArenaLike,
    success_radius: float | None = None,
    offset: Any = None,
) -> Any:
    """The outcome code of a step ending in ``state`` with ``touchdown`` (an integer array of the
    batch shape).

    A touchdown ends the episode: a success if on the deck's top surface with
    ``|relative_vertical_speed| < success_speed`` and ``relative_tilt < success_tilt`` (and, for
    the landing tasks, ``success_radius`` given: the drone's centre within it of the tag centre,
    horizontally), a crash otherwise (the first failed check, in that order, names it). Without a
    touchdown, a tilt over ``crash_tilt`` or leaving the arena (``|x|`` or ``|y| > half_width``,
    ``z > ceiling``) is a crash; otherwise the drone is flying. ``offset``: :func:`tag_offset` of
    ``state`` if already computed.
    """
    xp = namespace(state.drone_position, touchdown.contact)
    contact = touchdown.contact
    speed = xp.abs(touchdown.relative_vertical_speed)
    landed = xp.where(
        contact == CONTACT_GROUND,
        CRASH_GROUND,
        xp.where(
            contact == CONTACT_BASE,
            CRASH_BASE,
            xp.where(
                xp.logical_not(touchdown.on_deck),
                CRASH_OFF_DECK,
                xp.where(
                    speed >= thresholds.success_speed,
                    CRASH_SPEED,
                    xp.where(
                        touchdown.relative_tilt >= thresholds.success_tilt, CRASH_TOUCHDOWN_TILT, SUCCESS
                    ),
                ),
            ),
        ),
    )
    if success_radius is not None:
        offset = tag_offset(state) if offset is None else offset
        landed = xp.where((landed == SUCCESS) & (offset > success_radius), CRASH_OFF_TAG, landed)
    pos = state.drone_position
    outside = (
        (xp.abs(pos[..., 0]) > arena.half_width)
        | (xp.abs(pos[..., 1]) > arena.half_width)
        | (pos[..., 2] > arena.ceiling)
    )
    flying = xp.where(
        tilt(state.drone_rotation) > thresholds.crash_tilt,
        CRASH_TILT,
        xp.where(outside, CRASH_ARENA, FLYING),
    )
    return xp.where(contact == NO_CONTACT, flying, landed)
