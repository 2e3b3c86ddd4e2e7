"""One control step of the numpy physics for N worlds at once: :func:`advance`.

Each :class:`~ihrcf_env.sim.world.World` with ``physics="numpy"`` keeps its drone and deck bodies in
its PyBullet client (the sensors, the renderer and the ground truth read them there); between
control steps its flight is integrated here, over all the worlds given, on arrays:

1. gather each world's drone state (from its client), rotor speeds, autopilot state, command and
   the deck's poses over the control period (from its trajectory);
2. per physics tick: the navigation estimate and the disturbances (the worlds' own objects,
   :mod:`~ihrcf_env.sim.batched.external`), the autopilot
   (:mod:`~ihrcf_env.sim.batched.autopilot`), the ground effect
   (:mod:`~ihrcf_env.sim.batched.surface`), the rotors and the rigid-body step
   (:mod:`~ihrcf_env.sim.batched.dynamics`), then the sensors on their own clock that sample at
   this tick (their world written back first) and the first contact
   (:mod:`~ihrcf_env.sim.batched.contact`); after its first contact a drone rests on what it
   touched (it moves with the deck, or stays on the ground), as it would on its landing legs;
3. scatter: every world's final state written back to its client and its objects.

A row's arithmetic never depends on the other rows, so world ``i`` advances bit for bit as it
would alone (``advance([world])``, what ``World.step`` does).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pybullet as p
from numpy.typing import NDArray

from ihrcf_env.sim.batched import contact
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor
from ihrcf_env.sim.batched.external import ExternalInputs
from ihrcf_env.sim.batched.floatmath import matrices_from_quaternions
from ihrcf_env.sim.batched.ranging import prefetch
from ihrcf_env.sim.batched.surface import rotor_positions_batch, thrust_scale_batch
from ihrcf_env.sim.deck import angular_velocity_between
from ihrcf_env.sim.sensors.tag_camera import reading_row

if TYPE_CHECKING:
    from ihrcf_env.sim.drone import VelocityController
    from ihrcf_env.sim.world import Touchdown, World


def _check_group(worlds: Sequence[World]) -> None:
    if not worlds:
        raise ValueError("advance: no worlds")
    first = worlds[0].config
    for w in worlds:
        w._check_open()
        c = w.config
        if c.physics != "numpy":
            raise ValueError("advance: every world must have physics='numpy'")
        if (c.physics_hz, c.control_hz, c.quad, c.gains, c.ground_effect, c.deck, c.stewart) != (
            first.physics_hz,
            first.control_hz,
            first.quad,
            first.gains,
            first.ground_effect,
            first.deck,
            first.stewart,
        ):
            raise ValueError("advance: the worlds must share their physics configuration")


#: The per-drone state of :class:`BatchedVelocityController` (arrays with one row per drone).
_AUTOPILOT_STATE = (
    "p_ref",
    "yaw_ref",
    "integral",
    "disturbance",
    "_v_prev",
    "_has_v_prev",
    "_thrust_model",
    "_a_model",
    "_saturated",
    "_f_cmd",
)


def _gather_autopilots(controllers: Sequence[VelocityController]) -> BatchedVelocityController:
    """One batched autopilot holding the state of each world's scalar ``controllers`` (row ``i``:
    controller ``i``), which stay the worlds' record of it between control steps."""
    c0 = controllers[0]
    b = BatchedVelocityController(c0.quad.params, c0.gains, len(controllers))
    for i, c in enumerate(controllers):
        b.p_ref[i] = c.p_ref
        b.yaw_ref[i] = c.yaw_ref
        b.integral[i] = c.integral
        b.disturbance[i] = c.disturbance
        b._has_v_prev[i] = c._v_prev is not None
        b._v_prev[i] = c._v_prev if c._v_prev is not None else (0.0, 0.0)
        b._thrust_model[i] = c._thrust_model
        b._a_model[i] = c._a_model
        b._saturated[i] = c._saturated
        b._f_cmd[i] = c._f_cmd
    return b


def _scatter_autopilots(b: BatchedVelocityController, controllers: Sequence[VelocityController]) -> None:
    """The batched state back into each world's scalar controller (the inverse of the gather)."""
    for i, c in enumerate(controllers):
        c.p_ref = b.p_ref[i].tolist()
        c.yaw_ref = float(b.yaw_ref[i])
        c.integral = b.integral[i].tolist()
        c.disturbance = b.disturbance[i].tolist()
        c._v_prev = (float(b._v_prev[i, 0]), float(b._v_prev[i, 1])) if b._has_v_prev[i] else None
        c._thrust_model = float(b._thrust_model[i])
        c._a_model = (float(b._a_model[i, 0]), float(b._a_model[i, 1]))
        c._saturated = bool(b._saturated[i])
        c._f_cmd = (float(b._f_cmd[i, 0]), float(b._f_cmd[i, 1]))


def _autopilot_state(b: BatchedVelocityController) -> dict[str, NDArray]:
    return {k: np.array(getattr(b, k), copy=True) for k in _AUTOPILOT_STATE}


def _restore_rows(b: BatchedVelocityController, kept: dict[str, NDArray], rows: NDArray[np.bool_]) -> None:
    for k, v in kept.items():
        a = np.array(getattr(b, k), copy=True)
        a[rows] = v[rows]
        setattr(b, k, a)


def _deck_poses(worlds: Sequence[World], steps: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(N, steps + 1, 3) plate body centres (m) and (N, steps + 1, 4) quaternions of each world's
    deck at its ticks ``tick .. tick + steps``."""
    n = len(worlds)
    body = np.empty((n, steps + 1, 3))
    quat = np.empty((n, steps + 1, 4))
    for i, w in enumerate(worlds):
        traj = w.deck.trajectory
        assert traj is not None
        for j in range(steps + 1):
            q, b = traj.body_target(w.tick + j)
            quat[i, j] = q
            body[i, j] = b
    return body, quat


def _write_back(w: World, quad: BatchedQuadrotor, i: int, deck: tuple[list, list, tuple, tuple]) -> None:
    """World ``w``'s drone (row ``i`` of ``quad``) and deck state into its client (what the sensors
    and the ground truth read)."""
    cid = w.client
    p.resetBasePositionAndOrientation(
        w.quad.body, quad.position[i].tolist(), quad.quaternion[i].tolist(), physicsClientId=cid
    )
    p.resetBaseVelocity(
        w.quad.body, quad.velocity[i].tolist(), quad.angular_velocity[i].tolist(), physicsClientId=cid
    )
    body_pos, body_quat, v, om = deck
    p.resetBasePositionAndOrientation(w.deck.body, body_pos, body_quat, physicsClientId=cid)
    p.resetBaseVelocity(w.deck.body, v, om, physicsClientId=cid)


def _deck_state(
    body: NDArray[np.float64], quat: NDArray[np.float64], i: int, j: int, dt: float
) -> tuple[list, list, tuple, tuple]:
    """World ``i``'s plate at its tick ``j`` of this step: pose and the velocity that brought it
    there from tick ``j - 1`` (the finite difference PyBullet's driven plate carries)."""
    b1, q1 = body[i, j].tolist(), quat[i, j].tolist()
    if j == 0:
        return b1, q1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    b0, q0 = body[i, j - 1], quat[i, j - 1]
    v = ((b1[0] - b0[0]) / dt, (b1[1] - b0[1]) / dt, (b1[2] - b0[2]) / dt)
    return b1, q1, v, angular_velocity_between(q0.tolist(), q1, dt)


def advance(worlds: Sequence[World]) -> list[Touchdown | None]:
    """Advance every world of ``worlds`` by one control step (module docstring); returns each
    world's first contact in that step, or None."""
    _check_group(worlds)
    n = len(worlds)
    cfg = worlds[0].config
    steps, dt = cfg.substeps, worlds[0].dt
    half_thickness = cfg.deck.thickness / 2

    quad = BatchedQuadrotor(cfg.quad, n)
    for i, w in enumerate(worlds):
        pos, quat = p.getBasePositionAndOrientation(w.quad.body, physicsClientId=w.client)
        vel, omega = p.getBaseVelocity(w.quad.body, physicsClientId=w.client)
        quad.position[i], quad.quaternion[i], quad.velocity[i], quad.angular_velocity[i] = (
            pos,
            quat,
            vel,
            omega,
        )
        quad.rotor_speed[i] = w.quad.rotor_speed
    quad.invalidate()
    autopilot = _gather_autopilots([w.controller for w in worlds])
    velocity_rows = np.array([w._mode_velocity for w in worlds])
    setpoints = np.array([w._setpoint for w in worlds], dtype=np.float64)
    motor_cmd = np.array([w._motor_cmd for w in worlds], dtype=np.float64)
    deck_body, deck_quat = _deck_poses(worlds, steps)
    deck_rot = matrices_from_quaternions(deck_quat)  # (N, steps + 1, 3, 3)
    deck_top = deck_body + deck_rot[..., :, 2] * half_thickness
    due = [w.sensing.due_samples() if w.sensing.clocks else {} for w in worlds]
    ticks0 = np.array([w.tick for w in worlds], dtype=np.int64)
    touchdowns: list[Touchdown | None] = [None] * n
    latched = np.zeros(n, dtype=bool)
    rel_pos = np.zeros((n, 3))  # latched drones: pose in the frame of what they rest on
    rel_quat = np.zeros((n, 4))
    on_deck = np.zeros(n, dtype=bool)
    outside = ExternalInputs(worlds, ticks0, steps, dt)
    clocked_rows = [i for i in range(n) if due[i]]
    reach = contact.drone_radius()
    ge = worlds[0].ground_effect
    half = worlds[0].deck.top_half_extent
    base_radius = cfg.stewart.base_radius + 0.06
    base_height = cfg.stewart.base_height
    motor_xy = cfg.quad.motor_xy
    all_velocity = bool(velocity_rows.all())
    prev_vel = quad.velocity.copy()
    for j in range(steps):
        pos, vel = quad.position, quad.velocity
        quat = quad.reported_quaternion()
        rot = quad.reported_rotation()
        omega = quad.angular_velocity
        pos_c, vel_c = outside.navigation(j, pos, vel) if outside.navigating else (pos, vel)
        if all_velocity:
            cmd = autopilot.compute(setpoints, dt, pos_c, quat, vel_c, omega, rotation=rot)
        else:  # rows on motor commands: their autopilot state stays as it was (as in World.step)
            kept = _autopilot_state(autopilot)
            cmd = np.where(
                velocity_rows[:, None],
                autopilot.compute(setpoints, dt, pos_c, quat, vel_c, omega, rotation=rot),
                motor_cmd,
            )
            _restore_rows(autopilot, kept, ~velocity_rows)
        scale = None
        if ge is not None:
            rotors = rotor_positions_batch(pos, rot, motor_xy)
            scale = thrust_scale_batch(ge, rotors, deck_top[:, j], deck_rot[:, j], half)
        external = outside.forces(j, pos, vel)
        prev_vel = quad.velocity.copy()
        quad.step(cmd, dt, thrust_scale=scale, force=external)
        if latched.any():
            _rest(quad, np.flatnonzero(latched), on_deck, rel_pos, rel_quat, deck_top, deck_quat, j, dt)
        due_now = [(i, names) for i in clocked_rows if (names := due[i].get(int(ticks0[i]) + j + 1))]
        for i, _ in due_now:
            worlds[i].tick = int(ticks0[i]) + j + 1
            _write_back(worlds[i], quad, i, _deck_state(deck_body, deck_quat, i, j + 1, dt))
        _prefetch_ranges([worlds[i] for i, names in due_now if "tof" in names])
        for i, names in due_now:
            worlds[i].sensing.sample_clocked(names, tuple(prev_vel[i].tolist()))
        # contacts: only drones whose bounding sphere reaches the deck's plane or the ground
        near = ~latched & (
            (quad.position[:, 2] < reach + base_height)
            | (
                _plane_distance(quad.position, deck_top[:, j + 1], deck_rot[:, j + 1])
                < reach + cfg.deck.thickness
            )
        )
        if near.any():
            rows = np.flatnonzero(near)
            codes = np.zeros(n, dtype=np.int8)
            codes[rows] = contact.first_contact(
                quad.position[rows],
                matrices_from_quaternions(quad.quaternion[rows]),
                deck_top[rows, j + 1],
                deck_rot[rows, j + 1],
                half,
                cfg.deck.thickness,
                base_radius,
                base_height,
            )
            for i in np.flatnonzero(codes != contact.NO_CONTACT).tolist():
                w = worlds[i]
                w.tick = int(ticks0[i]) + j + 1
                _write_back(w, quad, i, _deck_state(deck_body, deck_quat, i, j + 1, dt))
                touchdowns[i] = w.touchdown(contact.CONTACT_NAMES[codes[i]], tuple(prev_vel[i].tolist()))
                latched[i] = True
                on_deck[i] = codes[i] == contact.DECK
                if on_deck[i]:
                    rel_pos[i], rel_quat[i] = relative_pose(
                        quad.position[i], quad.quaternion[i], deck_top[i, j + 1], deck_quat[i, j + 1]
                    )
                else:
                    rel_pos[i], rel_quat[i] = quad.position[i], quad.quaternion[i]
                _rest(quad, np.array([i]), on_deck, rel_pos, rel_quat, deck_top, deck_quat, j, dt)
    for i, w in enumerate(worlds):
        w.tick = int(ticks0[i]) + steps
        _write_back(w, quad, i, _deck_state(deck_body, deck_quat, i, steps, dt))
        w._acc_world = (quad.velocity[i] - prev_vel[i]) / dt
        w.quad.rotor_speed = quad.rotor_speed[i].tolist()
    _scatter_autopilots(autopilot, [w.controller for w in worlds])
    _prefetch_ranges([w for w in worlds if "tof" not in w.sensing.clocks])  # read at the control step
    _prefetch_camera(worlds)
    return touchdowns


def _prefetch_camera(worlds: Sequence[World]) -> None:
    """Read the projected tag cameras (closed-form rays) that the worlds' next sensor reads take,
    in one batched read per camera set-up (each from its world's generator and corner track)."""
    ahead = [a for a in (w.sensing.camera_ahead() for w in worlds) if a is not None]
    groups: list[list[int]] = []
    for k, (cam, _, _) in enumerate(ahead):
        assert cam.batched is not None
        group = next((g for g in groups if cam.batched.same_as(ahead[g[0]][0].batched)), None)  # type: ignore[arg-type]
        if group is None:
            groups.append([k])
        else:
            group.append(k)
    for rows in groups:
        if len(rows) < 2:  # alone, the world's own read casts them
            continue
        cams = [ahead[k][0] for k in rows]
        keys = [cam.poses_key(ahead[k][1]) for cam, k in zip(cams, rows, strict=True)]
        batched = cams[0].batched
        assert batched is not None
        states = [ahead[k][1] for k in rows]
        imaging: dict[str, Any] = {}
        if batched.realistic:
            imaging = {
                "velocity": np.stack([st.velocity for st in states]).astype(np.float64),
                "angular_velocity": np.stack([st.angular_velocity for st in states]).astype(np.float64),
                "episodes": [cam.episode for cam in cams],
            }
        out = batched.read(
            np.stack([st.position for st in states]).astype(np.float64),
            np.stack([st.rotation for st in states]).astype(np.float64),
            np.stack([key[1] for key in keys]),
            np.stack([key[2] for key in keys]),
            [cam.track for cam in cams],
            [ahead[k][2] for k in rows],
            **imaging,
        )
        for m, (cam, k) in enumerate(zip(cams, rows, strict=True)):
            cam.prefetched = (keys[m][0], ahead[k][2], reading_row(out, m))


def _prefetch_ranges(worlds: Sequence[World]) -> None:
    """Cast the closed-form ToF rays of ``worlds`` at their state now in one batched call, for
    their readings that follow (one world alone casts its own when it reads)."""
    ranged = [w for w in worlds if w.tof.closed_form is not None]
    if len(ranged) > 1:
        prefetch([w.tof for w in ranged], [w.sensing.body_state() for w in ranged])


def _plane_distance(
    position: NDArray[np.float64], plane_point: NDArray[np.float64], plane_rotation: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N,) distance (m) of each point from its deck's top plane, along the deck normal (column 2)."""
    d = position - plane_point
    return np.abs(
        d[:, 0] * plane_rotation[:, 0, 2]
        + d[:, 1] * plane_rotation[:, 1, 2]
        + d[:, 2] * plane_rotation[:, 2, 2]
    )


def _rest(
    quad: BatchedQuadrotor,
    rows: NDArray[np.intp],
    on_deck: NDArray[np.bool_],
    rel_pos: NDArray[np.float64],
    rel_quat: NDArray[np.float64],
    deck_top: NDArray[np.float64],
    deck_quat: NDArray[np.float64],
    j: int,
    dt: float,
) -> None:
    """Drones ``rows`` rest where they touched down, at their tick ``j + 1`` of this step: on the
    deck they move with it (pose fixed in the deck frame, velocity of that material point over the
    last tick); elsewhere they stay still."""
    for i in rows:
        if on_deck[i]:
            pos0, quat0 = compose(deck_top[i, j], deck_quat[i, j], rel_pos[i], rel_quat[i])
            pos, quat = compose(deck_top[i, j + 1], deck_quat[i, j + 1], rel_pos[i], rel_quat[i])
            quad.velocity[i] = (pos - pos0) / dt
            quad.angular_velocity[i] = angular_velocity_between(quat0.tolist(), quat.tolist(), dt)
            quad.position[i], quad.quaternion[i] = pos, quat
        else:
            quad.position[i], quad.quaternion[i] = rel_pos[i], rel_quat[i]
            quad.velocity[i] = 0.0
            quad.angular_velocity[i] = 0.0
    quad.invalidate()


def _quat_mul(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hamilton product ``a b`` of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ]
    )


def relative_pose(
    pos: NDArray[np.float64],
    quat: NDArray[np.float64],
    frame_pos: NDArray[np.float64],
    frame_quat: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The pose ``(pos, quat)`` (world) expressed in the frame ``(frame_pos, frame_quat)``."""
    R = matrices_from_quaternions(frame_quat[None])[0]
    inv = np.array([-frame_quat[0], -frame_quat[1], -frame_quat[2], frame_quat[3]])
    return R.T @ (pos - frame_pos), _quat_mul(inv, quat)


def compose(
    frame_pos: NDArray[np.float64],
    frame_quat: NDArray[np.float64],
    rel_pos: NDArray[np.float64],
    rel_quat: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The world pose of ``(rel_pos, rel_quat)`` given in the frame ``(frame_pos, frame_quat)``."""
    R = matrices_from_quaternions(frame_quat[None])[0]
    return frame_pos + R @ rel_pos, _quat_mul(frame_quat, rel_quat)


__all__ = [
    "advance",
    "compose",
    "relative_pose",
]
