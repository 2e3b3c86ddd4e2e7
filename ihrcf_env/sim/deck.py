"""The Stewart-platform deck in PyBullet: a heavy dynamic plate driven along a trajectory by velocity.

The plate is a dynamic rigid body (hundreds of kg, isotropic inertia, no damping). Before every
physics step its linear and angular velocity are set so that one step of Bullet's semi-implicit
Euler integration lands it on the next pose of the trajectory (the linear velocity is
pre-compensated for one step of gravity). The deck therefore has a real velocity, and a drone
resting on it is carried along by friction. The tag and the six legs are visual-only bodies placed
where the plate and the inverse kinematics say, before every camera render.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pybullet as p
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ihrcf_env.config.world import DeckConfig
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.frames import matrix_from_quat, quat_from_matrix
from ihrcf_env.core.profiles import MotionProfile, profile_leg_lengths, sample_until_unusable
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.sim.assets import asset_path, tag_texture
from ihrcf_env.tasks.episode import STROKE_CHECK_DT


class TickSeries:
    """A per-tick series of a :class:`DeckTrajectory` (``times``, ``position`` or ``quaternion``),
    indexed by the absolute physics tick: ``series[k]`` (one row) or ``series[a:b]`` (rows of ticks
    a..b-1, step 1). Only the ticks the trajectory still keeps (``first_tick`` to ``len - 1``) can
    be read; an older or not yet computed tick raises IndexError naming it."""

    def __init__(self, trajectory: DeckTrajectory, attr: str) -> None:
        self._traj = trajectory
        self._attr = attr

    def __len__(self) -> int:
        return len(self._traj)

    def _rows(self) -> NDArray[np.float64]:
        rows: NDArray[np.float64] = getattr(self._traj, self._attr)
        return rows

    def _index(self, k: int) -> int:
        first, end = self._traj.first_tick, len(self._traj)
        if k < 0:
            k += end
        if not first <= k < end:
            raise IndexError(
                f"deck trajectory tick {k} is not kept: ticks {first}..{end - 1} are (the trajectory keeps "
                f"a rolling window of {self._traj.window} ticks)"
            )
        return k - first

    def __getitem__(self, key: int | slice) -> NDArray[np.float64]:
        if isinstance(key, slice):
            start, stop, step = key.indices(len(self._traj))
            if step != 1:
                raise IndexError("deck trajectory slices take step 1")
            if stop <= start:
                return self._rows()[:0].copy()
            return self._rows()[self._index(start) : self._index(stop - 1) + 1].copy()
        return self._rows()[self._index(int(key))].copy()

    def __array__(self, dtype: object = None, copy: object = None) -> NDArray[np.float64]:
        """The rows kept (ticks ``first_tick`` to ``len - 1``)."""
        return np.asarray(self._rows(), dtype=dtype)  # type: ignore[call-overload]


class DeckTrajectory:
    """Deck poses at every physics tick: ``position[k]``, ``quaternion[k]`` (x, y, z, w) at time
    ``times[k] = k * dt``, world frame (deck frame origin = tag centre on the top surface).

    The profile is checked against the legs' stroke on a 20 Hz grid over ``check_horizon_s`` when
    the trajectory is made (ValueError naming the time and the leg), unless ``stroke_checked``
    says the caller has checked that grid already (:func:`~ihrcf_env.core.ship.fits`). Physics-rate poses are
    computed in chunks of ``chunk_s`` seconds as the simulation reaches them; should a chunk
    beyond the checked horizon leave the stroke (or the profile give no usable pose, see
    :func:`~ihrcf_env.core.profiles.sample_until_unusable`), the deck stops at its last reachable pose
    (``stalled_at`` gives the time) instead of failing mid-episode.

    Memory does not grow with the episode: only the last :attr:`window` ticks made (two chunks) are
    kept, from :attr:`first_tick` on (:class:`TickSeries` raises IndexError for older ones). Each
    chunk is computed from its own times alone, so the poses do not depend on the window.
    """

    CHECK_DT = STROKE_CHECK_DT

    def __init__(
        self,
        profile: MotionProfile,
        geometry: StewartGeometry,
        dt: float,
        check_horizon_s: float,
        plate_half_thickness: float = 0.0,
        chunk_s: float = 30.0,
        stroke_checked: bool = False,
    ) -> None:
        if not (math.isfinite(check_horizon_s) and check_horizon_s > 0):
            raise ValueError(f"check_horizon_s must be positive (s), got {check_horizon_s!r}")
        self.profile = profile
        self.geometry = geometry
        self.dt = dt
        self._half = plate_half_thickness
        self._chunk = max(1, int(round(chunk_s / dt)))
        #: ticks kept: the chunk being driven through and the one before it
        self.window = 2 * self._chunk
        if not stroke_checked:
            t = np.arange(0.0, check_horizon_s + self.CHECK_DT, self.CHECK_DT)
            geometry.check_stroke(t, profile_leg_lengths(profile, geometry, t))
        self.stalled_at: float | None = None
        #: the absolute tick of the first row kept, and the number of ticks made so far
        self.first_tick = 0
        self._end = 0
        self._times = np.zeros(0)
        self._position = np.zeros((0, 3))
        self._quaternion = np.zeros((0, 4))
        #: plate body centre (deck origin - half thickness * deck z) per tick kept (row i = tick
        #: first_tick + i), for the per-physics-step driver
        self._body_position = np.zeros((0, 3))
        self.ensure(0)

    @property
    def times(self) -> TickSeries:
        """Times (s) of the ticks kept, indexed by absolute tick."""
        return TickSeries(self, "_times")

    @property
    def position(self) -> TickSeries:
        """(3,) deck frame origin (world, m) per tick kept, indexed by absolute tick."""
        return TickSeries(self, "_position")

    @property
    def quaternion(self) -> TickSeries:
        """(4,) deck orientation (x, y, z, w), world from deck, per tick kept, indexed by absolute tick."""
        return TickSeries(self, "_quaternion")

    @property
    def stored_ticks(self) -> int:
        """Number of ticks held in memory (at most :attr:`window`)."""
        return len(self._times)

    def ensure(self, tick: int) -> None:
        """Make sure poses up to physics tick ``tick`` exist (extends by whole chunks, then drops the
        ticks older than the :attr:`window`)."""
        while tick >= self._end and self.stalled_at is None:
            k0 = self._end
            t = (k0 + np.arange(self._chunk, dtype=np.float64)) * self.dt
            offset, rpy = sample_until_unusable(self.profile, t)  # unusable pose: NaN, stalls
            rot = Rotation.from_euler("ZYX", rpy[:, ::-1])
            position = self.geometry.home_position + offset
            matrices = rot.as_matrix()
            legs = self.geometry.leg_lengths(position, matrices)
            bad = np.flatnonzero(
                np.any(
                    (legs < self.geometry.min_leg) | (legs > self.geometry.max_leg) | ~np.isfinite(legs),
                    axis=1,
                )
            )
            n = len(t) if bad.size == 0 else int(bad[0])
            if bad.size:
                self.stalled_at = float(t[n])
                if k0 + n == 0:  # cannot even start: let check_stroke name the leg
                    self.geometry.check_stroke(t, legs)
            quat = rot.as_quat()[:n]
            drop = max(0, self._end + n - self.first_tick - self.window)  # oldest rows out of the window
            self._times = np.concatenate([self._times[drop:], t[:n]])
            self._position = np.concatenate([self._position[drop:], position[:n]])
            self._quaternion = np.concatenate([self._quaternion[drop:], quat])
            body = position[:n] - matrices[:n, :, 2] * self._half
            self._body_position = np.concatenate([self._body_position[drop:], body])
            self.first_tick += drop
            self._end += n

    def body_target(self, tick: int) -> tuple[list[float], list[float]]:
        """(quaternion (x, y, z, w), plate body centre (m)) of the pose at ``tick`` (plain lists),
        or of the last pose made if ``tick`` is beyond it (a stalled or unfinished trajectory)."""
        if tick >= self._end:
            self.ensure(tick)
            tick = min(tick, self._end - 1)
        i = tick - self.first_tick
        if i < 0:
            raise IndexError(f"deck trajectory tick {tick} is no longer kept (first kept: {self.first_tick})")
        # one row at a time (a chunk's rows as Python lists at once is thousands of allocations)
        return self._quaternion[i].tolist(), self._body_position[i].tolist()

    def __len__(self) -> int:
        """Number of ticks made so far (kept or not)."""
        return self._end


def angular_velocity_between(q_from: Sequence[float], q_to: Sequence[float], dt: float) -> tuple[float, ...]:
    """World-frame angular velocity (rad/s) that rotates ``q_from`` into ``q_to`` in ``dt`` seconds."""
    # q_to * conj(q_from), written out (physics rate: no call or tuple overhead)
    ax, ay, az, aw = q_to
    bx, by, bz, bw = -q_from[0], -q_from[1], -q_from[2], q_from[3]
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        return (2 * x / dt, 2 * y / dt, 2 * z / dt)
    k = 2.0 * math.atan2(s, w) / (s * dt)
    return (x * k, y * k, z * k)


def rigid_point_velocity(
    origin: Sequence[float],
    v: Sequence[float],
    w: Sequence[float],
    point: Sequence[float] | NDArray[np.float64],
) -> NDArray[np.float64]:
    """Velocity ``v + w x (point - origin)`` of a rigid body's material point (scalar maths, the
    same operations and rounding as ``v + np.cross(w, point - origin)``)."""
    px, py, pz = map(float, point)
    rx, ry, rz = px - origin[0], py - origin[1], pz - origin[2]
    w0, w1, w2 = w
    return np.array([v[0] + (w1 * rz - w2 * ry), v[1] + (w2 * rx - w0 * rz), v[2] + (w0 * ry - w1 * rx)])


class Deck:
    """Plate, tag, legs and base of the Stewart platform in one PyBullet client."""

    def __init__(self, client: int, geometry: StewartGeometry, config: DeckConfig, texture_dir: Path) -> None:
        self.client = client
        self.geometry = geometry
        self.config = config
        cid = client
        half = config.thickness / 2
        # Plate: collision top = deck frame origin; the visual top sits 1 mm lower so the tag quad,
        # exactly on the collision surface, never z-fights with it.
        col = p.createCollisionShape(
            p.GEOM_BOX, halfExtents=[config.size / 2, config.size / 2, half], physicsClientId=cid
        )
        vis = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=[config.size / 2, config.size / 2, half - 0.0005],
            visualFramePosition=[0, 0, -0.0005],
            rgbaColor=[0.72, 0.74, 0.76, 1],
            physicsClientId=cid,
        )
        self.body = p.createMultiBody(
            baseMass=config.mass,
            baseCollisionShapeIndex=col,
            baseVisualShapeIndex=vis,
            basePosition=[0, 0, geometry.home_height - half],
            useMaximalCoordinates=True,
            physicsClientId=cid,
        )
        i_iso = config.mass * (config.size**2) / 6.0
        p.changeDynamics(
            self.body,
            -1,
            mass=config.mass,
            localInertiaDiagonal=[i_iso, i_iso, i_iso],
            linearDamping=0.0,
            angularDamping=0.0,
            lateralFriction=config.friction,
            physicsClientId=cid,
        )
        self._half = half

        # Tag: textured quad (visual only).
        tex_file = texture_dir / f"tag36h11_{config.tag_id}.png"
        cv2.imwrite(str(tex_file), tag_texture(config.tag_id))
        quad_edge = config.tag_size * 10 / 8
        tag_vis = p.createVisualShape(
            p.GEOM_MESH,
            fileName=str(asset_path("tag_quad.obj")),
            meshScale=[quad_edge, quad_edge, 1.0],
            physicsClientId=cid,
        )
        self.tag_body = p.createMultiBody(baseMass=0, baseVisualShapeIndex=tag_vis, physicsClientId=cid)
        tex = p.loadTexture(str(tex_file), physicsClientId=cid)
        p.changeVisualShape(
            self.tag_body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=cid
        )

        # Legs: a housing from the base joint and a rod from the top joint (telescoping look).
        self._leg_part = 0.45
        housing = p.createVisualShape(
            p.GEOM_CYLINDER,
            radius=0.022,
            length=self._leg_part,
            rgbaColor=[0.25, 0.27, 0.3, 1],
            physicsClientId=cid,
        )
        rod = p.createVisualShape(
            p.GEOM_CYLINDER,
            radius=0.012,
            length=self._leg_part,
            rgbaColor=[0.8, 0.8, 0.82, 1],
            physicsClientId=cid,
        )
        self.leg_bodies = [
            (
                p.createMultiBody(baseMass=0, baseVisualShapeIndex=housing, physicsClientId=cid),
                p.createMultiBody(baseMass=0, baseVisualShapeIndex=rod, physicsClientId=cid),
            )
            for _ in range(6)
        ]
        # Base: a static disc on the ground carrying the base joints.
        r_base = geometry.base_radius + 0.06
        base_col = p.createCollisionShape(
            p.GEOM_CYLINDER, radius=r_base, height=geometry.base_height, physicsClientId=cid
        )
        base_vis = p.createVisualShape(
            p.GEOM_CYLINDER,
            radius=r_base,
            length=geometry.base_height,
            rgbaColor=[0.3, 0.32, 0.36, 1],
            physicsClientId=cid,
        )
        self.base_body = p.createMultiBody(
            baseMass=0,
            baseCollisionShapeIndex=base_col,
            baseVisualShapeIndex=base_vis,
            basePosition=[0, 0, geometry.base_height / 2],
            physicsClientId=cid,
        )
        self.trajectory: DeckTrajectory | None = None

    # -- driving ---------------------------------------------------------------------------
    def set_trajectory(self, trajectory: DeckTrajectory) -> None:
        """Use ``trajectory`` (built with ``plate_half_thickness = config.thickness / 2``) and place
        the plate at its first pose with its velocity."""
        self.trajectory = trajectory
        self._tick = 0
        pos, quat = trajectory.position[0], trajectory.quaternion[0]
        body_pos = pos + matrix_from_quat(quat)[:, 2] * -self._half
        p.resetBasePositionAndOrientation(
            self.body, body_pos.tolist(), quat.tolist(), physicsClientId=self.client
        )
        self.drive(0)

    def drive(self, tick: int) -> None:
        """Set the plate velocity so the next physics step ends on trajectory pose ``tick + 1``.

        Past the trajectory's end the deck holds its last pose.
        """
        traj = self.trajectory
        assert traj is not None
        dt = traj.dt
        q_t, target = traj.body_target(tick + 1)
        pos_now, q_now = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        v = (
            (target[0] - pos_now[0]) / dt,
            (target[1] - pos_now[1]) / dt,
            (target[2] - pos_now[2]) / dt + GRAVITY * dt,
        )
        w = angular_velocity_between(q_now, q_t, dt)
        p.resetBaseVelocity(self.body, v, w, physicsClientId=self.client)

    # -- state -----------------------------------------------------------------------------
    def pose(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World pose of the deck frame: (position (3,), rotation (3, 3))."""
        pos, quat = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        return self.pose_from_body(pos, quat)

    def pose_from_body(
        self, body_pos: Sequence[float], body_quat: Sequence[float]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`pose` from the plate body's PyBullet position and quaternion (already read)."""
        R = matrix_from_quat(body_quat)
        return np.array(body_pos) + R[:, 2] * self._half, R

    def velocity(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """World linear velocity of the plate's centre of mass and angular velocity (m/s, rad/s)."""
        v, w = p.getBaseVelocity(self.body, physicsClientId=self.client)
        return np.asarray(v), np.asarray(w)

    def point_velocity(self, point_world: NDArray[np.float64]) -> NDArray[np.float64]:
        """World velocity (m/s) of the deck's material point at ``point_world``."""
        pos, _ = p.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        v, w = p.getBaseVelocity(self.body, physicsClientId=self.client)
        return rigid_point_velocity(pos, v, w, point_world)

    def leg_lengths(self) -> NDArray[np.float64]:
        """Current leg lengths (m) from the inverse kinematics of the plate's actual pose."""
        pos, R = self.pose()
        return self.geometry.leg_lengths(pos, R)

    def update_visuals(self) -> None:
        """Place the tag and legs at the plate's current pose (call before rendering)."""
        cid = self.client
        pos, R = self.pose()
        quat = quat_from_matrix(R)
        p.resetBasePositionAndOrientation(self.tag_body, pos.tolist(), quat.tolist(), physicsClientId=cid)
        tops = self.geometry.top_joints_world(pos, R)
        bases = self.geometry.base_joints
        for (housing, rod), b, t in zip(self.leg_bodies, bases, tops, strict=True):
            d = t - b
            length = float(np.linalg.norm(d))
            u = d / length
            # rotation taking +z to u
            axis = np.cross([0.0, 0.0, 1.0], u)
            s = float(np.linalg.norm(axis))
            angle = math.atan2(s, u[2])
            q = (
                [0.0, 0.0, 0.0, 1.0]
                if s < 1e-12
                else [*(axis / s * math.sin(angle / 2)), math.cos(angle / 2)]
            )
            half_part = self._leg_part / 2
            p.resetBasePositionAndOrientation(housing, (b + u * half_part).tolist(), q, physicsClientId=cid)
            p.resetBasePositionAndOrientation(rod, (t - u * half_part).tolist(), q, physicsClientId=cid)

    @property
    def top_half_extent(self) -> float:
        return self.config.size / 2


__all__ = [
    "Deck",
    "DeckTrajectory",
    "TickSeries",
    "angular_velocity_between",
    "rigid_point_velocity",
]
