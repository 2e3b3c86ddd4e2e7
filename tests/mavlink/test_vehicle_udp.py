"""The vehicle on localhost UDP, read with pymavlink: telemetry against the env's truth,
LANDING_TARGET against the estimator's output of the same frame, and bad input."""

from __future__ import annotations

import math
import socket
import time
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from udp_helpers import (
    ENV_ID,
    ENV_OPTIONS,
    VehicleThread,
    drain,
    free_udp_port,
    listener,
    truth_ned,
    vehicle_thread,
)

from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.mavlink import messages
from ihrcf_env.mavlink._pymavlink import dialect
from ihrcf_env.mavlink.link import Link, LinkError
from ihrcf_env.mavlink.loop import MavlinkVehicle, VehicleOptions

m = dialect()
pytestmark = pytest.mark.filterwarnings("ignore:.*DeckLanding-v1 is out of date")
D = np.diag([1.0, -1.0, -1.0])


class FrameSpy(gym.Wrapper):
    """Records, for each new camera frame, the estimate of ``target`` and the drone's pose."""

    def __init__(self, env: gym.Env, target: str) -> None:
        super().__init__(env)
        self.target = target
        self.frames: list[tuple[float, Any, np.ndarray, np.ndarray]] = []
        self._last: Any = None

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        stage = self.env.get_wrapper_attr("stage")
        frame = stage.last_frame
        if frame is not self._last:
            self._last = frame
            s = self.env.get_wrapper_attr("drone_state")()
            assert s.time == pytest.approx(frame.time)  # no camera latency: captured now
            self.frames.append(
                (float(frame.time), stage.last_estimates[self.target], s.position, s.quaternion)
            )
        return out


class LastObservation(gym.Wrapper):
    """Keeps the last observation the env returned."""

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        self.last = out[0]
        return out


def _rot_wxyz(q: Any) -> np.ndarray:
    w, x, y, z = (float(v) for v in q)
    return matrix_from_quat([x, y, z, w])


@pytest.mark.parametrize(("profile", "target"), [("px4", "fused"), ("ardupilot", "atda")])
def test_landing_target_and_telemetry_match_the_env(profile: str, target: str) -> None:
    port = free_udp_port()
    rx = listener(port)
    env = FrameSpy(gym.make(ENV_ID, **ENV_OPTIONS), target)
    try:
        opts = VehicleOptions(
            endpoints=(f"udpout:127.0.0.1:{port}",),
            speed=None,
            seed=3,
            target=target,
            profile=profile,
            auto_arm=True,
            duration=3.0,
        )
        with MavlinkVehicle(env, opts, log=lambda _t: None) as vehicle:
            runner = VehicleThread(vehicle)
            runner.start()
            msgs = []
            while runner.alive:  # read as a client does, while the vehicle runs
                msgs += drain(rx, settle=0.02)
            runner.pause()
            msgs += drain(rx)
            report, t0 = vehicle.report, vehicle.episode_start
            p_ned, v_ned, q = truth_ned(env)
    finally:
        env.close()
        rx.close()
    assert report.steps == 60 and report.counts["bad_packets"] == 0
    targets = [x for x in msgs if x.get_type() == "LANDING_TARGET"]
    valid = {round((t0 + t) * 1e6): (est, p, qd) for t, est, p, qd in env.frames if est.valid}
    invalid = {round((t0 + t) * 1e6) for t, est, _, _ in env.frames if not est.valid}
    assert len(valid) > 10  # the camera rate: every step here, most frames valid
    assert {x.time_usec for x in targets} == set(valid)  # each valid frame once, invalid ones never
    assert not invalid & {x.time_usec for x in targets}
    for x in targets:
        est, p_w, q_w = valid[x.time_usec]
        assert x.position_valid == 1 and x.type == m.LANDING_TARGET_TYPE_VISION_FIDUCIAL
        R_wb = matrix_from_quat(q_w)
        body_frd = D @ est.position
        assert x.distance == pytest.approx(np.linalg.norm(est.position), abs=1e-5)
        assert x.angle_x == pytest.approx(math.atan2(body_frd[1], body_frd[2]), abs=1e-5)
        assert x.angle_y == pytest.approx(math.atan2(-body_frd[0], body_frd[2]), abs=1e-5)
        if profile == "px4":
            assert x.frame == m.MAV_FRAME_LOCAL_NED
            np.testing.assert_allclose([x.x, x.y, x.z], D @ (p_w + R_wb @ est.position), atol=1e-4)
            np.testing.assert_allclose(_rot_wxyz(x.q), D @ R_wb @ est.rotation @ D, atol=1e-5)
        else:
            assert x.frame == m.MAV_FRAME_BODY_FRD
            np.testing.assert_allclose([x.x, x.y, x.z], body_frd, atol=1e-5)
            np.testing.assert_allclose(_rot_wxyz(x.q), D @ est.rotation @ D, atol=1e-5)
    if target == "fused":
        assert invalid  # the filter's first frames, before it converges: not sent
    # the last telemetry sent is the state the env is in now (1e-3)
    last = {x.get_type(): x for x in msgs}
    lp, att, aq = last["LOCAL_POSITION_NED"], last["ATTITUDE"], last["ATTITUDE_QUATERNION"]
    np.testing.assert_allclose([lp.x, lp.y, lp.z], p_ned, atol=1e-3)
    np.testing.assert_allclose([lp.vx, lp.vy, lp.vz], v_ned, atol=1e-3)
    R_ned = D @ matrix_from_quat(q) @ D
    np.testing.assert_allclose(_rot_wxyz([aq.q1, aq.q2, aq.q3, aq.q4]), R_ned, atol=1e-3)
    assert att.yaw == pytest.approx(math.atan2(R_ned[1, 0], R_ned[0, 0]), abs=1e-3)
    assert att.pitch == pytest.approx(-math.asin(R_ned[2, 0]), abs=1e-3)
    assert last["EXTENDED_SYS_STATE"].landed_state == m.MAV_LANDED_STATE_IN_AIR
    assert {x.id for x in msgs if x.get_type() == "DISTANCE_SENSOR"} == {0, 1, 2, 3}
    hb = last["HEARTBEAT"]
    assert hb.autopilot == m.MAV_AUTOPILOT_PX4 and hb.base_mode & m.MAV_MODE_FLAG_SAFETY_ARMED
    assert hb.custom_mode == (4 << 16) | (3 << 24)  # hold


def _send(tx: Any, msg: Any) -> None:
    tx.mav.send(msg)


def test_bad_input_is_refused_and_the_failsafe_holds() -> None:
    """Garbage, foreign and unknown commands, NaN setpoints, then a client that goes silent in
    offboard: the vehicle answers, counts, holds, and keeps running."""
    port = free_udp_port()
    rx = listener(port)
    env = gym.make(ENV_ID, **ENV_OPTIONS)
    try:
        with vehicle_thread(env, endpoints=(f"udpout:127.0.0.1:{port}",), speed=2.0) as runner:
            hb = rx.recv_match(type="HEARTBEAT", blocking=True, timeout=10)
            assert hb is not None and rx.target_system == 1
            raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            dest = next(iter(rx.clients))  # the vehicle's socket
            for junk in (b"\xfd\xff\x00" * 40, bytes(range(256)), b"\xfe\x09" + b"\x00" * 20):
                raw.sendto(junk, dest)
            raw.close()
            cmd = rx.mav.command_long_encode
            _send(rx, cmd(1, 1, 31_000, 0, 0, 0, 0, 0, 0, 0, 0))  # unknown command
            _send(rx, cmd(9, 1, m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))  # another system
            ack = rx.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
            assert ack is not None and (ack.command, ack.result) == (31_000, m.MAV_RESULT_UNSUPPORTED)
            _send(rx, cmd(1, 1, m.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0))
            sp = rx.mav.set_position_target_local_ned_encode
            vel = 0b010111000111
            for _ in range(5):
                _send(rx, sp(0, 1, 1, m.MAV_FRAME_LOCAL_NED, vel, 0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0, 0))
                time.sleep(0.02)
            _send(rx, cmd(1, 1, m.MAV_CMD_DO_SET_MODE, 0, 1, 6, 0, 0, 0, 0, 0))
            _send(rx, sp(0, 1, 1, m.MAV_FRAME_LOCAL_NED, vel, 0, 0, 0, math.nan, 0, 0, 0, 0, 0, 0, 0))
            _send(rx, sp(0, 1, 1, m.MAV_FRAME_LOCAL_NED, vel, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1e12))
            modes = []
            t_end = time.monotonic() + 3.0
            while time.monotonic() < t_end:  # silent now: offboard, then hold within 0.5 s simulated
                msg = rx.recv_match(type="HEARTBEAT", blocking=True, timeout=1.5)
                if msg is not None:
                    modes.append(msg.custom_mode)
            assert runner.alive
            runner.pause()
            v = runner.vehicle
            counts = v.vehicle.counts
            assert v.link.bad_packets >= 1
            assert counts["unsupported_commands"] == 1 and counts["foreign"] == 1
            assert counts["rejected_setpoints"] == 2
            assert counts["failsafes"] == 1
            assert v.vehicle.armed and modes[-1] == (4 << 16) | (3 << 24)
            assert np.isfinite(truth_ned(env)[0]).all()
    finally:
        env.close()
        rx.close()


def test_a_port_in_use_is_a_link_error_and_nothing_leaks() -> None:
    port = free_udp_port()
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("127.0.0.1", port))
    env = gym.make(ENV_ID, **ENV_OPTIONS)
    try:
        vehicle = MavlinkVehicle(
            env, VehicleOptions(endpoints=(f"udpout:127.0.0.1:{free_udp_port()}", f"udpin:127.0.0.1:{port}"))
        )
        with pytest.raises(LinkError, match="in use"):
            vehicle.open()
        assert vehicle.link.closed  # the first link was closed again
    finally:
        holder.close()
        env.close()


@pytest.mark.parametrize(
    ("endpoints", "match"),
    [
        (("tcp:127.0.0.1:5760",), "SCHEME"),
        (("udpout:127.0.0.1:70000",), "port"),
        (("udpout:no-such-host.invalid:14540",), "does not resolve"),
        ((), "non-empty"),
    ],
)
def test_bad_endpoints_are_refused_before_any_socket(endpoints: tuple[str, ...], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        VehicleOptions(endpoints=endpoints)


@pytest.mark.parametrize(
    ("field", "value"),
    [("speed", 0.0), ("speed", math.nan), ("episodes", 0), ("target", "pnp"), ("profile", "x")],
)
def test_bad_options_name_themselves(field: str, value: Any) -> None:
    with pytest.raises(ValueError, match=field):
        VehicleOptions(**{field: value})


def test_each_link_sends_from_one_socket_even_when_opened_twice() -> None:
    port, other = free_udp_port(), free_udp_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx:
        rx.bind(("127.0.0.1", port))
        rx.settimeout(0.5)
        with Link([f"udpout:127.0.0.1:{port}", f"udpout:127.0.0.1:{other}"]) as link:
            link.open()
            link.open()
            assert len(link.connections) == 2
            for _ in range(3):
                link.send(messages.heartbeat(False, 0))
            sources = set()
            try:
                while True:
                    data, addr = rx.recvfrom(1000)
                    if data:
                        sources.add(addr)
            except TimeoutError:
                pass
        assert len(sources) == 1 and link.closed


def test_timesync_and_requested_messages_are_answered() -> None:
    port = free_udp_port()
    rx = listener(port)
    env = gym.make(ENV_ID, **ENV_OPTIONS)
    try:
        with vehicle_thread(env, endpoints=(f"udpout:127.0.0.1:{port}",), speed=4.0):
            assert rx.recv_match(type="HEARTBEAT", blocking=True, timeout=10) is not None
            _send(rx, rx.mav.timesync_encode(0, 123_456_789))
            _send(rx, rx.mav.command_long_encode(1, 1, m.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0))
            _send(rx, rx.mav.command_long_encode(1, 1, m.MAV_CMD_GET_HOME_POSITION, 0, 0, 0, 0, 0, 0, 0, 0))
            got: dict[str, Any] = {}
            t_end = time.monotonic() + 5.0
            wanted = {"TIMESYNC", "AUTOPILOT_VERSION", "HOME_POSITION", "SYSTEM_TIME", "SYS_STATUS"}
            while time.monotonic() < t_end and not wanted <= set(got):
                msg = rx.recv_match(blocking=True, timeout=0.5)
                if msg is not None:
                    got.setdefault(msg.get_type(), msg)
            p_ned = truth_ned(env)[0]
        assert wanted <= set(got), sorted(got)
        assert got["TIMESYNC"].ts1 == 123_456_789 and got["TIMESYNC"].tc1 > 0
        assert got["AUTOPILOT_VERSION"].capabilities & m.MAV_PROTOCOL_CAPABILITY_MAVLINK2
        home = got["HOME_POSITION"]
        np.testing.assert_allclose([home.x, home.y, home.z], p_ned, atol=1e-3)  # the start (not armed)
    finally:
        env.close()
        rx.close()


def test_a_raw_hover_env_flies_with_the_truth_as_target() -> None:
    """A raw env (Dict observation, no estimators): the ToF ranges from its observation, the true
    deck pose as LANDING_TARGET at the camera rate."""
    port = free_udp_port()
    rx = listener(port)
    env = LastObservation(
        gym.make("ihrcf_env/DeckHoverRaw-v0", camera_model="projected", camera_hz=10, max_episode_steps=-1)
    )
    try:
        opts = VehicleOptions(
            endpoints=(f"udpout:127.0.0.1:{port}",),
            speed=None,
            target="truth",
            profile="ardupilot",
            auto_arm=True,
            duration=1.0,
        )
        with MavlinkVehicle(env, opts, log=lambda _t: None) as vehicle:
            runner = VehicleThread(vehicle)
            runner.start()
            msgs: list[Any] = []
            while runner.alive:
                msgs += drain(rx, settle=0.02)
            runner.pause()
            msgs += drain(rx)
            t0 = vehicle.episode_start
            deck, _ = env.get_wrapper_attr("deck_pose_body")()
            s = env.get_wrapper_attr("drone_state")()
            obs = env.last
    finally:
        env.close()
        rx.close()
    targets = [x for x in msgs if x.get_type() == "LANDING_TARGET"]
    assert len(targets) == 10  # 1 s at the camera's 10 Hz (20 steps)
    last = max(targets, key=lambda x: x.time_usec)
    assert last.time_usec == round((t0 + s.time) * 1e6)
    np.testing.assert_allclose([last.x, last.y, last.z], D @ deck, atol=1e-5)
    ranges = {x.id: x for x in msgs if x.get_type() == "DISTANCE_SENSOR"}  # the last of each beam
    valid = np.asarray(obs["ranges_valid"]).astype(bool)
    assert valid.any()
    for i, (r, ok) in enumerate(zip(np.asarray(obs["ranges"]).tolist(), valid.tolist(), strict=True)):
        assert ranges[i].current_distance == (round(r * 100) if ok else 0xFFFF)
