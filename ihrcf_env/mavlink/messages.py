"""The message table: what the vehicle sends, how often, in which frame; and its encoders.

Rates are on the vehicle's (simulated) clock, at most one message of a kind per control step
(``control_hz``, 20 Hz by default), except ``HEARTBEAT``, sent once per second of wall-clock time
(a link's liveness is judged on the client's clock). ``MAV_CMD_SET_MESSAGE_INTERVAL`` changes a
streamed message's rate (:meth:`Streams.set_interval`). Every encoder takes a
:class:`VehicleSample` (the env's ground truth in its own frames) and converts with
:mod:`ihrcf_env.mavlink.frames`.
"""

from __future__ import annotations

import math
import time
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ihrcf_env._version import __version__
from ihrcf_env.mavlink import frames
from ihrcf_env.mavlink._pymavlink import dialect


class MessageSpec(NamedTuple):
    """One row of the message table (``docs/mavlink.md`` shows the same)."""

    name: str
    msg_id: int
    rate: str
    frame: str
    fields: str


#: Every message the vehicle sends.
MESSAGE_TABLE: tuple[MessageSpec, ...] = (
    MessageSpec(
        "HEARTBEAT",
        0,
        "1 Hz (wall clock) and at each change of armed state or mode",
        "-",
        "type QUADROTOR, autopilot PX4, base_mode "
        "CUSTOM_MODE_ENABLED + SAFETY_ARMED, custom_mode (main << 16) + (sub << 24), system_status",
    ),
    MessageSpec("SYS_STATUS", 1, "1 Hz", "-", "sensors present/enabled/healthy, battery unknown"),
    MessageSpec("SYSTEM_TIME", 2, "1 Hz", "-", "time_unix_usec (wall), time_boot_ms (simulated)"),
    MessageSpec(
        "ATTITUDE", 30, "control rate", "NED from FRD", "roll, pitch, yaw (rad), FRD body rates (rad/s)"
    ),
    MessageSpec(
        "ATTITUDE_QUATERNION", 31, "control rate", "NED from FRD", "q1..q4 (w, x, y, z), FRD body rates"
    ),
    MessageSpec("LOCAL_POSITION_NED", 32, "control rate", "LOCAL_NED", "x, y, z (m), vx, vy, vz (m/s)"),
    MessageSpec("COMMAND_ACK", 77, "per command", "-", "command, result, target_system, target_component"),
    MessageSpec("TIMESYNC", 111, "per request", "-", "tc1 (vehicle clock, ns), ts1 (the request's)"),
    MessageSpec(
        "DISTANCE_SENSOR",
        132,
        "control rate, one per ToF beam",
        "body, downward (PITCH_270)",
        "id 0..3, current/min/max_distance (cm; UINT16_MAX invalid), signal_quality",
    ),
    MessageSpec(
        "AUTOPILOT_VERSION",
        148,
        "per request",
        "-",
        "capabilities MAVLINK2, COMMAND_INT, "
        "SET_POSITION_TARGET_LOCAL_NED; flight_sw_version (the package version)",
    ),
    MessageSpec(
        "LANDING_TARGET",
        149,
        "camera rate, valid estimates only",
        "LOCAL_NED (px4) / BODY_FRD (ardupilot)",
        "time_usec (the frame's capture), x, y, z, q, distance, angle_x, angle_y, "
        "size_x, size_y, position_valid 1, type VISION_FIDUCIAL, target_num (tag id)",
    ),
    MessageSpec(
        "HOME_POSITION",
        242,
        "0.5 Hz and per request",
        "LOCAL_NED",
        "x, y, z (the drone at arming), latitude/longitude/altitude 0 (no global position)",
    ),
    MessageSpec(
        "EXTENDED_SYS_STATE",
        245,
        "5 Hz",
        "-",
        "landed_state IN_AIR / LANDING / ON_GROUND (UNDEFINED after a crash off the deck)",
    ),
    MessageSpec(
        "STATUSTEXT",
        253,
        "per event",
        "-",
        "mode changes, failsafes, rejected setpoints, the episode's outcome",
    ),
)

#: Default rates (Hz, vehicle clock) of the streamed messages; at most the control rate.
DEFAULT_HZ: dict[str, float] = {
    "SYS_STATUS": 1.0,
    "SYSTEM_TIME": 1.0,
    "ATTITUDE": 50.0,
    "ATTITUDE_QUATERNION": 50.0,
    "LOCAL_POSITION_NED": 50.0,
    "DISTANCE_SENSOR": 50.0,
    "HOME_POSITION": 0.5,
    "EXTENDED_SYS_STATE": 5.0,
}
#: Message ids a client may ask for (``MAV_CMD_REQUEST_MESSAGE``).
ON_REQUEST: frozenset[int] = frozenset({148, 242, *(s.msg_id for s in MESSAGE_TABLE if s.name in DEFAULT_HZ)})

_IDS = {s.name: s.msg_id for s in MESSAGE_TABLE}
_NAMES = {v: k for k, v in _IDS.items()}


def message_table_markdown() -> str:
    """:data:`MESSAGE_TABLE` as the Markdown table of ``docs/mavlink.md``."""
    rows = ["| message | id | rate | frame | fields |", "|---|---|---|---|---|"]
    rows += [f"| `{s.name}` | {s.msg_id} | {s.rate} | {s.frame} | {s.fields} |" for s in MESSAGE_TABLE]
    return "\n".join(rows)


class Streams:
    """When each streamed message is due, on the vehicle's clock (s), given the control period
    ``dt`` (s): at most one per step."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.interval: dict[str, float | None] = {
            k: self._quantised(1.0 / hz) for k, hz in DEFAULT_HZ.items()
        }
        self._next: dict[str, float] = dict.fromkeys(DEFAULT_HZ, 0.0)

    def _quantised(self, interval: float) -> float:
        return max(interval, self.dt)

    def due(self, now: float) -> list[str]:
        """The messages due at ``now`` (s); each then waits its interval."""
        out = []
        eps = 1e-9
        for name, interval in self.interval.items():
            if interval is None or now + eps < self._next[name]:
                continue
            out.append(name)
            nxt = self._next[name] + interval
            self._next[name] = nxt if nxt > now + eps else now + interval
        return out

    def set_interval(self, msg_id: int, interval_us: float) -> int:
        """``MAV_CMD_SET_MESSAGE_INTERVAL``: ``interval_us`` > 0 sets the interval (at least the
        control period), 0 the default, -1 stops the stream; returns the ``MAV_RESULT``."""
        m = dialect()
        name = _NAMES.get(msg_id)
        if name not in DEFAULT_HZ:
            return m.MAV_RESULT_UNSUPPORTED
        if interval_us == -1:
            self.interval[name] = None
        elif interval_us == 0:
            self.interval[name] = self._quantised(1.0 / DEFAULT_HZ[name])
        elif interval_us > 0:
            self.interval[name] = self._quantised(interval_us * 1e-6)
        else:
            return m.MAV_RESULT_DENIED
        return m.MAV_RESULT_ACCEPTED


class VehicleSample(NamedTuple):
    """What the encoders read, in the env's frames: the vehicle clock ``time`` (s since boot),
    position and velocity (world, m, m/s), ``quaternion`` (x, y, z, w, world from body), body
    rates (FLU, rad/s), ToF ``ranges`` (m) with their ``ranges_valid`` flags, ``max_range`` (m),
    the MAVLink ``landed_state`` and the home position (world, m)."""

    time: float
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    quaternion: NDArray[np.float64]
    rates: NDArray[np.float64]
    ranges: NDArray[np.float64]
    ranges_valid: NDArray[np.bool_]
    max_range: float
    landed_state: int
    home: NDArray[np.float64]


def boot_ms(t: float) -> int:
    """Vehicle time (s) as ``time_boot_ms`` (uint32, wraps after ~49 days)."""
    return int(round(t * 1e3)) & 0xFFFFFFFF


def usec(t: float) -> int:
    """Vehicle time (s) as microseconds since boot."""
    return int(round(t * 1e6))


def heartbeat(armed: bool, custom_mode: int) -> Any:
    """``HEARTBEAT`` of a PX4-style quadrotor."""
    m = dialect()
    base = m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (m.MAV_MODE_FLAG_SAFETY_ARMED if armed else 0)
    status = m.MAV_STATE_ACTIVE if armed else m.MAV_STATE_STANDBY
    return m.MAVLink_heartbeat_message(
        m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_PX4, base, custom_mode, status, 3
    )


def stream(name: str, s: VehicleSample) -> list[Any]:
    """The messages of the stream ``name`` (a key of :data:`DEFAULT_HZ`) for the sample ``s``."""
    m = dialect()
    t = boot_ms(s.time)
    if name == "ATTITUDE":
        a = frames.attitude_to_mavlink(s.quaternion, s.rates)
        return [m.MAVLink_attitude_message(t, *a)]
    if name == "ATTITUDE_QUATERNION":
        q = frames.quat_to_mavlink(s.quaternion)
        a = frames.attitude_to_mavlink(s.quaternion, s.rates)
        return [m.MAVLink_attitude_quaternion_message(t, *q.tolist(), a.rollspeed, a.pitchspeed, a.yawspeed)]
    if name == "LOCAL_POSITION_NED":
        p, v = frames.world_to_ned(s.position), frames.world_to_ned(s.velocity)
        return [m.MAVLink_local_position_ned_message(t, *p.tolist(), *v.tolist())]
    if name == "EXTENDED_SYS_STATE":
        return [m.MAVLink_extended_sys_state_message(m.MAV_VTOL_STATE_UNDEFINED, s.landed_state)]
    if name == "SYS_STATUS":
        sensors = (
            m.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | m.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | m.MAV_SYS_STATUS_SENSOR_LASER_POSITION
            | m.MAV_SYS_STATUS_SENSOR_VISION_POSITION
            | m.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
            | m.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
            | m.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
            | m.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
            | m.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        )
        return [m.MAVLink_sys_status_message(sensors, sensors, sensors, 0, 0xFFFF, -1, -1, 0, 0, 0, 0, 0, 0)]
    if name == "SYSTEM_TIME":
        return [m.MAVLink_system_time_message(int(time.time() * 1e6), t)]
    if name == "DISTANCE_SENSOR":
        top = int(round(s.max_range * 100))
        out = []
        for i, (r, ok) in enumerate(zip(s.ranges.tolist(), s.ranges_valid.tolist(), strict=True)):
            cm = min(int(round(r * 100)), top) if ok and math.isfinite(r) else 0xFFFF
            out.append(
                m.MAVLink_distance_sensor_message(
                    t,
                    0,
                    top,
                    cm,
                    m.MAV_DISTANCE_SENSOR_LASER,
                    i,
                    m.MAV_SENSOR_ROTATION_PITCH_270,
                    255,
                    0.0,
                    0.0,
                    (0.0, 0.0, 0.0, 0.0),
                    100 if ok else 1,
                )
            )
        return out
    if name == "HOME_POSITION":
        return [home_position(s)]
    raise KeyError(f"no stream {name!r}")


def home_position(s: VehicleSample) -> Any:
    """``HOME_POSITION``: the local NED home (no global position: latitude/longitude/altitude 0)."""
    m = dialect()
    h = frames.world_to_ned(s.home)
    return m.MAVLink_home_position_message(
        0, 0, 0, *h.tolist(), (1.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0, usec(s.time)
    )


def autopilot_version() -> Any:
    """``AUTOPILOT_VERSION``: the capabilities emulated and the package's version."""
    m = dialect()
    caps = (
        m.MAV_PROTOCOL_CAPABILITY_MAVLINK2
        | m.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        | m.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    )
    parts = [int(x) if x.isdigit() else 0 for x in __version__.split(".")[:3]] + [0, 0, 0]
    version = (parts[0] << 24) | (parts[1] << 16) | (parts[2] << 8) | 0xFF  # 0xFF: a release
    zeros = [0] * 8
    return m.MAVLink_autopilot_version_message(caps, version, 0, 0, 0, zeros, zeros, zeros, 0, 0, 0)


def timesync_reply(msg: Any, now: float) -> Any | None:
    """The answer to a ``TIMESYNC`` request (``tc1`` 0), None for anything else."""
    if int(msg.tc1) != 0:
        return None
    return dialect().MAVLink_timesync_message(int(round(now * 1e9)), int(msg.ts1))


def statustext(text: str, severity: int | None = None) -> Any:
    """``STATUSTEXT`` (50 characters at most; longer text is cut)."""
    m = dialect()
    sev = m.MAV_SEVERITY_INFO if severity is None else severity
    return m.MAVLink_statustext_message(sev, text.encode("ascii", "replace")[:50])


__all__ = [
    "DEFAULT_HZ",
    "MESSAGE_TABLE",
    "ON_REQUEST",
    "MessageSpec",
    "Streams",
    "VehicleSample",
    "autopilot_version",
    "boot_ms",
    "heartbeat",
    "home_position",
    "message_table_markdown",
    "statustext",
    "stream",
    "timesync_reply",
    "usec",
]
