"""One control period of flight (ihrcf_env.fast.advance) against the numpy physics' loop
(sim.batched.loop.advance through World.step), free-running over a windy descent of more than
five seconds to a touchdown on the moving deck, float64."""

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
from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.fast import contact
from ihrcf_env.fast.advance import AdvanceConsts, Flight, advance
from ihrcf_env.fast.autopilot import ControllerState, gains_of
from ihrcf_env.fast.dynamics import DroneState, GroundEffectParams, drone_params
from ihrcf_env.fast.wind import wind_constants
from ihrcf_env.sim.batched import contact as np_contact
from ihrcf_env.sim.batched.loop import _AUTOPILOT_STATE, _deck_poses, _gather_autopilots
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.world import World

WIND = WindParams(mean_speed_min=9.0, mean_speed_max=9.0)


def _world(make_world: Any) -> tuple[World, Wind]:
    cfg = WorldConfig(camera=None, gains=VelocityGains(wind_hold=True), ground_effect=True, physics="numpy")
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
    centres, halves = np_contact.drone_boxes()
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
        np_contact.drone_radius(),
        np.asarray(centres),
        np.asarray(halves),
        wind_constants(WIND).drag,
    )


def _state(w: World) -> tuple[DroneState, ControllerState]:
    pos, quat = p.getBasePositionAndOrientation(w.quad.body, physicsClientId=w.client)
    vel, omega = p.getBaseVelocity(w.quad.body, physicsClientId=w.client)
    b = _gather_autopilots([w.controller])
    ctrl = ControllerState(*(np.asarray(getattr(b, k))[0] for k in _AUTOPILOT_STATE))
    drone = DroneState(
        *(np.asarray(v, dtype=np.float64) for v in (pos, quat, vel, omega, w.quad.rotor_speed))
    )
    return drone, ctrl


def test_periods_match_numpy_physics(make_world: Any) -> None:
    w, wind = _world(make_world)
    c = _consts(w)
    steps = c.substeps
    half_t = w.config.deck.thickness / 2
    run = jax.jit(lambda f, sp, top, q, air: advance(c, f, sp, top, q, air))
    worst = 0.0
    touched = None
    drone, ctrl = _state(w)
    z3 = np.zeros(3)
    flight = Flight(
        drone, ctrl, np.array(False), np.array(False), z3, np.array([0.0, 0, 0, 1]), np.array(0),
        np.array(0), z3, z3,
    )  # fmt: skip
    for k in range(2000):  # free-running: the JAX state is carried from period to period
        sp = np.array([0.1 * math.sin(0.1 * k), 0.02, -0.08, 0.1])
        body, quat = _deck_poses([w], steps)
        rot = np.stack([np.asarray(p.getMatrixFromQuaternion(q)).reshape(3, 3) for q in quat[0]])
        top = body[0] + rot[:, :, 2] * half_t
        air = wind.velocity_at((w.tick + np.arange(steps)) * w.dt)
        tick0 = w.tick
        w.set_velocity_setpoint(sp)
        td = w.step()
        out = flight = run(flight, sp, top, quat[0], air)
        got, _ = _state(w)
        reported = np.asarray(
            p.getQuaternionFromEuler(p.getEulerFromQuaternion(np.asarray(out.drone.quaternion)))
        )
        R_got = np.asarray(p.getMatrixFromQuaternion(got.quaternion)).reshape(3, 3)
        R_out = np.asarray(p.getMatrixFromQuaternion(reported)).reshape(3, 3)
        for a, b in ((out.drone.position, got.position), (R_out, R_got), (out.drone.velocity, got.velocity)):
            worst = max(worst, float(np.max(np.abs(np.asarray(a) - b))))
        assert worst < 1e-9, (k, worst)
        if td is None:
            assert int(out.code) == contact.NO_CONTACT
            continue
        assert np_contact.CONTACT_NAMES[int(out.code)] == td.body
        assert bool(out.on_deck) == td.on_deck
        assert abs((tick0 + int(out.tick)) * w.dt - td.time) < 1e-9
        touched = td
        break
    print(f"max |fast - numpy loop| (position, rotation, velocity) over the descent = {worst:.3g}")
    assert touched is not None and touched.on_deck
    assert k * steps * w.dt > 5.0  # over five seconds of flight before the touchdown
