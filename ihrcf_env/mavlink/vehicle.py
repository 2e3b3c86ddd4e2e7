"""The vehicle's state machine: armed, mode (hold / offboard / land), setpoints and the failsafe.

Pure logic on decoded MAVLink messages and the vehicle's clock (s since boot, simulated): no
sockets, no env. :class:`Vehicle` takes each message the link receives (:meth:`Vehicle.handle`:
the answers to send back), says what to fly now (:meth:`Vehicle.command`: a NED velocity and yaw
rate) and what the heartbeat shows (:meth:`Vehicle.custom_mode`, :attr:`Vehicle.armed`).

Modes, in PX4's encoding (``custom_mode = main_mode << 16 | sub_mode << 24``): hold (AUTO 4,
LOITER 3: zero velocity, the autopilot holds its position), offboard (OFFBOARD 6: the last
``SET_POSITION_TARGET_LOCAL_NED`` velocity), land (AUTO 4, LAND 6: straight down at
:data:`LAND_SPEED`). A new episode starts disarmed in hold. The failsafe: in offboard, no valid
setpoint for :data:`SETPOINT_TIMEOUT` s of the vehicle's clock -> hold. A setpoint with NaN/inf or
beyond :data:`MAX_SETPOINT_SPEED` / :data:`MAX_SETPOINT_YAW_RATE` is rejected (counted, logged):
the vehicle holds in place until a valid one arrives.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.frames import wrap_angle
from ihrcf_env.mavlink import frames
from ihrcf_env.mavlink._pymavlink import dialect

#: PX4's main modes (``px4_custom_mode.h``) and AUTO's sub modes used here.
PX4_MAIN_AUTO = 4
PX4_MAIN_OFFBOARD = 6
PX4_SUB_AUTO_LOITER = 3
PX4_SUB_AUTO_LAND = 6
#: No valid offboard setpoint for this long (s, vehicle clock) -> hold (PX4's offboard loss).
SETPOINT_TIMEOUT = 0.5
#: Descent speed of the land mode (m/s).
LAND_SPEED = 0.3
#: A setpoint speed component above this (m/s) is refused as absurd (not saturated).
MAX_SETPOINT_SPEED = 20.0
#: A setpoint yaw rate above this (rad/s) is refused as absurd.
MAX_SETPOINT_YAW_RATE = 20.0
#: Gain (1/s) turning a yaw setpoint (rad) into a yaw rate.
YAW_GAIN = 2.0
#: Disarm this long (s, vehicle clock) after the episode ends (PX4 disarms after landing).
AUTO_DISARM = 1.0
#: ``param2`` of ``MAV_CMD_COMPONENT_ARM_DISARM`` that forces it.
FORCE_MAGIC = 21196

# POSITION_TARGET_TYPEMASK bits
_POS_IGNORE = 1 | 2 | 4
_VEL_IGNORE = 8 | 16 | 32
_ACC_IGNORE = 64 | 128 | 256
_YAW_IGNORE = 1024
_YAW_RATE_IGNORE = 2048
#: Event kinds a client can repeat at its message rate: logged sparingly.
_FLOODS = frozenset({"rejected", "unsupported", "command"})
#: Setpoint frames taken: local NED, and the heading-aligned body frames (PX4 rotates body
#: velocities by the yaw only).
_LOCAL_NED = 1
_BODY_FRAMES = (8, 9, 12)  # MAV_FRAME_BODY_NED, BODY_OFFSET_NED, BODY_FRD


class Mode(Enum):
    """Flight modes emulated, with their PX4 (main, sub) mode."""

    HOLD = (PX4_MAIN_AUTO, PX4_SUB_AUTO_LOITER)
    OFFBOARD = (PX4_MAIN_OFFBOARD, 0)
    LAND = (PX4_MAIN_AUTO, PX4_SUB_AUTO_LAND)


def custom_mode(mode: Mode) -> int:
    """The heartbeat's ``custom_mode`` of ``mode``: ``main << 16 | sub << 24``."""
    main, sub = mode.value
    return (main << 16) | (sub << 24)


def mode_of(main: int, sub: int) -> Mode | None:
    """The mode of a PX4 (main, sub) mode, or None for one not emulated (AUTO's sub mode 0 is
    taken as loiter, as PX4 does)."""
    if main == PX4_MAIN_OFFBOARD:
        return Mode.OFFBOARD
    if main == PX4_MAIN_AUTO and sub in (0, PX4_SUB_AUTO_LOITER):
        return Mode.HOLD
    if main == PX4_MAIN_AUTO and sub == PX4_SUB_AUTO_LAND:
        return Mode.LAND
    return None


@dataclass
class Setpoint:
    """A valid offboard setpoint: NED velocity (m/s), and a NED yaw rate (rad/s) or yaw (rad)."""

    velocity_ned: NDArray[np.float64]
    yaw_rate: float | None
    yaw: float | None
    time: float  # s, vehicle clock


class Vehicle:
    """The state machine (module docstring).

    Args:
        system_id, component_id: this vehicle's MAVLink ids (messages for others are ignored).
        log: where events go (rejected setpoints, failsafes, mode changes), one line each.
        streams: a callback ``(message_id, interval_us) -> MAV_RESULT`` taking
            ``MAV_CMD_SET_MESSAGE_INTERVAL``; None refuses it.
        can_send: which message ids ``MAV_CMD_REQUEST_MESSAGE`` may ask for.

    Attributes:
        armed, mode: as the heartbeat shows them.
        counts: events counted (``rejected_setpoints``, ``unsupported_setpoints``,
            ``unsupported_commands``, ``foreign``, ``failsafes``, ...).
        requested: message ids asked for by the messages handled since the caller last cleared it
            (``REQUEST_MESSAGE``, ``GET_HOME_POSITION``, ``REQUEST_AUTOPILOT_CAPABILITIES``).
    """

    def __init__(
        self,
        system_id: int = 1,
        component_id: int = 1,
        log: Callable[[str], None] | None = None,
        streams: Callable[[int, float], int] | None = None,
        can_send: frozenset[int] = frozenset(),
    ) -> None:
        self.system_id, self.component_id = system_id, component_id
        self._log = log or (lambda _text: None)
        self._streams = streams
        self._can_send = can_send
        self.counts: Counter[str] = Counter()
        self.requested: list[int] = []
        self._logged: Counter[str] = Counter()
        self.new_episode()

    # -- state ---------------------------------------------------------------------------------
    def new_episode(self) -> None:
        """Disarmed, in hold, in the air, no setpoint (a new episode's start)."""
        self.armed = False
        self.mode = Mode.HOLD
        self.landed = False
        self.setpoint: Setpoint | None = None
        self._last_setpoint_time = -math.inf
        self._landed_time: float | None = None

    def custom_mode(self) -> int:
        """The heartbeat's ``custom_mode``."""
        return custom_mode(self.mode)

    def episode_ended(self, now: float) -> None:
        """The episode ended at ``now`` (s; a touchdown, a crash or its step limit): the vehicle
        is down (``landed``), in hold, disarmed :data:`AUTO_DISARM` s later (:meth:`update`)."""
        self.landed = True
        self._landed_time = now
        self.mode = Mode.HOLD

    def update(self, now: float) -> None:
        """Timers at ``now`` (s, vehicle clock): the offboard failsafe, the disarm after landing."""
        if self.mode is Mode.OFFBOARD and now - self._last_setpoint_time > SETPOINT_TIMEOUT:
            self.mode = Mode.HOLD
            self.counts["failsafes"] += 1
            self._event("failsafe", f"failsafe: no offboard setpoint for {SETPOINT_TIMEOUT} s: hold")
        if self._landed_time is not None and self.armed and now - self._landed_time >= AUTO_DISARM:
            self.armed = False
            self._event("disarm", "episode over: disarmed")

    def command(self, yaw_ned: float) -> tuple[NDArray[np.float64], float]:
        """What to fly now: (NED velocity m/s, NED yaw rate rad/s), for a vehicle heading
        ``yaw_ned`` (rad). Zero unless armed and in the air."""
        if not self.armed or self.landed:
            return np.zeros(3), 0.0
        if self.mode is Mode.LAND:
            return np.array([0.0, 0.0, LAND_SPEED]), 0.0
        sp = self.setpoint
        if self.mode is not Mode.OFFBOARD or sp is None:
            return np.zeros(3), 0.0
        if sp.yaw_rate is not None:
            rate = sp.yaw_rate
        elif sp.yaw is not None:
            rate = YAW_GAIN * float(wrap_angle(sp.yaw - yaw_ned))
        else:
            rate = 0.0
        return sp.velocity_ned.copy(), rate

    # -- messages ------------------------------------------------------------------------------
    def handle(self, msg: Any, now: float, yaw_ned: float) -> list[Any]:
        """Take one decoded message at ``now`` (s); returns the messages to send back (command
        acks). A message for another system, or one this vehicle does not take, is ignored."""
        kind = msg.get_type()
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.system_id):
            self.counts["foreign"] += 1
            return []
        if kind == "SET_POSITION_TARGET_LOCAL_NED":
            self._setpoint(msg, now, yaw_ned)
            return []
        if kind in ("COMMAND_LONG", "COMMAND_INT"):
            comp = getattr(msg, "target_component", 0)
            if comp not in (0, self.component_id):
                self.counts["foreign"] += 1
                return []
            return [self._command(msg, now)]
        if kind == "SET_MODE":
            self._set_mode(int(msg.custom_mode) >> 16 & 0xFF, int(msg.custom_mode) >> 24 & 0xFF, now)
        return []

    def _command(self, msg: Any, now: float) -> Any:
        m = dialect()
        cmd = int(msg.command)
        p = [float(getattr(msg, f"param{i}")) for i in range(1, 5)]
        if cmd == m.MAV_CMD_COMPONENT_ARM_DISARM:
            result = self._arm(p[0], p[1])
        elif cmd == m.MAV_CMD_DO_SET_MODE:
            if not math.isfinite(p[1]) or not math.isfinite(p[2]):
                result = m.MAV_RESULT_DENIED
            else:
                result = self._set_mode(int(p[1]), int(p[2]), now)
        elif cmd == m.MAV_CMD_NAV_LAND:
            result = self._set_mode(PX4_MAIN_AUTO, PX4_SUB_AUTO_LAND, now)
        elif cmd == m.MAV_CMD_SET_MESSAGE_INTERVAL:
            ok = self._streams is not None and math.isfinite(p[0]) and math.isfinite(p[1])
            result = self._streams(int(p[0]), p[1]) if ok else m.MAV_RESULT_DENIED  # type: ignore[misc]
        elif cmd in (
            m.MAV_CMD_REQUEST_MESSAGE,
            m.MAV_CMD_GET_HOME_POSITION,
            m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
        ):
            wanted = {
                m.MAV_CMD_GET_HOME_POSITION: m.MAVLINK_MSG_ID_HOME_POSITION,
                m.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: m.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            }.get(cmd, int(p[0]) if math.isfinite(p[0]) else -1)
            if wanted in self._can_send:
                self.requested.append(wanted)
                result = m.MAV_RESULT_ACCEPTED
            else:
                result = m.MAV_RESULT_UNSUPPORTED
        else:
            self.counts["unsupported_commands"] += 1
            self._event("command", f"command {cmd} not supported")
            result = m.MAV_RESULT_UNSUPPORTED
        return m.MAVLink_command_ack_message(cmd, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())

    def _arm(self, arm: float, force: float) -> int:
        m = dialect()
        if arm == 1.0:
            if self.landed:
                self._event("arm", "arming refused: the episode is over (landed)")
                return m.MAV_RESULT_TEMPORARILY_REJECTED
            if not self.armed:
                self.armed = True
                self._event("arm", "armed")
            return m.MAV_RESULT_ACCEPTED
        if arm == 0.0:
            if self.armed and not self.landed:
                # PX4 refuses to disarm in the air unless forced; cutting the motors in flight
                # is not emulated, so a forced disarm is refused too
                why = "forced disarm in flight is not emulated" if force == FORCE_MAGIC else "in the air"
                self._event("arm", f"disarm refused: {why}")
                return m.MAV_RESULT_DENIED
            self.armed = False
            return m.MAV_RESULT_ACCEPTED
        return m.MAV_RESULT_DENIED

    def _set_mode(self, main: int, sub: int, now: float) -> int:
        m = dialect()
        mode = mode_of(main, sub)
        if mode is None:
            self._event("mode", f"mode {main}/{sub} not emulated")
            return m.MAV_RESULT_UNSUPPORTED
        if self.landed and mode is not Mode.HOLD:
            return m.MAV_RESULT_TEMPORARILY_REJECTED
        if mode is Mode.OFFBOARD and now - self._last_setpoint_time > SETPOINT_TIMEOUT:
            self._event("mode", "offboard refused: no setpoint in the last 0.5 s")
            return m.MAV_RESULT_TEMPORARILY_REJECTED
        if mode is Mode.LAND and not self.armed:
            return m.MAV_RESULT_TEMPORARILY_REJECTED
        if mode is not self.mode:
            self.mode = mode
            self._event("mode", f"mode {mode.name.lower()}")
        return m.MAV_RESULT_ACCEPTED

    def _setpoint(self, msg: Any, now: float, yaw_ned: float) -> None:
        mask = int(msg.type_mask)
        frame = int(msg.coordinate_frame)
        if (mask & _POS_IGNORE) != _POS_IGNORE or (mask & _VEL_IGNORE) or (mask & _ACC_IGNORE) != _ACC_IGNORE:
            self.counts["unsupported_setpoints"] += 1
            self._event("unsupported", "only velocity setpoints (with yaw or yaw rate) are emulated")
            return
        if frame != _LOCAL_NED and frame not in _BODY_FRAMES:
            self.counts["unsupported_setpoints"] += 1
            self._event("unsupported", f"setpoint frame {frame} not emulated (LOCAL_NED, BODY_NED, BODY_FRD)")
            return
        v = np.array([msg.vx, msg.vy, msg.vz], dtype=np.float64)
        yaw_rate = None if mask & _YAW_RATE_IGNORE else float(msg.yaw_rate)
        yaw = None if (mask & _YAW_IGNORE) or yaw_rate is not None else float(msg.yaw)
        used = [*v.tolist(), *(x for x in (yaw_rate, yaw) if x is not None)]
        bad = not all(math.isfinite(x) for x in used)
        if not bad:
            bad = bool(np.max(np.abs(v)) > MAX_SETPOINT_SPEED) or (
                yaw_rate is not None and abs(yaw_rate) > MAX_SETPOINT_YAW_RATE
            )
        if bad:
            self.counts["rejected_setpoints"] += 1
            self._event(
                "rejected",
                f"setpoint rejected (NaN/inf, or beyond {MAX_SETPOINT_SPEED:g} m/s or "
                f"{MAX_SETPOINT_YAW_RATE:g} rad/s): v={v.tolist()}, yaw_rate={yaw_rate}, yaw={yaw}; holding",
            )
            self.setpoint = Setpoint(np.zeros(3), 0.0, None, now)  # hold in place; not a live stream
            return
        if frame != _LOCAL_NED:
            v = frames.body_velocity_to_ned(v, yaw_ned)
        self.setpoint = Setpoint(v, yaw_rate, yaw, now)
        self._last_setpoint_time = now

    def _event(self, kind: str, text: str) -> None:
        """Log ``text``; of the kinds a client can flood (:data:`_FLOODS`), the first 5 events
        and then every 100th."""
        self._logged[kind] += 1
        n = self._logged[kind]
        if kind not in _FLOODS or n <= 5:
            self._log(text)
        elif n % 100 == 0:
            self._log(f"{text} (x{n})")


__all__ = [
    "AUTO_DISARM",
    "FORCE_MAGIC",
    "LAND_SPEED",
    "MAX_SETPOINT_SPEED",
    "MAX_SETPOINT_YAW_RATE",
    "SETPOINT_TIMEOUT",
    "Mode",
    "Setpoint",
    "Vehicle",
    "custom_mode",
    "mode_of",
]
