"""The simulator as a MAVLink 2 vehicle (the optional ``[mavlink]`` extra: ``pymavlink``).

A landing or hover env flown behind UDP links as a PX4-style quadrotor: heartbeat, arming, the
hold / offboard / land modes, ``SET_POSITION_TARGET_LOCAL_NED`` velocity setpoints into the env's
velocity autopilot, telemetry from the env's ground truth, and the deck-pose estimate as
``LANDING_TARGET``, so a MAVSDK or pymavlink landing script runs against it unchanged. The
command line is ``ihrcf-mavlink`` (``python -m ihrcf_env.mavlink``); the reference (message
table, profiles, ports, what is emulated) is ``docs/mavlink.md``.

Rooms: :mod:`~ihrcf_env.mavlink.frames` (env world/body <-> NED/FRD, pure functions),
:mod:`~ihrcf_env.mavlink.messages` (the message table, rates, encoders),
:mod:`~ihrcf_env.mavlink.target` (``LANDING_TARGET`` profiles), :mod:`~ihrcf_env.mavlink.vehicle`
(the state machine), :mod:`~ihrcf_env.mavlink.link` (UDP links), :mod:`~ihrcf_env.mavlink.loop`
(the simulated clock and the env), :mod:`~ihrcf_env.mavlink.options` (its checked options) and
:mod:`~ihrcf_env.mavlink.report` (what a run did). Only :mod:`~ihrcf_env.mavlink.frames`
imports without pymavlink.
"""

from typing import Any

from ihrcf_env.mavlink._pymavlink import INSTALL_HINT, MavlinkMissingError

__all__ = ["INSTALL_HINT", "MavlinkMissingError", "MavlinkVehicle", "VehicleOptions", "run_vehicle"]


def __getattr__(name: str) -> Any:
    if name in ("MavlinkVehicle", "VehicleOptions", "run_vehicle"):  # imported when asked for
        from ihrcf_env.mavlink import loop

        return getattr(loop, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
