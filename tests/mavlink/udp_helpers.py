"""Helpers of the MAVLink tests: free ports, a pymavlink listener, a vehicle in a thread."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.mavlink._pymavlink import import_pymavlink
from ihrcf_env.mavlink.loop import MavlinkVehicle, VehicleOptions

#: The env the socket tests fly: v1 with the projected camera (fast resets, no ship motion).
ENV_ID = "ihrcf_env/DeckLanding-v1"
ENV_OPTIONS: dict[str, Any] = {"camera_model": "projected", "max_episode_steps": -1}


def free_udp_port() -> int:
    """A UDP port nobody holds now on 127.0.0.1."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def listener(port: int) -> Any:
    """A pymavlink connection listening on 127.0.0.1:``port`` (MAVLink 2, common)."""
    return import_pymavlink().mavlink_connection(
        f"udpin:127.0.0.1:{port}", dialect="common", source_system=245
    )


def drain(conn: Any, settle: float = 0.2) -> list[Any]:
    """Every message waiting on ``conn`` (until none arrives for ``settle`` s)."""
    out: list[Any] = []
    last = time.monotonic()
    while time.monotonic() - last < settle:
        msg = conn.recv_msg()
        if msg is None:
            time.sleep(0.005)
            continue
        last = time.monotonic()
        if msg.get_type() != "BAD_DATA":
            out.append(msg)
    return out


def truth_ned(env: gym.Env) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The drone's (position, velocity, quaternion x, y, z, w) now, position and velocity in NED
    written out here (north = x, east = -y, down = -z), independently of the package's frames."""
    s = env.get_wrapper_attr("drone_state")()
    p, v = np.asarray(s.position), np.asarray(s.velocity)
    return np.array([p[0], -p[1], -p[2]]), np.array([v[0], -v[1], -v[2]]), np.asarray(s.quaternion)


class VehicleThread:
    """A :class:`MavlinkVehicle` run in a thread, paused (the thread joined) to read the env."""

    def __init__(self, vehicle: MavlinkVehicle) -> None:
        self.vehicle = vehicle
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    def start(self) -> None:
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            self.vehicle.run(self._stop)
        except BaseException as e:  # surfaced by pause()
            self.error = e

    def pause(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=30)
            assert not self._thread.is_alive()
        if self.error is not None:
            raise self.error

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()


@contextlib.contextmanager
def vehicle_thread(env: gym.Env, **options: Any) -> Iterator[VehicleThread]:
    """A vehicle flying ``env`` with ``options`` in a thread; paused and closed at the end."""
    logs: list[str] = []
    vehicle = MavlinkVehicle(env, VehicleOptions(**options), log=logs.append)
    vehicle.open()
    runner = VehicleThread(vehicle)
    runner.start()
    try:
        yield runner
    finally:
        try:
            runner.pause()
        finally:
            vehicle.close()
