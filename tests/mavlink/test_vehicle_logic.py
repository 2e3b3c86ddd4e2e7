"""The vehicle's state machine and message table without sockets or an env."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ihrcf_env.mavlink import messages
from ihrcf_env.mavlink._pymavlink import dialect
from ihrcf_env.mavlink.vehicle import (
    MAX_SETPOINT_SPEED,
    SETPOINT_TIMEOUT,
    Mode,
    Vehicle,
    custom_mode,
)

m = dialect()
_VEL = 0b010111000111  # velocity + yaw rate used; position, acceleration and yaw ignored
_GCS = m.MAVLink(None, srcSystem=245, srcComponent=190)


def _decoded(msg: Any) -> Any:
    """``msg`` as the vehicle receives it: packed by a ground station and decoded."""
    return m.MAVLink(None).decode(bytearray(msg.pack(_GCS)))


def _command(cmd: int, *params: float, target: int = 1) -> Any:
    p = [*params, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0][:7]
    return _decoded(m.MAVLink_command_long_message(target, 1, cmd, 0, *p))


def _setpoint(
    vx: float, vy: float, vz: float, yaw_rate: float = 0.0, frame: int = 1, mask: int = _VEL
) -> Any:
    return _decoded(
        m.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, frame, mask, 0, 0, 0, vx, vy, vz, 0, 0, 0, 0, yaw_rate
        )
    )


def _result(v: Vehicle, msg: Any, now: float = 0.0) -> int:
    (ack,) = v.handle(msg, now, 0.0)
    assert ack.get_type() == "COMMAND_ACK"
    assert (ack.target_system, ack.target_component) == (245, 190)
    return int(ack.result)


def _armed_offboard(v: Vehicle, now: float = 0.0) -> None:
    assert _result(v, _command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0), now) == m.MAV_RESULT_ACCEPTED
    v.handle(_setpoint(0.5, 0.0, 0.0), now, 0.0)
    assert _result(v, _command(m.MAV_CMD_DO_SET_MODE, 1.0, 6.0, 0.0), now) == m.MAV_RESULT_ACCEPTED
    assert v.mode is Mode.OFFBOARD


def test_custom_modes_follow_px4s_encoding() -> None:
    assert custom_mode(Mode.OFFBOARD) == 6 << 16
    assert custom_mode(Mode.HOLD) == (4 << 16) | (3 << 24)
    assert custom_mode(Mode.LAND) == (4 << 16) | (6 << 24)
    v = Vehicle()
    assert (v.armed, v.mode) == (False, Mode.HOLD)


def test_arm_offboard_and_the_velocity_flown() -> None:
    v = Vehicle()
    _armed_offboard(v)
    vel, rate = v.command(0.0)
    np.testing.assert_allclose(vel, [0.5, 0.0, 0.0])
    assert rate == 0.0
    # a body-frame setpoint turns with the heading (east: forward is east)
    v.handle(_setpoint(1.0, 0.0, 0.0, frame=m.MAV_FRAME_BODY_NED), 0.1, math.pi / 2)
    np.testing.assert_allclose(v.command(math.pi / 2)[0], [0.0, 1.0, 0.0], atol=1e-12)


def test_offboard_needs_a_setpoint_first_and_unknown_modes_are_unsupported() -> None:
    v = Vehicle()
    assert _result(v, _command(m.MAV_CMD_DO_SET_MODE, 1.0, 6.0, 0.0)) == m.MAV_RESULT_TEMPORARILY_REJECTED
    assert _result(v, _command(m.MAV_CMD_DO_SET_MODE, 1.0, 5.0, 0.0)) == m.MAV_RESULT_UNSUPPORTED  # acro
    assert v.mode is Mode.HOLD


def test_failsafe_holds_after_half_a_second_without_setpoints() -> None:
    v = Vehicle()
    _armed_offboard(v, now=1.0)
    v.update(1.0 + SETPOINT_TIMEOUT - 0.05)
    assert v.mode is Mode.OFFBOARD
    v.update(1.0 + SETPOINT_TIMEOUT + 0.05)
    assert v.mode is Mode.HOLD
    assert v.counts["failsafes"] == 1
    np.testing.assert_allclose(v.command(0.0)[0], [0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "values",
    [
        (math.nan, 0.0, 0.0, 0.0),
        (0.0, math.inf, 0.0, 0.0),
        (2 * MAX_SETPOINT_SPEED, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, 1e9),
    ],
)
def test_nan_or_huge_setpoints_are_rejected_counted_and_the_vehicle_holds(values: tuple[float, ...]) -> None:
    lines: list[str] = []
    v = Vehicle(log=lines.append)
    _armed_offboard(v, now=0.0)
    v.handle(_setpoint(*values), 0.1, 0.0)
    assert v.counts["rejected_setpoints"] == 1
    assert any("rejected" in line for line in lines)
    vel, rate = v.command(0.0)
    np.testing.assert_allclose(vel, [0.0, 0.0, 0.0])
    assert rate == 0.0
    v.update(0.1 + SETPOINT_TIMEOUT)  # the rejected setpoint does not keep offboard alive
    assert v.mode is Mode.HOLD


def test_position_setpoints_are_not_emulated() -> None:
    v = Vehicle()
    _armed_offboard(v)
    v.handle(_setpoint(0.0, 0.0, 0.0, mask=0b110111111000), 0.1, 0.0)  # position only
    assert v.counts["unsupported_setpoints"] == 1
    np.testing.assert_allclose(v.command(0.0)[0], [0.5, 0.0, 0.0])  # the last valid one stands


def test_unknown_commands_are_unsupported_and_foreign_ones_ignored() -> None:
    v = Vehicle()
    assert _result(v, _command(31_000, 1.0)) == m.MAV_RESULT_UNSUPPORTED
    assert v.counts["unsupported_commands"] == 1
    assert v.handle(_command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0, target=7), 0.0, 0.0) == []
    assert not v.armed and v.counts["foreign"] == 1


def test_disarm_in_the_air_is_refused_and_land_descends() -> None:
    v = Vehicle()
    _armed_offboard(v)
    assert _result(v, _command(m.MAV_CMD_COMPONENT_ARM_DISARM, 0.0)) == m.MAV_RESULT_DENIED
    assert _result(v, _command(m.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 21196.0)) == m.MAV_RESULT_DENIED
    assert v.armed
    assert _result(v, _command(m.MAV_CMD_NAV_LAND)) == m.MAV_RESULT_ACCEPTED
    assert v.mode is Mode.LAND
    assert v.command(0.0)[0][2] > 0  # down
    v.episode_ended(5.0)
    v.update(5.5)
    assert v.armed
    v.update(6.0)
    assert not v.armed
    assert _result(v, _command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1.0), 6.0) == m.MAV_RESULT_TEMPORARILY_REJECTED


def test_requests_and_message_intervals() -> None:
    streams = messages.Streams(0.05)
    v = Vehicle(streams=streams.set_interval, can_send=messages.ON_REQUEST)
    assert _result(v, _command(m.MAV_CMD_REQUEST_MESSAGE, 148.0)) == m.MAV_RESULT_ACCEPTED
    assert _result(v, _command(m.MAV_CMD_GET_HOME_POSITION)) == m.MAV_RESULT_ACCEPTED
    assert _result(v, _command(m.MAV_CMD_REQUEST_MESSAGE, 12_345.0)) == m.MAV_RESULT_UNSUPPORTED
    assert v.requested == [148, 242]
    # 5 Hz asked for ATTITUDE (32 is LOCAL_POSITION_NED): due every 4 steps of 50 ms
    assert _result(v, _command(m.MAV_CMD_SET_MESSAGE_INTERVAL, 32.0, 200_000.0)) == m.MAV_RESULT_ACCEPTED
    due = [("LOCAL_POSITION_NED" in streams.due(k * 0.05)) for k in range(8)]
    assert due == [True, False, False, False, True, False, False, False]
    assert _result(v, _command(m.MAV_CMD_SET_MESSAGE_INTERVAL, 32.0, -1.0)) == m.MAV_RESULT_ACCEPTED
    assert all("LOCAL_POSITION_NED" not in streams.due(1.0 + k * 0.05) for k in range(10))
    assert _result(v, _command(m.MAV_CMD_SET_MESSAGE_INTERVAL, 77.0, 1000.0)) == m.MAV_RESULT_UNSUPPORTED


def test_message_table_ids_match_the_dialect() -> None:
    for spec in messages.MESSAGE_TABLE:
        assert getattr(m, f"MAVLINK_MSG_ID_{spec.name}") == spec.msg_id, spec.name
    assert set(messages.DEFAULT_HZ) <= {s.name for s in messages.MESSAGE_TABLE}


def test_the_docs_show_the_message_table_as_built() -> None:
    text = (Path(__file__).resolve().parents[2] / "docs" / "mavlink.md").read_text()
    begin = "<!-- message table: begin (ihrcf_env.mavlink.messages.message_table_markdown) -->\n"
    block = text[text.index(begin) + len(begin) : text.index("<!-- message table: end -->")]
    assert block.strip() == messages.message_table_markdown()
