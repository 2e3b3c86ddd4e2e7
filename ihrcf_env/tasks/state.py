"""The state the task rules read: a snapshot of drone and deck, and the touchdown of a step.

Both are NamedTuples of arrays (float64 unless said otherwise), so a batch is the same structure
with a leading axis on every field, and in JAX they are pytrees (``jax.jit``/``vmap`` take them
as they are). World frame: x, y horizontal, z up (m); rotation matrices map the body's (or
deck's) axes into the world (columns = the body's axes in world coordinates).
"""

from __future__ import annotations

from typing import Any, NamedTuple

__all__ = [
    "CONTACT_NAMES",
    "NO_CONTACT",
    "CONTACT_DECK",
    "CONTACT_GROUND",
    "CONTACT_BASE",
    "TaskState",
    "TouchdownState",
]

#: Contact codes of :attr:`TouchdownState.contact` (index into :data:`CONTACT_NAMES`).
NO_CONTACT, CONTACT_DECK, CONTACT_GROUND, CONTACT_BASE = 0, 1, 2, 3
#: Names of the contact codes: what the drone touched (``""``: nothing this step).
CONTACT_NAMES: tuple[str, ...] = ("", "deck", "ground", "base")


class TaskState(NamedTuple):
    """Ground truth of drone and deck at one instant (world frame).

    Shapes ``(..., 3)`` and ``(..., 3, 3)`` with any leading batch axes (the same on every field).
    """

    #: drone centre of mass (m)
    drone_position: Any
    #: drone attitude, world-from-body rotation matrix (body FLU: x forward, y left, z up)
    drone_rotation: Any
    #: drone velocity (m/s)
    drone_velocity: Any
    #: deck frame origin: the tag centre on the deck's top surface (m)
    deck_position: Any
    #: deck attitude, world-from-deck rotation matrix (deck z = the top surface's normal)
    deck_rotation: Any
    #: velocity of the deck's material point under the drone's centre (m/s)
    deck_point_velocity: Any


class TouchdownState(NamedTuple):
    """The first contact of the drone during a control step, or none.

    Each field has the batch shape of the :class:`TaskState` (scalars per drone). Without a
    contact (``contact == NO_CONTACT``) the other fields are ignored by the rules.
    """

    #: contact code (integer): :data:`NO_CONTACT`, :data:`CONTACT_DECK`, :data:`CONTACT_GROUND`
    #: or :data:`CONTACT_BASE`
    contact: Any
    #: approach speed along the deck normal, drone minus deck point (m/s; negative = closing)
    relative_vertical_speed: Any
    #: angle between the drone's z axis and the deck normal (rad)
    relative_tilt: Any
    #: True if the drone's centre projects inside the deck's top surface (bool)
    on_deck: Any
