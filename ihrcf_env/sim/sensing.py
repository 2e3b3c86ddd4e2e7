"""Sensing in a :class:`~ihrcf_env.sim.world.World`: reading its sensors and its ground truth.

:class:`Sensing` (a world's :attr:`~ihrcf_env.sim.world.World.sensing`) reads the world's sensors
(:attr:`~ihrcf_env.sim.world.World.sensors`) through the configured noise models and faults, each
on its own schedule: every ``update_interval`` control steps, on its own sample clock
(``ToFConfig.rate_hz``, ``IMUConfig.rate_hz``) or through the camera's delay line
(``CameraConfig.latency``); and it reads the ground truth (:meth:`Sensing.snapshot`,
:meth:`Sensing.body_state`). The world's stepping calls it where a sample falls inside a control
step (:meth:`Sensing.due_samples`, :meth:`Sensing.sample_clocked`).
"""

from __future__ import annotations

import math
import struct
import weakref
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env import tasks
from ihrcf_env.core.frames import matrix_from_quat, relative_pose
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim.deck import rigid_point_velocity
from ihrcf_env.sim.registry import apply_faults, finite_reading
from ihrcf_env.sim.sensors import BodyState
from ihrcf_env.sim.sensors.base import TAG_CAMERA
from ihrcf_env.sim.sensors.timing import DelayLine, SampleClock, no_frame_reading

if TYPE_CHECKING:
    from ihrcf_env.sim.world import World

__all__ = ["CAMERA_SENSORS", "Sensing", "Snapshot"]

#: Names of the camera sensors in ``World.sensors`` (read at ``camera_hz``, held in between).
CAMERA_SENSORS: tuple[str, ...] = ("camera", TAG_CAMERA)


@dataclass(frozen=True)
class Snapshot:
    """Ground truth at one instant. World frame unless the name says body (drone FLU frame).

    :meth:`Sensing.snapshot` shares one Snapshot between its callers until the state changes: its
    arrays are read-only."""

    drone_position: NDArray[np.float64]
    drone_rotation: NDArray[np.float64]
    drone_quaternion: NDArray[np.float64]  # x, y, z, w
    drone_velocity: NDArray[np.float64]
    deck_position: NDArray[np.float64]  # deck frame origin (tag centre on the top surface)
    deck_rotation: NDArray[np.float64]
    deck_point_velocity: NDArray[np.float64]  # velocity of the deck's material point at the drone
    deck_position_body: NDArray[np.float64]
    deck_rotation_body: NDArray[np.float64]

    @property
    def relative_velocity(self) -> NDArray[np.float64]:
        return self.drone_velocity - self.deck_point_velocity

    @property
    def relative_tilt(self) -> float:
        """Angle (rad) between the drone's z axis and the deck normal."""
        return float(tasks.relative_tilt(self.drone_rotation, self.deck_rotation))

    def task_state(self) -> tasks.TaskState:
        """This snapshot as the task rules' state (:class:`~ihrcf_env.tasks.TaskState`; the same
        read-only arrays)."""
        return tasks.TaskState(
            drone_position=self.drone_position,
            drone_rotation=self.drone_rotation,
            drone_velocity=self.drone_velocity,
            deck_position=self.deck_position,
            deck_rotation=self.deck_rotation,
            deck_point_velocity=self.deck_point_velocity,
        )


class Sensing:
    """The sensing of ``world`` (held weakly: the world owns its sensing): its sensors' readings,
    their noise models (:attr:`corruptors`), faults (:attr:`faults`), sample clocks
    (:attr:`clocks`), the camera's delay line (:attr:`camera_pipeline`), when each reading shown was
    taken (:attr:`sample_times`), and the ground truth."""

    def __init__(self, world: World) -> None:
        from ihrcf_env.sim.registry import NOISE_MODELS, build_faults, measurement_sizes

        self.world: World = weakref.proxy(world)
        cfg = world.config
        sizes = measurement_sizes(cfg.extra_sensors)
        #: measurement -> the noise model corrupting it (``measurement_noise``)
        self.corruptors = {key: NOISE_MODELS[model](sizes[key]) for key, model in cfg.measurement_noise}
        #: fault name -> the fault (``faults``), applied in this order after the corruptors
        self.faults = build_faults(cfg.faults)
        self._held: dict[str, dict[str, NDArray]] = {}  # sensor -> its last reading
        #: sensor name -> simulated time (s) of the reading shown (NaN: none yet this episode); for
        #: a camera, the exposure time of the frame shown
        self.sample_times: dict[str, float] = dict.fromkeys(world.sensors, math.nan)
        #: sensors on their own clock (``ToFConfig.rate_hz``, ``IMUConfig.rate_hz``): name -> clock
        self.clocks: dict[str, SampleClock] = {
            name: SampleClock(rate, cfg.physics_hz)
            for name, rate in (("tof", cfg.tof.rate_hz), ("imu", cfg.imu.rate_hz))
            if rate is not None
        }
        latency = cfg.camera.latency if cfg.camera is not None else 0.0
        #: the camera's frames in flight (``CameraConfig.latency`` > 0), or None
        self.camera_pipeline = DelayLine(latency, cfg.physics_hz) if latency > 0 else None
        #: camera sensor -> frames delivered this episode
        self.frame_counts: dict[str, int] = {n: 0 for n in CAMERA_SENSORS if n in world.sensors}
        self._rngs: dict[str, np.random.Generator] = {}  # stream name -> this episode's generator
        self._snapshot: Snapshot | None = None  # memo of snapshot(), valid for _snapshot_key
        self._snapshot_key = b""
        self._rotation = np.eye(3)  # memo of _drone_rotation(), valid for _rotation_key
        self._rotation_key = b""

    def reset(self) -> None:
        """A new episode: no reading held, none taken yet, clocks and delay line emptied."""
        self._held = {}
        self.sample_times = dict.fromkeys(self.world.sensors, math.nan)
        for clock in self.clocks.values():
            clock.reset()
        if self.camera_pipeline is not None:
            self.camera_pipeline.reset()
        self.frame_counts = dict.fromkeys(self.frame_counts, 0)

    def reset_random(self, streams: SeedStreams) -> None:
        """Draw this episode's sensor state: sensor ``name`` from stream ``"sensor.<name>"`` (which
        also gives its per-reading noise), noise model ``key`` from ``"noise.<key>"``, fault
        ``name`` from ``"fault.<name>"``."""
        self._rngs = {}
        for name, sensor in self.world.sensors.items():
            rng = self._rngs[name] = streams.generator(f"sensor.{name}")
            sensor.reset(rng)
        for key, model in self.corruptors.items():
            rng = self._rngs[f"noise.{key}"] = streams.generator(f"noise.{key}")
            model.reset(rng)
        for key, fault in self.faults.items():
            rng = self._rngs[f"fault.{key}"] = streams.generator(f"fault.{key}")
            fault.reset(rng)

    def _check_open(self) -> None:
        try:
            closed = self.world.closed
        except ReferenceError:  # the world was dropped: its client is released
            closed = True
        if closed:
            raise RuntimeError("this world is closed (its PyBullet client was disconnected)")

    def body_state(self, acceleration: NDArray[np.float64] | None = None) -> BodyState:
        """The drone's true state now, as sensors see it (``acceleration``, world m/s^2: over the
        last physics step; default the one of the last control step's end)."""
        self._check_open()
        pos, quat, vel, omega = self.world.quad.state()
        return BodyState(
            time=self.world.time,
            position=np.asarray(pos),
            rotation=self._drone_rotation(quat).copy(),
            quaternion=np.asarray(quat),
            velocity=np.asarray(vel),
            angular_velocity=np.asarray(omega),
            acceleration=(self.world._acc_world if acceleration is None else acceleration).copy(),
        )

    def read_sensors(
        self, rng: np.random.Generator | None = None, names: tuple[str, ...] | None = None
    ) -> dict[str, NDArray]:
        """One reading of the sensors ``names`` (default: all, in ``World.sensors`` order), merged into
        one mapping of measurement names (``image``, or ``tag_corners``/``tag_detected``/``tag_reason``;
        ``ranges``, ``ranges_valid``, ``quaternion``, ``angular_velocity``, ``linear_acceleration``)
        to arrays. Call once per control step: noise models advance by one control period.

        Each sensor samples every ``update_interval`` control steps (its attribute, default 1; the
        camera's is ``control_hz / camera_hz``), counted from the episode's start; in between its
        last reading is repeated (fresh copies of the same arrays) and :attr:`sample_times` (s)
        still says when it was taken. A sensor on its own clock (:attr:`clocks`) shows its last
        sample instead (taken by ``World.step`` at its own instants), and a camera with a latency
        shows the last frame whose delivery time has come (:attr:`camera_pipeline`;
        :attr:`sample_times` holds its exposure time, :attr:`frame_counts` counts the frames
        delivered). Noise is drawn from each sensor's own stream (see :meth:`reset_random`), or
        from ``rng`` when given. Named explicitly, a sensor is always read now."""
        state = self.body_state()
        control_dt = self.world.config.substeps * self.world.dt
        out: dict[str, NDArray] = {}
        held = names is None
        for name in names if names is not None else tuple(self.world.sensors):
            sensor = self.world.sensors[name]
            every = int(getattr(sensor, "update_interval", 1))
            if held and name in self.clocks:
                out.update(self._read_clocked(name, state, rng))
                continue
            if held and self.camera_pipeline is not None and name in self.frame_counts:
                out.update(self._read_delayed(name, state, self.takes_fresh(name), control_dt * every, rng))
                continue
            last = self._held.get(name)
            if held and not self.takes_fresh(name):
                assert last is not None
                out.update({k: v.copy() for k, v in last.items()})
                continue
            reading = self._take(name, state, control_dt * every, rng)
            out.update(reading)
            if held:
                self._held[name] = dict(reading)
                self.sample_times[name] = state.time
                if name in self.frame_counts:
                    self.frame_counts[name] += 1
        return out

    def takes_fresh(self, name: str) -> bool:
        """True when the next :meth:`read_sensors` (of all sensors) takes a new reading of sensor
        ``name`` at this tick (False: it shows a held one, or the sensor runs on its own clock)."""
        if name in self.clocks:
            return False
        step = self.world.tick // self.world.config.substeps
        every = int(getattr(self.world.sensors[name], "update_interval", 1))
        line = self.camera_pipeline
        if line is not None and name in self.frame_counts:
            return step % every == 0 and line.exposed_at != self.world.tick
        return step % every == 0 or self._held.get(name) is None

    def _take(
        self, name: str, state: BodyState, dt: float, rng: np.random.Generator | None
    ) -> Mapping[str, NDArray]:
        """One reading of sensor ``name`` at ``state``, ``dt`` s after its previous one, with the
        configured noise models applied."""
        if name == "camera":
            self.world.deck.update_visuals()
        gen = rng if rng is not None else self._rngs.get(name)
        if gen is None:  # before the first reset_random: a fixed stream
            gen = self._rngs[name] = SeedStreams(0).generator(f"sensor.{name}")
        reading = self.world.sensors[name].read(state, dt, gen)
        if self.corruptors:
            reading = self._corrupt(reading, dt, rng)
        if self.faults:
            reading = apply_faults(self.faults, reading, state.time, dt, self._fault_rng(rng))
        return finite_reading(reading, self.world.config.tof.max_range, self.corruptors, self.faults)

    def _read_delayed(
        self, name: str, state: BodyState, exposing: bool, dt: float, rng: np.random.Generator | None
    ) -> dict[str, NDArray]:
        """The camera through its delay line: expose a frame now (``exposing``: a camera step, not
        yet exposed at this tick), then show the last frame due."""
        line = self.camera_pipeline
        assert line is not None
        if exposing:
            line.push(self.world.tick, self._take(name, state, dt, rng))
        for tick, reading in line.deliver(self.world.tick):
            self._held[name] = reading
            self.sample_times[name] = tick * self.world.dt
            self.frame_counts[name] += 1
        last = self._held.get(name)
        if last is None:
            cam = self.world.config.camera
            assert cam is not None
            return no_frame_reading(name, cam.width, cam.height)
        return {k: v.copy() for k, v in last.items()}

    def _read_clocked(
        self, name: str, state: BodyState, rng: np.random.Generator | None
    ) -> dict[str, NDArray]:
        """A sensor on its own clock: sampled now if a sample falls on this tick (or none was taken
        yet this episode), else its last sample."""
        clock = self.clocks[name]
        if name not in self._held or clock.last_index(self.world.tick) >= clock.next:
            self._store_clocked(name, state, rng)
        return {k: v.copy() for k, v in self._held[name].items()}

    def _store_clocked(self, name: str, state: BodyState, rng: np.random.Generator | None = None) -> None:
        clock = self.clocks[name]
        self._held[name] = dict(self._take(name, state, clock.period, rng))
        self.sample_times[name] = state.time
        clock.taken(self.world.tick)

    def due_samples(self) -> dict[int, list[str]]:
        """Physics tick -> the sensors on their own clock that sample there, over the next control
        period (after the current tick)."""
        due: dict[int, list[str]] = {}
        first, last = self.world.tick + 1, self.world.tick + self.world.config.substeps
        for name, clock in self.clocks.items():
            for tick in clock.pending(first, last):
                due.setdefault(tick, []).append(name)
        return due

    def sample_clocked(self, names: list[str], previous_velocity: tuple[float, ...]) -> None:
        """Sample ``names`` now, mid control step (acceleration over the last physics step)."""
        v_now = p.getBaseVelocity(self.world.quad.body, physicsClientId=self.world.client)[0]
        acc = (np.asarray(v_now) - np.asarray(previous_velocity)) / self.world.dt
        state = self.body_state(acc)
        for name in names:
            self._store_clocked(name, state)

    def _corrupt(
        self, reading: Mapping[str, NDArray], dt: float, rng: np.random.Generator | None
    ) -> dict[str, NDArray]:
        """``reading`` with the configured noise models applied (a ``<name>_valid`` mask, when the
        reading has one, travels with the values)."""
        out = dict(reading)
        for key, model in self.corruptors.items():
            if key not in out:
                continue
            value = np.asarray(out[key], dtype=np.float64)
            mask_key = f"{key}_valid"
            valid = (
                np.asarray(out[mask_key]).astype(bool).ravel()
                if mask_key in out
                else np.ones(value.size, bool)
            )
            gen = rng if rng is not None else self._rngs.get(f"noise.{key}")
            if gen is None:  # before the first reset_random: a fixed stream
                gen = self._rngs[f"noise.{key}"] = SeedStreams(0).generator(f"noise.{key}")
            noisy, ok = model.apply(value.ravel(), valid, dt, gen)
            out[key] = np.asarray(noisy, dtype=np.float64).reshape(value.shape)
            if mask_key in out:
                out[mask_key] = np.asarray(ok).astype(np.asarray(out[mask_key]).dtype)
        return out

    def _fault_rng(self, rng: np.random.Generator | None) -> Callable[[str], np.random.Generator]:
        """Fault name -> its stream (``rng`` when given; before the first reset_random a fixed one)."""

        def gen(name: str) -> np.random.Generator:
            if rng is not None:
                return rng
            key = f"fault.{name}"
            if key not in self._rngs:
                self._rngs[key] = SeedStreams(0).generator(key)
            return self._rngs[key]

        return gen

    @property
    def camera_time(self) -> float:
        """Simulated exposure time (s) of the camera frame last delivered (NaN: none yet this
        episode)."""
        for name in CAMERA_SENSORS:
            if name in self.sample_times:
                return self.sample_times[name]
        return math.nan

    def render_camera(self) -> NDArray[np.uint8]:
        """The downward camera's RGB image (H, W, 3) uint8."""
        if self.world.camera is None:
            raise RuntimeError("this world has no camera (camera=None in WorldConfig)")
        image: NDArray[np.uint8] = self.read_sensors(np.random.default_rng(0), ("camera",))["image"]
        return image

    def read_tof(self, rng: np.random.Generator) -> tuple[NDArray[np.float32], NDArray[np.int8]]:
        """ToF ``(ranges, ranges_valid)``, see :class:`~ihrcf_env.sim.sensors.ToFArray`."""
        r = self.read_sensors(rng, ("tof",))
        return r["ranges"], r["ranges_valid"]

    def imu(self, rng: np.random.Generator | None = None) -> dict[str, NDArray[np.float64]]:
        """IMU reading: attitude ``quaternion`` (x, y, z, w, world from body), body rates
        ``angular_velocity`` (rad/s, body frame) and specific force ``acceleration`` (m/s^2, body
        frame; reads +9.81 on z when hovering); see :class:`~ihrcf_env.sim.sensors.IMU`."""
        r = self.read_sensors(rng if rng is not None else np.random.default_rng(0), ("imu",))
        return {
            "quaternion": r["quaternion"],
            "angular_velocity": r["angular_velocity"],
            "acceleration": r["linear_acceleration"],
        }

    def deck_in_body(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ground-truth deck pose in the drone body frame: (position (3,) m, rotation R_body_deck)."""
        s = self.snapshot()
        return s.deck_position_body.copy(), s.deck_rotation_body.copy()

    def _drone_rotation(self, quat: tuple[float, ...]) -> NDArray[np.float64]:
        """``matrix_from_quat(quat)`` (read-only), memoised on the last quaternion (bit-exact): the
        snapshot and the sensors' body state of one instant share it."""
        key = _QUAT_KEY.pack(*quat)
        if key != self._rotation_key:
            self._rotation, self._rotation_key = _frozen(matrix_from_quat(quat)), key
        return self._rotation

    def snapshot(self) -> Snapshot:
        """Ground-truth state of drone and deck now (one read of the simulator).

        Memoised on the raw simulator state it is computed from (drone and deck poses and
        velocities, bit for bit): until that state changes -- a physics step, a reset, a teleport --
        every call returns the same Snapshot, whose arrays are read-only (copy to modify)."""
        self._check_open()
        cid, drone, plate = self.world.client, self.world.quad.body, self.world.deck.body
        pos, quat = p.getBasePositionAndOrientation(drone, physicsClientId=cid)
        vel = p.getBaseVelocity(drone, physicsClientId=cid)[0]
        deck_body_pos, deck_quat = p.getBasePositionAndOrientation(plate, physicsClientId=cid)
        deck_v, deck_w = p.getBaseVelocity(plate, physicsClientId=cid)
        key = _SNAPSHOT_KEY.pack(*pos, *quat, *vel, *deck_body_pos, *deck_quat, *deck_v, *deck_w)
        if key == self._snapshot_key and self._snapshot is not None:
            return self._snapshot
        R = self._drone_rotation(quat)
        pos_a = np.array(pos)
        deck_pos, R_wd = self.world.deck.pose_from_body(deck_body_pos, deck_quat)
        R_bd, p_bd = relative_pose(R, pos_a, R_wd, deck_pos)
        snap = Snapshot(
            drone_position=_frozen(pos_a),
            drone_rotation=R,
            drone_quaternion=_frozen(np.array(quat)),
            drone_velocity=_frozen(np.array(vel)),
            deck_position=_frozen(deck_pos),
            deck_rotation=_frozen(R_wd),
            deck_point_velocity=_frozen(rigid_point_velocity(deck_body_pos, deck_v, deck_w, pos)),
            deck_position_body=_frozen(p_bd),
            deck_rotation_body=_frozen(R_bd),
        )
        self._snapshot, self._snapshot_key = snap, key
        return snap


#: Packs the raw simulator state a :class:`Snapshot` is computed from into a bytes key (bit-exact:
#: tells -0.0 from 0.0 and NaN payloads apart, as float comparison would not).
_SNAPSHOT_KEY = struct.Struct("<23d")
_QUAT_KEY = struct.Struct("<4d")


def _frozen(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a`` made read-only (the memoised snapshot's arrays are shared by its callers)."""
    a.flags.writeable = False
    return a
