"""One control period of flight (ihrcf_env.fast.advance) against the simulator's world
(sim.world.World.step: PyBullet's rigid-body solver and contacts), free-running over a windy
descent of more than five seconds to a touchdown on the moving deck, float64.

Before the touchdown, the drone's position, rotation and velocity after every control period
agree within :data:`FLIGHT_TOL` (measured on x86-64: 7.8e-16 over the descent). The touchdown:
the same body and outcome, PyBullet's contact within one physics tick of the closed-form test (it
may fall in the next control period)."""

from __future__ import annotations

import math
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pybullet as p

from ihrcf_env.config.vehicle import VelocityGains
from ihrcf_env.config.wind import WindParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.collision import drone_boxes
from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.fast import contact
from ihrcf_env.fast.advance import AdvanceConsts, Flight, advance
from ihrcf_env.fast.autopilot import ControllerState, gains_of
from ihrcf_env.fast.dynamics import DroneState, GroundEffectParams, drone_params
from ihrcf_env.fast.wind import wind_constants
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.world import World

from .bullet_ref import controller_state

WIND = WindParams(mean_speed_min=9.0, mean_speed_max=9.0)
#: Position (m), rotation-matrix and velocity (m/s) agreement over the flight before the touchdown.
FLIGHT_TOL = 1e-12
#: The contact codes' names, as the world's touchdowns give them.
CONTACT_NAMES = ("", "deck", "ground", "base")


def _world(make_world: Any) -> tuple[World, Wind]:
    cfg = WorldConfig(camera=None, gains=VelocityGains(wind_hold=True), ground_effect=True)
    w = make_world(cfg)
    wind = Wind(WIND)
    w.add_disturbance(wind)
    w.reset(paper_profile(), horizon_s=30.0, altitude=0.8)
    w.reset_random(np.random.default_rng(11))
    w.trim()
    return w, wind


def _consts(w: World) -> AdvanceConsts:
    cfg = w.config
    ge = w.ground_effect
    assert ge is not None
    half = w.deck.top_half_extent
    centres, halves = drone_boxes()
    reach = float(np.linalg.norm(contact.box_corners(centres, halves), axis=1).max()) + 0.01
    return AdvanceConsts(
        drone_params(cfg.quad),
        gains_of(cfg.gains),
        GroundEffectParams(
            jnp.asarray(ge.rotor_radius),
            jnp.asarray(ge.ground_height),
            jnp.asarray(ge.min_height_ratio),
            jnp.asarray(half),
        ),
        w.dt,
        cfg.substeps,
        half,
        cfg.deck.thickness,
        cfg.stewart.base_radius + 0.06,
        cfg.stewart.base_height,
        reach,
        np.asarray(centres),
        np.asarray(halves),
        wind_constants(WIND).drag,
    )


def _state(w: World) -> tuple[DroneState, ControllerState]:
    pos, quat = p.getBasePositionAndOrientation(w.quad.body, physicsClientId=w.client)
    vel, omega = p.getBaseVelocity(w.quad.body, physicsClientId=w.client)
    drone = DroneState(
        *(np.asarray(v, dtype=np.float64) for v in (pos, quat, vel, omega, w.quad.rotor_speed))
    )
    return drone, controller_state(w.controller)


def _deck_poses(w: World, tick: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(steps + 1, 3) plate body centres (m) and (steps + 1, 4) quaternions of the world's deck at
    the ticks ``tick .. tick + steps`` (its trajectory's targets)."""
    traj = w.deck.trajectory
    assert traj is not None
    poses = [traj.body_target(tick + j) for j in range(steps + 1)]
    return np.array([b for _, b in poses]), np.array([q for q, _ in poses])


def test_periods_match_the_world(make_world: Any) -> None:
    w, wind = _world(make_world)
    c = _consts(w)
    steps, dt = c.substeps, w.dt
    half_t = w.config.deck.thickness / 2
    run = jax.jit(lambda f, sp, top, q, air: advance(c, f, sp, top, q, air))
    worst = 0.0
    drone, ctrl = _state(w)
    z3 = np.zeros(3)
    flight = Flight(
        drone, ctrl, np.array(False), np.array(False), z3, np.array([0.0, 0, 0, 1]), np.array(0),
        np.array(0), z3, z3,
    )  # fmt: skip
    ref_end: tuple[str, bool, float] | None = None  # the touchdown: body, on the deck, time (s)
    jax_end: tuple[str, bool, float] | None = None
    tick = w.tick
    flown = 0  # control periods flown by both before either touched down
    for k in range(2000):  # free-running: the JAX state is carried from period to period
        sp = np.array([0.1 * math.sin(0.1 * k), 0.02, -0.08, 0.1])
        body, quat = _deck_poses(w, tick, steps)
        rot = np.stack([np.asarray(p.getMatrixFromQuaternion(q)).reshape(3, 3) for q in quat])
        top = body + rot[:, :, 2] * half_t
        air = wind.velocity_at((tick + np.arange(steps)) * dt)
        if ref_end is None:
            w.set_velocity_setpoint(sp)
            td = w.step()
            if td is not None:
                ref_end = (td.body, td.on_deck, td.time)
        if jax_end is None:
            flight = run(flight, sp, top, quat, air)
            if int(flight.code) != contact.NO_CONTACT:
                jax_end = (
                    CONTACT_NAMES[int(flight.code)],
                    bool(flight.on_deck),
                    (tick + int(flight.tick)) * dt,
                )
        tick += steps
        if ref_end is None and jax_end is None:
            flown += 1
            got, _ = _state(w)
            R_got = np.asarray(p.getMatrixFromQuaternion(got.quaternion)).reshape(3, 3)
            R_out = np.asarray(p.getMatrixFromQuaternion(np.asarray(flight.drone.quaternion))).reshape(3, 3)
            pairs = (
                (flight.drone.position, got.position),
                (R_out, R_got),
                (flight.drone.velocity, got.velocity),
            )
            for a, b in pairs:
                worst = max(worst, float(np.max(np.abs(np.asarray(a) - b))))
            assert worst < FLIGHT_TOL, (k, worst)
        elif ref_end is not None and jax_end is not None:
            break
        else:  # one has touched down: the other within a physics tick, so in this period or the next
            assert k <= flown + 1, (ref_end, jax_end)
    print(f"max |fast - world| (position, rotation, velocity) over the descent = {worst:.3g}")
    print(f"touchdowns: world {ref_end}, fast {jax_end}")
    assert ref_end is not None and jax_end is not None
    assert ref_end[:2] == jax_end[:2] == ("deck", True)
    assert abs(ref_end[2] - jax_end[2]) <= dt + 1e-9
    assert flown * steps * dt > 5.0  # over five seconds of flight before the touchdown
