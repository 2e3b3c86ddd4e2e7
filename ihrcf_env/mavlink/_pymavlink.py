"""The one place pymavlink is imported: MAVLink 2 and the ``common`` dialect, chosen before use.

pymavlink picks its wire protocol from the ``MAVLINK20`` environment variable when a dialect is
loaded; this module sets it and loads ``common`` once, so every connection and encoder of
:mod:`ihrcf_env.mavlink` (and the tests) speaks MAVLink 2. Without pymavlink installed,
:func:`import_pymavlink` raises :class:`MavlinkMissingError` saying how to install it.
"""

from __future__ import annotations

import os
from types import ModuleType
from typing import Any

#: How to install what the MAVLink face needs.
INSTALL_HINT = (
    'the MAVLink vehicle needs pymavlink (and MAVSDK for the example): pip install "ihrcf-env[mavlink]"'
)


class MavlinkMissingError(ImportError):
    """pymavlink is not installed (the ``[mavlink]`` extra)."""


_MAVUTIL: ModuleType | None = None


def import_pymavlink() -> ModuleType:
    """pymavlink's ``mavutil`` with MAVLink 2 and the ``common`` dialect loaded (its
    ``mavutil.mavlink`` is the dialect module); :class:`MavlinkMissingError` without pymavlink."""
    global _MAVUTIL
    if _MAVUTIL is None:
        os.environ["MAVLINK20"] = "1"  # read by set_dialect below (and by pymavlink's first import)
        try:
            from pymavlink import mavutil
        except ImportError as e:
            raise MavlinkMissingError(f"{INSTALL_HINT} ({e})") from e
        mavutil.set_dialect("common")
        if getattr(mavutil.mavlink, "WIRE_PROTOCOL_VERSION", "") != "2.0":
            raise MavlinkMissingError("pymavlink did not load MAVLink 2 (the MAVLINK20 environment variable)")
        _MAVUTIL = mavutil
    return _MAVUTIL


def dialect() -> Any:
    """The ``common`` MAVLink 2 dialect module (constants, message classes)."""
    return import_pymavlink().mavlink


__all__ = ["INSTALL_HINT", "MavlinkMissingError", "dialect", "import_pymavlink"]
