"""The simulated world: one PyBullet client holding the ground, the Stewart deck and the quadrotor.

Used without Gymnasium by tests and tools (calibration); the Gymnasium env wraps it. Every
PyBullet call passes this world's ``physicsClientId``; several worlds in one process are
independent.
"""

from __future__ import annotations

import math
import tempfile
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env import tasks
from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.wind import Disturbance
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.frames import matrix_from_quat, quat_from_matrix
from ihrcf_env.core.profiles import MotionProfile
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim.deck import Deck, DeckTrajectory
from ihrcf_env.sim.disturbances import disturbance_force
from ihrcf_env.sim.drone import Quadrotor, VelocityController
from ihrcf_env.sim.ground_effect import GroundEffect, deck_surface, rotor_positions
from ihrcf_env.sim.navigation import Navigation, make_navigation
from ihrcf_env.sim.sensing import CAMERA_SENSORS, Sensing
from ihrcf_env.sim.sensors import IMU, DownCamera, Sensor, ToFArray
from ihrcf_env.sim.sensors.base import TAG_CAMERA


def _release(client: int, tmp: tempfile.TemporaryDirectory[str]) -> None:
    """Disconnect ``client`` and remove ``tmp`` (a world's finalizer: also runs for a world that is
    dropped without ``close()``)."""
    try:
        p.disconnect(physicsClientId=client)
    except p.error:
        pass
    tmp.cleanup()


@dataclass
class Touchdown:
    """First contact of the drone with something during a control step (its figures from
    :func:`ihrcf_env.tasks.touchdown_state`)."""

    body: str  # "deck", "ground" or "base"
    time: float  # s
    relative_vertical_speed: float  # m/s, drone minus deck point, along the deck normal (negative = closing)
    relative_tilt: float  # rad, angle between drone z and deck z
    on_deck: bool  # drone centre projects inside the deck's top surface

    def task_state(self) -> tasks.TouchdownState:
        """This touchdown as the task rules' record (:class:`~ihrcf_env.tasks.TouchdownState`)."""
        return touchdown_arrays(self)


def touchdown_arrays(touchdown: Touchdown | None) -> tasks.TouchdownState:
    """``touchdown`` as the task rules' record (0-d arrays; no contact when None)."""
    if touchdown is None:
        return tasks.TouchdownState(
            np.asarray(tasks.NO_CONTACT), np.asarray(0.0), np.asarray(0.0), np.asarray(False)
        )
    return tasks.TouchdownState(
        contact=np.asarray(tasks.CONTACT_NAMES.index(touchdown.body)),
        relative_vertical_speed=np.asarray(touchdown.relative_vertical_speed, dtype=np.float64),
        relative_tilt=np.asarray(touchdown.relative_tilt, dtype=np.float64),
        on_deck=np.asarray(touchdown.on_deck),
    )


class World:
    """Ground + Stewart deck + quadrotor with its sensors in one explicit PyBullet client.

    The world builds, resets and steps the scene (contacts and touchdowns included). Sensors
    (:class:`~ihrcf_env.sim.sensors.Sensor`) are in :attr:`sensors`, by name, in reading order;
    :attr:`sensing` (:class:`~ihrcf_env.sim.sensing.Sensing`) reads them and the ground truth.
    Disturbances (:class:`~ihrcf_env.config.wind.Disturbance`) added with
    :meth:`add_disturbance` push the drone at every physics step.

    In velocity mode the autopilot closes its position and velocity loops on :attr:`navigation`'s
    estimate (:mod:`ihrcf_env.sim.navigation`: the truth, or a GNSS/INS estimate with drifting
    errors, per ``WorldConfig.navigation``); its attitude loop uses the true attitude and rates.
    :meth:`nav_position` / :meth:`nav_velocity` give the estimate the autopilot flies on.
    """

    def __init__(self, config: WorldConfig | None = None, gui: bool = False) -> None:
        self.config = config if config is not None else WorldConfig()
        self._closed = True  # until the client exists
        self.client = p.connect(p.GUI if gui else p.DIRECT)
        if self.client < 0:
            raise RuntimeError("could not start a PyBullet physics client" + (" with a GUI" if gui else ""))
        self._closed = False
        self._tmp = tempfile.TemporaryDirectory(prefix="ihrcf_env_")
        # released when the world is closed, garbage-collected or the interpreter exits
        self._finalizer = weakref.finalize(self, _release, self.client, self._tmp)
        try:
            self._build(gui)
        except BaseException:
            self.close()  # never leak a connected client or its temp dir
            raise

    def _build(self, gui: bool) -> None:
        cfg = self.config
        cid = self.client
        self.dt = 1.0 / cfg.physics_hz
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0, 0, -GRAVITY, physicsClientId=cid)
        p.setTimeStep(self.dt, physicsClientId=cid)
        if gui:
            p.configureDebugVisualizer(p.COV_ENABLE_GUI, 0, physicsClientId=cid)
        # Ground: collision only (no visual), so it costs the renderer nothing.
        # (A body without a visual shape would be drawn from its collision shape; a tiny hidden
        # sphere 50 m underground stands in as its visual.)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        hidden = p.createVisualShape(
            p.GEOM_SPHERE, radius=0.001, visualFramePosition=[0, 0, -50], physicsClientId=cid
        )
        self.ground = p.createMultiBody(
            baseMass=0, baseCollisionShapeIndex=plane, baseVisualShapeIndex=hidden, physicsClientId=cid
        )
        self.deck = Deck(cid, cfg.stewart, cfg.deck, Path(self._tmp.name))
        self.quad = Quadrotor(cid, cfg.quad)
        self.controller = VelocityController(self.quad, cfg.gains)
        rendered = cfg.camera is not None and cfg.camera_model == "rendered"
        self.camera = DownCamera(cid, cfg.camera, cfg.rig) if rendered and cfg.camera is not None else None
        self.tof = ToFArray(cid, cfg.tof, cfg.rig)
        self.imu_sensor = IMU.from_config(cfg.imu)
        self.navigation: Navigation = make_navigation(cfg.navigation, self.dt)
        self.sensors: dict[str, Sensor] = {}
        if cfg.camera is not None:
            self.sensors.update(self._camera_sensor(cfg.camera))
        self.sensors["tof"] = self.tof
        self.sensors["imu"] = self.imu_sensor
        from ihrcf_env.sim.registry import SENSORS

        for name in cfg.extra_sensors:
            self.sensors[name] = SENSORS[name].factory(self)
        for name in CAMERA_SENSORS:
            if name in self.sensors:
                self.sensors[name].update_interval = cfg.camera_every  # type: ignore[attr-defined]
        self.ground_effect = GroundEffect(cfg.quad.rotor_radius) if cfg.ground_effect else None
        self._motor_xy = cfg.quad.motor_xy.tolist()
        self.disturbances: list[Disturbance] = []
        self.tick = 0
        self._motor_cmd = [0.0] * 4
        self._acc_world = np.zeros(3)
        self._setpoint = (0.0, 0.0, 0.0, 0.0)
        self._mode_velocity = cfg.action_mode == "velocity"
        #: reading the sensors (noise models, faults, sample clocks, the camera's delay line) and
        #: the ground truth (:class:`~ihrcf_env.sim.sensing.Sensing`)
        self.sensing = Sensing(self)

    def _camera_sensor(self, camera: CameraConfig) -> dict[str, Sensor]:
        """The camera as configured: the image (``"camera"``), or the tag corners (:data:`TAG_CAMERA`)
        from a rendered window or the projected model."""
        cfg = self.config
        if self.camera is not None and cfg.camera_output == "image":
            return {"camera": self.camera}
        tag_size, tag_id = cfg.deck.tag_size, cfg.deck.tag_id
        if self.camera is not None:
            from ihrcf_env.sim.sensors.tag_window import WindowedTagCamera

            return {TAG_CAMERA: WindowedTagCamera(self.camera, self.deck, tag_size, tag_id)}
        from ihrcf_env.core.detector_model import DetectorModel
        from ihrcf_env.sim.sensors.tag_camera import ProjectedTagCamera

        model = cfg.detector_model if cfg.detector_model is not None else DetectorModel.load()
        return {TAG_CAMERA: ProjectedTagCamera(self.client, camera, cfg.rig, self.deck, tag_size, model)}

    # -- lifecycle -------------------------------------------------------------------------
    def reset(
        self,
        profile: MotionProfile,
        horizon_s: float,
        altitude: float = 1.0,
        offset_xy: tuple[float, float] = (0.0, 0.0),
        yaw: float = 0.0,
        stroke_checked: bool = False,
    ) -> None:
        """Start a new episode: deck on ``profile`` (stroke checked over ``horizon_s`` seconds unless
        ``stroke_checked`` says the caller did, as :func:`~ihrcf_env.core.ship.fits` does), drone
        hovering ``altitude`` m above the deck frame origin, shifted by ``offset_xy`` (world, m).
        Sensors and disturbances are reset by :meth:`reset_random` (they draw from the env's rng)."""
        self._check_open()
        traj = DeckTrajectory(
            profile,
            self.config.stewart,
            self.dt,
            horizon_s,
            plate_half_thickness=self.config.deck.thickness / 2,
            stroke_checked=stroke_checked,
        )
        self.tick = 0
        self.sensing.reset()
        self.deck.set_trajectory(traj)
        deck_pos, _ = self.deck.pose()
        start = np.array([deck_pos[0] + offset_xy[0], deck_pos[1] + offset_xy[1], deck_pos[2] + altitude])
        self.quad.reset(start, yaw, hover=True)
        self.controller.reset(start, yaw)
        self._motor_cmd = list(self.quad.rotor_speed)
        self._setpoint = (0.0, 0.0, 0.0, 0.0)
        self._acc_world = np.zeros(3)
        self.deck.update_visuals()

    def reset_random(self, streams: SeedStreams | np.random.Generator) -> None:
        """Draw this episode's random state (sensor biases, gusts, navigation errors), each subsystem
        from its own stream of ``streams`` (a Generator: streams keyed by one draw from it): sensor
        ``name`` from ``"sensor.<name>"``, the i-th disturbance from ``disturbance_streams[i]``
        (default ``"disturbance.<i>"``), the navigation estimate from ``"navigation"``. A sensor
        keeps drawing its per-reading noise from its stream. With an estimated navigation the
        position hold then engages on the estimate (as an autopilot's does), not on the truth."""
        if isinstance(streams, np.random.Generator):
            streams = SeedStreams.from_generator(streams)
        self.sensing.reset_random(streams)
        names = self.disturbance_streams
        for i, d in enumerate(self.disturbances):
            d.reset(streams.generator(names[i] if i < len(names) else f"disturbance.{i}"))
        nav = self.navigation
        nav.reset(streams.generator("navigation"))
        if not nav.ideal:
            pos, _, vel, _ = self.quad.state()
            est, _ = nav.estimate(self.time, pos, vel)
            self.controller.reset(np.asarray(est), self.controller.yaw_ref)

    def trim(self, keep_view: bool = False) -> NDArray[np.float64]:
        """Put the drone (placed by :meth:`reset`, after :meth:`reset_random`) in the state of an
        autopilot already holding position in the disturbances: leaning so that its thrust balances
        their force at rest at this instant (world, at zero velocity), rotors at that thrust, and the
        autopilot's disturbance estimate (or, on the classic loop, its integral) converged to it.
        With ``keep_view`` the drone is moved upwind so that the point the camera looked at before
        the trim (straight below, at the deck origin's height) lies on the tilted camera's optical
        axis. Returns the shift (world, m; zero without ``keep_view``)."""
        self._check_open()
        pos, quat, _, _ = self.quad.state()
        t = self.time
        f = np.zeros(3)
        for d in self.disturbances:
            f += np.asarray(disturbance_force(d, t, pos, (0.0, 0.0, 0.0)), dtype=np.float64)
        m = self.config.quad.mass
        thrust = np.array([-f[0], -f[1], m * GRAVITY - f[2]])
        norm = float(np.linalg.norm(thrust))
        if norm <= 0.0 or not np.isfinite(norm):
            return np.zeros(3)
        z = thrust / norm
        R = matrix_from_quat(np.asarray(quat, dtype=np.float64))
        yaw = math.atan2(R[1, 0], R[0, 0])
        xc = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        y = np.cross(z, xc)
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        R_new = np.column_stack([x, y, z])
        shift = np.zeros(3)
        if keep_view:
            depth = float(pos[2]) - float(self.deck.pose()[0][2])
            cam = R_new @ np.asarray(self.config.rig.camera_position, dtype=np.float64)
            axis = -z  # the camera looks along the body's -z
            depth_cam = depth + float(cam[2])
            # where the axis meets the plane depth_cam below the camera, relative to the drone
            hit = cam[:2] + axis[:2] * depth_cam / max(-float(axis[2]), 1e-6)
            shift[:2] = -hit
        new_pos = np.asarray(pos, dtype=np.float64) + shift
        q_new = [float(v) for v in quat_from_matrix(R_new)]
        p.resetBasePositionAndOrientation(
            self.quad.body, new_pos.tolist(), q_new, physicsClientId=self.client
        )
        p.resetBaseVelocity(self.quad.body, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)
        w = math.sqrt(norm / 4.0 / self.config.quad.kf)
        self.quad.rotor_speed = [w] * 4
        self._motor_cmd = list(self.quad.rotor_speed)
        ctrl = self.controller
        ctrl.p_ref = [ctrl.p_ref[0] + float(shift[0]), ctrl.p_ref[1] + float(shift[1]), ctrl.p_ref[2]]
        ctrl.trim(f / m)
        return shift

    def close(self) -> None:
        """Disconnect the client (and any a sensor holds: the tag window's tag scene) and remove
        temporary files; safe to call twice. A world dropped without ``close()`` releases its client
        when it is garbage-collected."""
        if self._closed:
            return
        self._closed = True
        for sensor in getattr(self, "sensors", {}).values():
            close = getattr(sensor, "close", None)
            if callable(close):
                try:
                    close()
                except p.error:
                    pass
        self._finalizer()

    @property
    def closed(self) -> bool:
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this world is closed (its PyBullet client was disconnected)")

    def add_disturbance(self, disturbance: Disturbance) -> None:
        """Apply ``disturbance``'s force to the drone at every physics step from now on."""
        if not isinstance(disturbance, Disturbance):
            raise TypeError(
                f"disturbance must have reset(rng) and __call__(t, position, velocity), got {disturbance!r}"
            )
        self.disturbances.append(disturbance)

    #: Stream names of the disturbances, by position (others: ``"disturbance.<i>"``); the env names
    #: its wind ``"wind"``, so user disturbances never shift the wind's draws.
    disturbance_streams: tuple[str, ...] = ()

    @property
    def time(self) -> float:
        return self.tick * self.dt

    # -- stepping --------------------------------------------------------------------------
    def set_velocity_setpoint(self, setpoint: NDArray[np.float64]) -> None:
        """(vx, vy, vz, yaw_rate) in m/s and rad/s, see :class:`VelocityController`."""
        sp = np.asarray(setpoint, dtype=np.float64)
        if sp.shape != (4,) or not np.isfinite(sp).all():
            raise ValueError(f"velocity setpoint must be 4 finite numbers, got {setpoint!r}")
        self._setpoint = tuple(sp.tolist())
        if not self._mode_velocity:  # coming from motor commands: hold from where the drone is now
            pos, R = self.drone_pose()
            if not self.navigation.ideal:
                pos = self.nav_position()
            self.controller.reset(pos, math.atan2(R[1, 0], R[0, 0]))
        self._mode_velocity = True

    def set_motor_thrusts(self, fractions: NDArray[np.float64]) -> None:
        """Per-motor thrust as a fraction of the maximum, clipped to [0, 1]."""
        f = np.clip(np.asarray(fractions, dtype=np.float64), 0.0, 1.0) * self.config.quad.max_thrust
        self._motor_cmd = self.quad.thrusts_to_speeds(f.tolist())
        self._mode_velocity = False

    def step(self) -> Touchdown | None:
        """Advance one control period (``substeps`` physics steps); return the first contact, if any."""
        self._check_open()
        cid = self.client
        quad, ctrl, deck = self.quad, self.controller, self.deck
        dt = self.dt
        first: Touchdown | None = None
        vel_mode = self._mode_velocity
        disturbances = self.disturbances
        nav = self.navigation
        truth = nav.ideal
        prev_vel: tuple[float, ...] = (0.0, 0.0, 0.0)
        body = quad.body
        get_pose, get_velocity = p.getBasePositionAndOrientation, p.getBaseVelocity
        half_thickness = self.config.deck.thickness / 2
        due = self.sensing.due_samples() if self.sensing.clocks else None
        for _ in range(self.config.substeps):
            deck.drive(self.tick)
            pos, quat = get_pose(body, physicsClientId=cid)  # quad.state(), inlined
            vel, omega = get_velocity(body, physicsClientId=cid)
            if not vel_mode:
                cmd = self._motor_cmd
            elif truth:
                cmd = ctrl.compute(self._setpoint, dt, pos, quat, vel, omega)
            else:  # position/velocity loops on the navigation estimate, attitude loop on the truth
                pos_est, vel_est = nav.estimate(self.tick * dt, pos, vel)
                cmd = ctrl.compute(self._setpoint, dt, pos_est, quat, vel_est, omega)
            scale = None
            if self.ground_effect is not None:
                deck_pos, deck_quat = get_pose(deck.body, physicsClientId=cid)
                point, rot = deck_surface(deck_pos, deck_quat, half_thickness)
                rotors = rotor_positions(pos, p.getMatrixFromQuaternion(quat), self._motor_xy)
                scale = self.ground_effect.thrust_scale(rotors, point, rot, deck.top_half_extent)
            quad.apply(cmd, dt, pos, quat, vel, thrust_scale=scale)
            if disturbances:
                t = self.tick * dt
                fx = fy = fz = 0.0
                for d in disturbances:
                    f = disturbance_force(d, t, pos, vel)
                    fx, fy, fz = fx + f[0], fy + f[1], fz + f[2]
                p.applyExternalForce(quad.body, -1, (fx, fy, fz), pos, p.WORLD_FRAME, physicsClientId=cid)
            prev_vel = vel
            p.stepSimulation(physicsClientId=cid)
            self.tick += 1
            if due and self.tick in due:
                self.sensing.sample_clocked(due[self.tick], vel)
            if first is None:
                first = self._check_contact(approach_velocity=vel)
        v_now = p.getBaseVelocity(quad.body, physicsClientId=cid)[0]
        self._acc_world = (np.asarray(v_now) - np.asarray(prev_vel)) / dt
        return first

    def _check_contact(self, approach_velocity: tuple[float, ...]) -> Touchdown | None:
        """Touchdown record if the drone touches anything after this physics step.

        The relative speed is taken from the drone's velocity *before* the step (the contact
        solver has already changed it after), against the deck point's velocity.
        """
        contacts = p.getContactPoints(bodyA=self.quad.body, physicsClientId=self.client)
        if not contacts:
            return None
        ids = {c[2] for c in contacts}
        body = "deck" if self.deck.body in ids else ("ground" if self.ground in ids else "base")
        return self.touchdown(body, approach_velocity)

    def touchdown(self, body: str, approach_velocity: tuple[float, ...]) -> Touchdown:
        """The :class:`Touchdown` record of a contact with ``body`` now, the drone having approached
        at ``approach_velocity`` (world, m/s)."""
        s = self.sensing.snapshot()
        td = tasks.touchdown_state(
            s.task_state(),
            tasks.CONTACT_NAMES.index(body),
            np.asarray(approach_velocity, dtype=np.float64),
            self.deck.top_half_extent,
        )
        return Touchdown(
            body=body,
            time=self.time,
            relative_vertical_speed=float(td.relative_vertical_speed),
            relative_tilt=float(td.relative_tilt),
            on_deck=bool(td.on_deck),
        )

    def contact_bodies(self) -> set[int]:
        """Ids of the bodies the drone touches now."""
        return {c[2] for c in p.getContactPoints(bodyA=self.quad.body, physicsClientId=self.client)}

    # -- sensing and ground truth ----------------------------------------------------------
    def drone_pose(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World position (m) and rotation matrix of the drone body frame."""
        pos, quat = p.getBasePositionAndOrientation(self.quad.body, physicsClientId=self.client)
        return np.asarray(pos), matrix_from_quat(quat)

    def nav_position(self) -> NDArray[np.float64]:
        """The autopilot's position estimate now (world, m): the truth, or the GNSS/INS estimate."""
        self._check_open()
        pos, _, vel, _ = self.quad.state()
        est, _ = self.navigation.estimate(self.time, pos, vel)
        return np.asarray(est, dtype=np.float64)

    def nav_velocity(self) -> NDArray[np.float64]:
        """The autopilot's velocity estimate now (world, m/s): the truth, or the GNSS/INS estimate."""
        self._check_open()
        pos, _, vel, _ = self.quad.state()
        _, est = self.navigation.estimate(self.time, pos, vel)
        return np.asarray(est, dtype=np.float64)
