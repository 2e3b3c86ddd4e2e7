"""The vehicle's loop: an env stepped on a simulated clock, behind MAVLink links.

:class:`MavlinkVehicle` owns the links (:class:`~ihrcf_env.mavlink.link.Link`) and the state
machine (:class:`~ihrcf_env.mavlink.vehicle.Vehicle`) and drives a landing or hover env (velocity
actions) given to it. Each tick of the vehicle clock is one control period of the env
(``1 / control_hz`` s): the packets received are handled, the vehicle's command (a NED velocity
and yaw rate) becomes the env's velocity action, the env steps, and the telemetry due is sent
(:mod:`ihrcf_env.mavlink.messages`), with ``LANDING_TARGET`` on each new camera frame
(:mod:`ihrcf_env.mavlink.target`). ``speed`` K paces the clock at K times real time (None: as
fast as it runs); packets are taken while it waits.

Episodes: the env is reset with seeds ``seed, seed + 1, ...``; a new episode waits, disarmed in
hold, with the world still (the env is not stepped) until the first arm. It ends at the env's
termination (touchdown, crash) or truncation: the vehicle reports it (``STATUSTEXT`` and the
log), shows the landed state, disarms :data:`~ihrcf_env.mavlink.vehicle.AUTO_DISARM` s later and,
with episodes left, starts the next one; after the last one it stays up (``episodes=None``) or
the loop returns.
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.envs.deck_landing import DroneState
from ihrcf_env.mavlink import frames, messages
from ihrcf_env.mavlink._pymavlink import dialect
from ihrcf_env.mavlink.link import Link
from ihrcf_env.mavlink.options import DEFAULT_OUT, VehicleOptions
from ihrcf_env.mavlink.report import EpisodeRecord, VehicleReport, format_rates
from ihrcf_env.mavlink.target import DeckFix, landing_target
from ihrcf_env.mavlink.vehicle import AUTO_DISARM, Mode, Vehicle
from ihrcf_env.wrappers.estimates import base_config

#: The vehicle stays up this long (s, vehicle clock) after the last episode's disarm before
#: the loop returns (``episodes`` given), so clients see the disarm.
LINGER = 1.0
#: Behind the pace by more than this (s of wall time), the pace restarts from now (no burst).
MAX_LAG = 0.25


class MavlinkVehicle:
    """An env flown as a MAVLink vehicle (module docstring).

    Args:
        env: a deck env (possibly wrapped) with ``action_mode="velocity"``: a landing env
            (``ihrcf_env/DeckLanding-v1`` / ``-v2``) or the hover envs; ``--target`` other than
            ``"truth"`` needs its estimator stage (the landing envs, ``DeckHover-v0``).
        options: :class:`VehicleOptions`.
        log: where the vehicle's events go (one line each; default: print).

    Raises ValueError (naming the option) for an env it cannot fly or a target it cannot read.
    Open the links with :meth:`open` (or ``with``); :meth:`close` closes the links (not the env).
    """

    def __init__(
        self, env: gym.Env, options: VehicleOptions, log: Callable[[str], None] | None = None
    ) -> None:
        self.env, self.options = env, options
        self._print = log or (lambda text: print(text, flush=True))
        config = base_config(env)
        world = config.world
        if world.action_mode != "velocity":
            raise ValueError(
                f"action_mode={world.action_mode!r}: the MAVLink vehicle flies velocity setpoints "
                "(action_mode='velocity')"
            )
        self.dt = 1.0 / world.control_hz
        self.max_velocity = np.asarray(config.task.max_velocity, dtype=np.float64)
        self.max_range = float(world.tof.max_range)
        self.tag_id, self.tag_size = int(world.deck.tag_id), float(world.deck.tag_size)
        self.camera_every = int(world.camera_every) if world.camera is not None else 1
        self._stage: Any = None
        if options.target != "truth":
            try:
                self._stage = env.get_wrapper_attr("stage")
            except AttributeError:
                raise ValueError(
                    f"target {options.target!r}: this env has no estimators (use a landing env, "
                    "DeckHover-v0, or target 'truth')"
                ) from None
            if options.target not in self._stage.sources:
                raise ValueError(
                    f"target {options.target!r}: the env's estimators are {tuple(self._stage.sources)}"
                )
        self._slices, self._scales = _range_layout(env)
        self.streams = messages.Streams(self.dt)
        self.vehicle = Vehicle(
            options.system_id,
            options.component_id,
            log=self._event,
            streams=self.streams.set_interval,
            can_send=messages.ON_REQUEST,
        )
        self.link = Link(options.endpoints, options.system_id, options.component_id)
        self.report = VehicleReport()
        self.now = 0.0  # s, vehicle clock (simulated, since boot)
        self.last_sample: messages.VehicleSample | None = None
        self._episode = -1
        self._seed = options.seed
        self._running = False  # the env steps (armed once this episode)
        self._over_at: float | None = None  # vehicle time the episode ended
        self._landed_state = 0
        self._t0 = 0.0  # vehicle time of the episode's env time 0
        self._obs: Any = None
        self._info: dict[str, Any] = {}
        self._state: DroneState | None = None
        self._home = np.zeros(3)
        self._history: deque[tuple[float, NDArray[np.float64], NDArray[np.float64]]] = deque(maxlen=64)
        self._last_frame: Any = None
        self._steps = 0
        self._touchdown: dict[str, Any] | None = None
        self._next_heartbeat = 0.0
        self._shown: tuple[bool, int] | None = None  # (armed, custom_mode) of the last heartbeat
        self._done = False

    @property
    def episode_start(self) -> float:
        """The vehicle-clock time (s) of the current episode's env time 0 (its first step after
        arming); a ``LANDING_TARGET`` of a frame captured at env time t is stamped ``episode_start + t``."""
        return self._t0

    # -- links ---------------------------------------------------------------------------------
    def open(self) -> MavlinkVehicle:
        """Open the links (:class:`~ihrcf_env.mavlink.link.LinkError` if one cannot be) and reset
        the env for the first episode."""
        self.link.open()
        if self._episode < 0:
            try:
                self._new_episode()
            except BaseException:
                self.close()
                raise
        return self

    def close(self) -> None:
        """Close the links; safe to call twice. The env is the caller's."""
        self.link.close()

    def __enter__(self) -> MavlinkVehicle:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the loop ------------------------------------------------------------------------------
    def run(self, stop: threading.Event | None = None) -> VehicleReport:
        """Run until ``stop`` is set, the episodes are done or ``duration`` has passed; returns the
        report (:attr:`report`, kept across calls). May be called again to go on."""
        if self.link.closed:
            raise RuntimeError("the links are closed: open() the vehicle first")
        if self._episode < 0:
            self._new_episode()
        speed = self.options.speed
        wall0, v0 = time.perf_counter(), self.now
        start_wall, start_now = wall0, self.now
        try:
            while not self._done and not (stop is not None and stop.is_set()):
                if self.options.duration is not None and self.now >= self.options.duration - 1e-9:
                    break
                if speed is not None:
                    deadline = wall0 + (self.now - v0) / speed
                    while True:
                        self._receive()
                        left = deadline - time.perf_counter()
                        if left <= 0:
                            break
                        self.link.wait(min(left, 0.05))
                    if time.perf_counter() - deadline > MAX_LAG:
                        wall0, v0 = time.perf_counter(), self.now
                else:
                    self._receive()
                self._tick()
        finally:
            self.report.wall_time += time.perf_counter() - start_wall
            self.report.sim_time += self.now - start_now
            self.report.counts = Counter(self.vehicle.counts)
            self.report.counts["bad_packets"] = self.link.bad_packets
            self.report.counts["send_errors"] = self.link.send_errors
        return self.report

    def _tick(self) -> None:
        """One control period of the vehicle clock."""
        v = self.vehicle
        v.update(self.now)
        if self._over_at is None and not self._running and (v.armed or self.options.auto_arm):
            if self.options.auto_arm and not v.armed:
                v.armed = True
            self._running = True
            self._t0 = self.now
            self._home = self._state.position.copy() if self._state is not None else np.zeros(3)
        if self._running and self._over_at is None:
            self._step()
        self.now += self.dt
        if self._over_at is not None:
            self._after_episode()
        self._send_telemetry()
        wall = time.monotonic()
        shown = (v.armed, v.custom_mode())
        if wall >= self._next_heartbeat or shown != self._shown:  # at once on a change of state
            self._next_heartbeat = wall + 1.0
            self._shown = shown
            self._send(messages.heartbeat(*shown))

    def _step(self) -> None:
        assert self._state is not None
        yaw_world = _yaw(self._state.quaternion)
        v_ned, rate_ned = self.vehicle.command(frames.yaw_world_to_ned(yaw_world))
        v_cmd, rate = frames.velocity_command(v_ned, rate_ned, yaw_world)
        action = np.clip(np.append(v_cmd, rate) / self.max_velocity, -1.0, 1.0)
        t = time.perf_counter()
        obs, _, terminated, truncated, info = self.env.step(action.astype(np.float32))
        self.report.env_time += time.perf_counter() - t
        self.report.steps += 1
        self._steps += 1
        self._obs, self._info = obs, info
        self._state = self.env.get_wrapper_attr("drone_state")()
        s = self._state
        self._history.append((s.time, s.position, s.quaternion))
        if "touchdown" in info and self._touchdown is None:
            self._touchdown = info["touchdown"]
        self._landing_target(self._t0 + s.time)
        if terminated or truncated:
            self._end_episode(info, truncated and not terminated)

    def _landing_target(self, now: float) -> None:
        """``LANDING_TARGET`` for a new camera frame with a valid estimate (or the truth)."""
        fix: DeckFix | None = None
        if self._stage is None:  # the truth, at the camera's rate
            if self._steps % self.camera_every != 0 or self._state is None:
                return
            info = self._info
            fix = DeckFix(
                now,
                np.asarray(info["deck_position_body"], np.float64),
                np.asarray(info["deck_rotation_body"], np.float64),
                self._state.position,
                self._state.quaternion,
            )
        else:
            frame = self._stage.last_frame
            if frame is None or frame is self._last_frame:
                return
            self._last_frame = frame
            est = self._stage.last_estimates[self.options.target]
            pose = self._pose_at(float(frame.time))
            if not est.valid or pose is None:
                self.vehicle.counts["targets_not_sent"] += 1
                return
            fix = DeckFix(self._t0 + float(frame.time), est.position, est.rotation, *pose)
        self._send(landing_target(fix, self.options.profile, self.tag_id, self.tag_size))

    def _pose_at(self, t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The drone's world pose at env time ``t`` (s) from the recent steps, or None."""
        best = min(self._history, key=lambda h: abs(h[0] - t), default=None)
        if best is None or abs(best[0] - t) > 0.5 * self.dt:
            return None
        return best[1], best[2]

    # -- episodes ------------------------------------------------------------------------------
    def _new_episode(self) -> None:
        self._episode += 1
        self._seed = self.options.seed + self._episode
        self._obs, self._info = self.env.reset(seed=self._seed)
        self._state = self.env.get_wrapper_attr("drone_state")()
        self._history.clear()
        self._last_frame = self._stage.last_frame if self._stage is not None else None
        self._steps = 0
        self._touchdown = None
        self._running = False
        self._over_at = None
        self._home = self._state.position.copy()
        self.vehicle.new_episode()
        self._event(f"seed {self._seed} (episode {self._episode + 1}): waiting for arming")

    def _end_episode(self, info: Mapping[str, Any], truncated: bool) -> None:
        assert self._state is not None
        td = self._touchdown
        outcome = "truncated" if truncated else str(info.get("outcome", "terminated"))
        rec = EpisodeRecord(
            self._seed, outcome, float(self._state.time), reason=str(info.get("crash_reason", "") or "")
        )
        if td is not None:
            rec.speed = float(td["relative_vertical_speed"])
            rec.tilt = float(td["relative_tilt"])
            rec.offset = float(info.get("tag_offset", math.nan))
        self.report.episodes.append(rec)
        self._over_at = self.now
        self._landed_state = dialect().MAV_LANDED_STATE_ON_GROUND if td is not None else 0
        self.vehicle.episode_ended(self.now)
        self._print(rec.line())
        short = f"{outcome}" + (
            f" v{rec.speed:.2f} tilt{math.degrees(rec.tilt):.1f} off{rec.offset:.2f}"
            if rec.speed is not None and rec.tilt is not None and rec.offset is not None
            else ""
        )
        self._send(messages.statustext(f"episode end: {short}"))

    def _after_episode(self) -> None:
        assert self._over_at is not None
        if self.now - self._over_at < AUTO_DISARM + LINGER - 1e-9:
            return
        n = self.options.episodes
        done = len(self.report.episodes)
        if n is not None and done >= n:
            self._done = True
        elif n is not None:
            self._new_episode()

    # -- messages ------------------------------------------------------------------------------
    def _send(self, msg: Any) -> None:
        self.link.send(msg)
        self.report.sent[msg.get_type()] += 1

    def _event(self, text: str) -> None:
        self._print(f"[t {self.now:8.2f} s] {text}")
        if not self.link.closed:
            severe = text.startswith(("failsafe", "setpoint rejected"))
            m = dialect()
            self._send(messages.statustext(text, m.MAV_SEVERITY_WARNING if severe else None))

    def _receive(self) -> None:
        m = dialect()
        yaw_ned = frames.yaw_world_to_ned(_yaw(self._state.quaternion)) if self._state is not None else 0.0
        for msg in self.link.receive():
            if (
                msg.get_srcSystem() == self.options.system_id
                and msg.get_srcComponent() == self.options.component_id
            ):
                continue  # our own packets, echoed
            kind = msg.get_type()
            if kind == "TIMESYNC":
                reply = messages.timesync_reply(msg, self.now)
                if reply is not None:
                    self._send(reply)
                continue
            try:
                answers = self.vehicle.handle(msg, self.now, yaw_ned)
            except (TypeError, ValueError, OverflowError, AttributeError):
                self.vehicle.counts["bad_messages"] += 1  # a message whose fields cannot be read
                continue
            for answer in answers:
                self._send(answer)
            for msg_id in self.vehicle.requested:
                sample = self.sample()
                if msg_id == m.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                    self._send(messages.autopilot_version())
                elif msg_id == m.MAVLINK_MSG_ID_HOME_POSITION:
                    self._send(messages.home_position(sample))
                else:
                    name = next(s.name for s in messages.MESSAGE_TABLE if s.msg_id == msg_id)
                    for out in messages.stream(name, sample):
                        self._send(out)
            self.vehicle.requested.clear()

    def sample(self) -> messages.VehicleSample:
        """The vehicle's state now, as the telemetry reports it (env frames; see
        :class:`~ihrcf_env.mavlink.messages.VehicleSample`)."""
        s = self._state
        assert s is not None
        ranges, valid = self._ranges()
        m = dialect()
        over = self._over_at is not None
        if over:
            landed = self._landed_state
        elif self._running and self.vehicle.mode is Mode.LAND and self.vehicle.armed:
            landed = m.MAV_LANDED_STATE_LANDING
        else:
            landed = m.MAV_LANDED_STATE_IN_AIR
        still = over or not self._running  # the world waits (or the episode is over): at rest
        return messages.VehicleSample(
            self.now,
            s.position,
            np.zeros(3) if still else s.velocity,
            s.quaternion,
            np.zeros(3) if still else s.rates,
            ranges,
            valid,
            self.max_range,
            landed,
            self._home,
        )

    def _send_telemetry(self) -> None:
        due = self.streams.due(self.now)
        if not due:
            return
        sample = self.sample()
        self.last_sample = sample
        for name in due:
            for msg in messages.stream(name, sample):
                self._send(msg)

    def _ranges(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """ToF ranges (m) and valid flags of the last observation."""
        obs = self._obs
        if isinstance(obs, Mapping):
            return np.asarray(obs["ranges"], np.float64), np.asarray(obs["ranges_valid"]).astype(bool)
        a = np.asarray(obs, np.float64)
        r = a[self._slices["ranges"]] * self._scales.get("ranges", 1.0)
        return r, a[self._slices["ranges_valid"]] > 0.5


def _yaw(q_xyzw: NDArray[np.float64]) -> float:
    """Heading (rad) about world z of the body x axis."""
    R = matrix_from_quat(q_xyzw)
    return math.atan2(R[1, 0], R[0, 0])


def _range_layout(env: gym.Env) -> tuple[dict[str, slice], dict[str, float]]:
    """The slices (and scales) of the ranges in a flat observation (empty for a Dict one)."""
    for slices_name, scales_name in (("obs_slices", "obs_scales"), ("flat_slices", None)):
        try:
            slices = env.get_wrapper_attr(slices_name)
        except AttributeError:
            continue
        scales = env.get_wrapper_attr(scales_name) if scales_name is not None else {}
        return dict(slices), dict(scales)
    return {}, {}


def run_vehicle(
    env: gym.Env, options: VehicleOptions, log: Callable[[str], None] | None = None
) -> VehicleReport:
    """Fly ``env`` as a MAVLink vehicle with ``options`` until its episodes are done (or
    Ctrl-C); the links are closed on the way out, the env is the caller's."""
    with MavlinkVehicle(env, options, log) as vehicle:
        return vehicle.run()


__all__ = [
    "DEFAULT_OUT",
    "EpisodeRecord",
    "MavlinkVehicle",
    "VehicleOptions",
    "VehicleReport",
    "format_rates",
    "run_vehicle",
]
