"""MAVSDK-Python (4.x, ctypes over its bundled library) flies the vehicle on localhost UDP:
connect within 3 s, arm, offboard, telemetry equal to the env's truth, a velocity setpoint moving
the drone the commanded way, and the failsafe when the client vanishes."""

from __future__ import annotations

import asyncio
import time

import gymnasium as gym
import numpy as np
import pytest
from udp_helpers import ENV_ID, ENV_OPTIONS, VehicleThread, free_udp_port, truth_ned, vehicle_thread

from ihrcf_env.core.frames import matrix_from_quat

mavsdk = pytest.importorskip("mavsdk")
from mavsdk.asyncio import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.offboard import OffboardAsync, VelocityNedYaw  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import FlightMode, LandedState, TelemetryAsync  # noqa: E402

from ihrcf_env.mavlink.vehicle import Mode  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore:.*DeckLanding-v1 is out of date")
D = np.diag([1.0, -1.0, -1.0])


async def _matches_truth(tel: TelemetryAsync, env: gym.Env, landed: LandedState) -> None:
    """MAVSDK's latest position, velocity, attitude and landed state equal the env's truth (the
    vehicle paused: its last telemetry is the state the env is in)."""
    await asyncio.sleep(0.3)
    pv = await tel.position_velocity_ned()
    q = await tel.attitude_quaternion()
    p_ned, v_ned, q_env = truth_ned(env)
    pos, vel = pv.position, pv.velocity
    np.testing.assert_allclose([pos.north_m, pos.east_m, pos.down_m], p_ned, atol=1e-3)
    np.testing.assert_allclose([vel.north_m_s, vel.east_m_s, vel.down_m_s], v_ned, atol=1e-3)
    R = matrix_from_quat([q.x, q.y, q.z, q.w])
    np.testing.assert_allclose(R, D @ matrix_from_quat(q_env) @ D, atol=1e-3)
    assert await tel.landed_state() == landed


def test_mavsdk_connects_arms_flies_offboard_and_the_failsafe_holds() -> None:
    port = free_udp_port()
    env = gym.make(ENV_ID, **ENV_OPTIONS)
    try:
        with vehicle_thread(env, endpoints=(f"udpout:127.0.0.1:{port}",), speed=2.0, seed=1) as runner:
            asyncio.run(_fly(runner, env, port))
            runner.start()
            time.sleep(1.0)  # the client is gone: 2 s simulated without setpoints
            runner.pause()
            v = runner.vehicle.vehicle
            assert v.mode is Mode.HOLD and v.armed
            assert v.counts["failsafes"] == 1
            assert np.isfinite(truth_ned(env)[0]).all()
    finally:
        env.close()


async def _fly(runner: VehicleThread, env: gym.Env, port: int) -> None:
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        t0 = time.monotonic()
        system = await sdk.first_autopilot(timeout_s=3.0)
        assert system is not None, "no autopilot within 3 s"
        assert time.monotonic() - t0 < 3.0
        tel, action, offboard = TelemetryAsync(system), ActionAsync(system), OffboardAsync(system)
        await asyncio.sleep(0.5)
        # disarmed: the world waits; the telemetry is the start state
        runner.pause()
        await _matches_truth(tel, env, LandedState.IN_AIR)
        assert not await tel.armed()
        runner.start()
        await action.arm()
        heading = (await tel.attitude_euler()).yaw_deg  # keep the heading (deg, NED)
        await offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, heading))
        await offboard.start()
        await asyncio.sleep(0.3)
        assert await tel.flight_mode() == FlightMode.OFFBOARD
        assert await tel.armed()
        runner.pause()
        start = truth_ned(env)[0]
        runner.start()
        want = np.array([0.4, -0.3, 0.0])  # m/s NED: north and west, level
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:
            await offboard.set_velocity_ned(VelocityNedYaw(*want.tolist(), heading))
            await asyncio.sleep(0.05)
        runner.pause()
        moved = truth_ned(env)[0] - start
        assert np.linalg.norm(moved[:2]) > 0.5  # ~4 s simulated at 0.5 m/s
        cos = float(moved[:2] @ want[:2]) / (np.linalg.norm(moved[:2]) * np.linalg.norm(want[:2]))
        assert cos > 0.95, (moved, want)
        assert abs(moved[2]) < 0.2
        await _matches_truth(tel, env, LandedState.IN_AIR)
        runner.start()
        await asyncio.sleep(0.2)
    # leaving the context destroys MAVSDK: the client vanishes mid-flight, in offboard
