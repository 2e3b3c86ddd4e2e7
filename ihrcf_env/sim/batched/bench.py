"""Cost of one physics substep per drone: the batched numpy autopilot and dynamics at several N
against PyBullet, measured in the same run: ``python -m ihrcf_env.sim.batched.bench [--seconds S]``.

Rows (microseconds per drone per physics substep):

* ``numpy N=...``: :class:`~ihrcf_env.sim.batched.autopilot.BatchedVelocityController` plus
  :class:`~ihrcf_env.sim.batched.dynamics.BatchedQuadrotor` (the orientation as PyBullet reports
  it, the controller, the rotor lag, forces with per-rotor thrust factors and a wind force, the
  rigid-body step), with the split between the controller and the dynamics;
* ``pybullet drone``: the scalar controller, ``Quadrotor.apply``, the wind force and
  ``stepSimulation`` of a client holding only the drone;
* ``pybullet World``: :meth:`~ihrcf_env.sim.world.World.step` of the default world (deck driven,
  contacts checked) divided by its substeps.

PyBullet is imported only by the two PyBullet rows.

``--rays``: the cost per drone of one reading of the four ToF sensors' cones (the realistic
VL53L1X model, noise-free: ``cone_ranges``) instead, by :mod:`~ihrcf_env.sim.batched.ranging` at
several N against PyBullet's ``rayTestBatch`` in one world (``ToFArray.cone_ranges``).

``--camera``: the cost per world of one read of the projected tag camera (ideal quality, the tag in
view), by :class:`~ihrcf_env.sim.batched.tag_camera.BatchedTagCamera` at several N against
:meth:`ProjectedTagCamera.read <ihrcf_env.sim.sensors.tag_camera.ProjectedTagCamera.read>`.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.sim.batched.autopilot import BatchedVelocityController
from ihrcf_env.sim.batched.dynamics import BatchedQuadrotor

SIZES = (1, 8, 32, 128)
DT = 1.0 / 240


def bench_numpy(n: int, steps: int) -> tuple[float, float]:
    """(controller, dynamics) seconds per drone per substep for N drones hovering in wind."""
    from ihrcf_env.config.vehicle import QuadParams, VelocityGains

    params, gains = QuadParams(), VelocityGains(wind_hold=True)
    rng = np.random.default_rng(0)
    quad = BatchedQuadrotor(params, n)
    ctrl = BatchedVelocityController(params, gains, n)
    start = np.column_stack([rng.uniform(-1, 1, (n, 2)), np.full(n, 3.0)])
    yaw = rng.uniform(-math.pi, math.pi, n)
    quad.reset(start, yaw)
    ctrl.reset(start, yaw)
    setpoint = np.tile([0.3, -0.2, -0.1, 0.2], (n, 1))
    wind = np.tile([2.0, -1.0, 0.0], (n, 1))
    scale = np.ones((n, 4))
    t_ctrl = t_dyn = 0.0
    for _ in range(steps):
        t0 = time.perf_counter()
        q, r = quad.reported_quaternion(), quad.reported_rotation()
        cmd = ctrl.compute(setpoint, DT, quad.position, q, quad.velocity, quad.angular_velocity, r)
        t1 = time.perf_counter()
        quad.step(cmd, DT, thrust_scale=scale, force=wind)
        t2 = time.perf_counter()
        t_ctrl += t1 - t0
        t_dyn += t2 - t1
    return t_ctrl / (steps * n), t_dyn / (steps * n)


def bench_pybullet_drone(steps: int) -> float:
    """Seconds per substep of one drone alone in a PyBullet client (scalar controller)."""
    import pybullet as p

    from ihrcf_env.config.vehicle import QuadParams, VelocityGains
    from ihrcf_env.sim.drone import Quadrotor, VelocityController

    cid = p.connect(p.DIRECT)
    try:
        p.setGravity(0, 0, -GRAVITY, physicsClientId=cid)
        p.setTimeStep(DT, physicsClientId=cid)
        quad = Quadrotor(cid, QuadParams())
        quad.reset(np.array([0.0, 0.0, 3.0]), 0.3)
        ctrl = VelocityController(quad, VelocityGains(wind_hold=True))
        ctrl.reset(np.array([0.0, 0.0, 3.0]), 0.3)
        sp, wind = (0.3, -0.2, -0.1, 0.2), (2.0, -1.0, 0.0)
        t0 = time.perf_counter()
        for _ in range(steps):
            pos, quat = p.getBasePositionAndOrientation(quad.body, physicsClientId=cid)
            vel, omega = p.getBaseVelocity(quad.body, physicsClientId=cid)
            cmd = ctrl.compute(sp, DT, pos, quat, vel, omega)
            quad.apply(cmd, DT, pos, quat, vel)
            p.applyExternalForce(quad.body, -1, wind, pos, p.WORLD_FRAME, physicsClientId=cid)
            p.stepSimulation(physicsClientId=cid)
        return (time.perf_counter() - t0) / steps
    finally:
        p.disconnect(cid)


def bench_world(control_steps: int) -> float:
    """Seconds per physics substep of the default :class:`~ihrcf_env.sim.world.World`."""
    from ihrcf_env.core.profiles import StaticProfile
    from ihrcf_env.sim.world import World

    world = World()
    try:
        world.reset(StaticProfile(), horizon_s=control_steps * world.config.substeps * DT + 1.0, altitude=2.0)
        world.set_velocity_setpoint(np.array([0.3, -0.2, 0.0, 0.2]))
        t0 = time.perf_counter()
        for _ in range(control_steps):
            world.step()
        return (time.perf_counter() - t0) / (control_steps * world.config.substeps)
    finally:
        world.close()


def bench_rays(repeats: int) -> None:
    """Print microseconds per drone of the four cones' noise-free readings."""
    import pybullet as p
    from scipy.spatial.transform import Rotation

    from ihrcf_env.config.sensors import ToFConfig
    from ihrcf_env.config.world import WorldConfig
    from ihrcf_env.sim.batched.ranging import BatchedToF
    from ihrcf_env.sim.batched.rays import RayScene
    from ihrcf_env.sim.sensors.tof import ToFArray
    from ihrcf_env.sim.world import World

    world = World(WorldConfig(camera=None))
    try:
        cfg, tof_cfg = world.config, ToFConfig(noise="realistic")
        scene = RayScene.of(
            cfg.deck.size, cfg.deck.thickness, cfg.stewart.base_radius, cfg.stewart.base_height
        )
        tof = BatchedToF(cfg.rig.sensor_positions_body, tof_cfg.max_range, scene, tof_cfg.model)
        rng = np.random.default_rng(0)
        dp, dR = world.deck.pose()
        rays = 4 * tof_cfg.model.rays if tof_cfg.model is not None else 4
        print(f"microseconds per drone per reading of the four ToF cones ({rays} rays)")
        for n in SIZES:
            pos = dp + np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(0.3, 2.0, n)])
            R = Rotation.from_euler("xyz", rng.uniform(-0.3, 0.3, (n, 3))).as_matrix()
            deck = (np.tile(dp, (n, 1)), np.tile(dR, (n, 1, 1)))
            tof.cone_ranges(pos, R, *deck)  # warm-up
            t0 = time.perf_counter()
            for _ in range(repeats):
                tof.cone_ranges(pos, R, *deck)
            print(f"{'closed form N=' + str(n):<24}{(time.perf_counter() - t0) / (repeats * n) * 1e6:>10.2f}")
        bullet = ToFArray(world.client, tof_cfg, cfg.rig)
        quat = Rotation.from_euler("xyz", [0.1, -0.05, 0.3]).as_quat().tolist()
        p.resetBasePositionAndOrientation(
            world.quad.body, (dp + [0.1, 0.0, 1.0]).tolist(), quat, physicsClientId=world.client
        )
        pos1, R1 = world.drone_pose()
        bullet.cone_ranges(pos1, R1)
        t0 = time.perf_counter()
        for _ in range(repeats):
            bullet.cone_ranges(pos1, R1)
        print(f"{'pybullet rayTestBatch':<24}{(time.perf_counter() - t0) / repeats * 1e6:>10.2f}")
    finally:
        world.close()


def bench_camera(repeats: int) -> None:
    """Print microseconds per world per read of the projected tag camera (ideal quality)."""
    import pybullet as p
    from scipy.spatial.transform import Rotation

    from ihrcf_env.config.world import WorldConfig
    from ihrcf_env.core.detector_model import CornerTrack
    from ihrcf_env.core.profiles import StaticProfile
    from ihrcf_env.sim.batched.detector import BatchedCornerTrack
    from ihrcf_env.sim.batched.rays import RayScene
    from ihrcf_env.sim.batched.tag_camera import BatchedTagCamera
    from ihrcf_env.sim.sensors.base import TAG_CAMERA, BodyState
    from ihrcf_env.sim.sensors.tag_camera import ProjectedTagCamera
    from ihrcf_env.sim.world import World

    world = World(WorldConfig(camera_model="projected", camera_output="corners"))
    try:
        world.reset(StaticProfile(), horizon_s=1.0, altitude=1.0)
        cfg, cam = world.config, world.sensors[TAG_CAMERA]
        assert isinstance(cam, ProjectedTagCamera)
        scene = RayScene.of(
            cfg.deck.size, cfg.deck.thickness, cfg.stewart.base_radius, cfg.stewart.base_height
        )
        bcam = BatchedTagCamera(cam.camera, cfg.rig, scene, cfg.deck.tag_size, cam.model)
        rng = np.random.default_rng(0)
        dp, dR = world.deck.pose()
        print("microseconds per world per read of the projected tag camera (tag in view)")
        for n in SIZES:
            pos = dp + np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0.8, 2.0, n)])
            R = Rotation.from_euler("xyz", rng.uniform(-0.15, 0.15, (n, 3))).as_matrix()
            deck = (np.tile(dp, (n, 1)), np.tile(dR, (n, 1, 1)))
            rngs = [np.random.default_rng([0, i]) for i in range(n)]
            track = BatchedCornerTrack(n)
            track.reset(rngs)
            out = bcam.read(pos, R, *deck, track, rngs)  # warm-up
            t0 = time.perf_counter()
            for _ in range(repeats):
                bcam.read(pos, R, *deck, track, rngs)
            us = (time.perf_counter() - t0) / (repeats * n) * 1e6
            print(f"{'batched N=' + str(n):<24}{us:>10.2f}   ({int(out['tag_detected'].sum())}/{n} detected)")
        q = Rotation.from_euler("xyz", [0.1, -0.05, 0.3])
        pos1 = dp + np.array([0.1, 0.0, 1.0])
        p.resetBasePositionAndOrientation(
            world.quad.body, pos1.tolist(), q.as_quat().tolist(), physicsClientId=world.client
        )
        z = np.zeros(3)
        state = BodyState(0.0, pos1, q.as_matrix(), q.as_quat(), z, z, z)
        cam.track = CornerTrack(rng)
        assert cam.read(state, 0.05, rng)["tag_detected"]
        t0 = time.perf_counter()
        for _ in range(repeats):
            cam.read(state, 0.05, rng)
        print(f"{'scalar (rayTestBatch)':<24}{(time.perf_counter() - t0) / repeats * 1e6:>10.2f}")
    finally:
        world.close()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per row (default 2)")
    parser.add_argument("--rays", action="store_true", help="benchmark the ToF sensors' ray casts instead")
    parser.add_argument("--camera", action="store_true", help="benchmark the projected tag camera instead")
    args = parser.parse_args(argv)
    if args.rays:
        bench_rays(max(10, int(round(args.seconds * 100))))
        return
    if args.camera:
        bench_camera(max(10, int(round(args.seconds * 100))))
        return
    steps = max(10, int(round(args.seconds / DT)))
    us = 1e6
    print("microseconds per drone per physics substep (240 Hz)")
    print(f"{'row':<20}{'total':>10}{'control':>10}{'dynamics':>10}")
    for n in SIZES:
        bench_numpy(n, 5)  # warm-up
        c, d = bench_numpy(n, steps)
        print(f"{'numpy N=' + str(n):<20}{(c + d) * us:>10.2f}{c * us:>10.2f}{d * us:>10.2f}")
    print(f"{'pybullet drone':<20}{bench_pybullet_drone(steps) * us:>10.2f}")
    world_steps = max(2, steps // 8)
    print(f"{'pybullet World':<20}{bench_world(world_steps) * us:>10.2f}")


if __name__ == "__main__":
    main()

__all__ = [
    "DT",
    "SIZES",
    "bench_camera",
    "bench_numpy",
    "bench_pybullet_drone",
    "bench_rays",
    "bench_world",
    "main",
]
