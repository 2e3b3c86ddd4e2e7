"""The numpy physics (``WorldConfig(physics="numpy")``) against PyBullet's rigid-body solver."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from ihrcf_env.config.vehicle import VelocityGains
from ihrcf_env.config.wind import WindParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.world import World


def _world(make_world: Any, physics: str, **kw: Any) -> World:
    cfg = WorldConfig(
        camera=None, gains=VelocityGains(wind_hold=True), ground_effect=True, physics=physics, **kw
    )
    w = make_world(cfg)
    w.add_disturbance(Wind(WindParams(mean_speed_min=9.0, mean_speed_max=9.0)))
    w.reset(paper_profile(), horizon_s=30.0, altitude=0.8)
    w.reset_random(np.random.default_rng(11))
    w.trim()
    return w


def _fly(w: World, steps: int) -> list[Any]:
    out = []
    for k in range(steps):
        w.set_velocity_setpoint(np.array([0.1 * math.sin(0.1 * k), 0.02, -0.15, 0.1]))
        td = w.step()
        s = w.sensing.snapshot()
        out.append((td, s.drone_position.copy(), s.drone_rotation.copy(), s.drone_velocity.copy()))
        if td is not None:
            break
    return out


def test_numpy_flight_follows_pybullet_until_touchdown(make_world: Any) -> None:
    """The same drone, deck, wind and commands: the two integrators stay together (the numpy one
    reproduces Bullet's step) and touch the deck at the same instant within a physics tick."""
    a = _fly(_world(make_world, "pybullet"), 200)
    b = _fly(_world(make_world, "numpy"), 200)
    n = min(len(a), len(b))
    for (td_a, pa, Ra, va), (td_b, pb, Rb, vb) in zip(a[: n - 1], b[: n - 1], strict=True):
        assert td_a is None and td_b is None
        np.testing.assert_allclose(pb, pa, atol=1e-9)
        np.testing.assert_allclose(Rb, Ra, atol=1e-9)
        np.testing.assert_allclose(vb, va, atol=1e-8)
    td_a, td_b = a[-1][0], b[-1][0]
    assert td_a is not None and td_b is not None, "the descent should reach the deck"
    assert td_a.body == td_b.body == "deck" and td_a.on_deck == td_b.on_deck
    assert abs(td_a.time - td_b.time) <= 1.0 / 240 + 1e-9
    assert td_b.relative_vertical_speed == pytest.approx(td_a.relative_vertical_speed, abs=0.02)
    assert td_b.relative_tilt == pytest.approx(td_a.relative_tilt, abs=0.01)


def test_numpy_physics_is_deterministic(make_world: Any) -> None:
    runs = [_fly(_world(make_world, "numpy"), 40) for _ in range(2)]
    for (_, pa, Ra, va), (_, pb, Rb, vb) in zip(*runs, strict=True):
        assert (pa == pb).all() and (Ra == Rb).all() and (va == vb).all()


def test_the_physics_backend_is_checked_by_name() -> None:
    with pytest.raises(ValueError, match="physics"):
        WorldConfig(physics="bullet")
    assert dataclasses.replace(WorldConfig(), physics="numpy").physics == "numpy"


@pytest.mark.parametrize("tof_noise", ["ideal", "realistic"])
def test_worlds_advanced_together_read_the_ranges_of_a_world_alone(make_world: Any, tof_noise: str) -> None:
    """Numpy worlds cast their ToF rays in closed form; advanced together, the rays of all are cast
    in one call (ranging.prefetch), and each world reads what it reads when advanced alone."""
    from ihrcf_env.config.sensors import ToFConfig
    from ihrcf_env.sim.batched.loop import advance

    def worlds() -> list[World]:
        out = []
        for k in range(3):
            w = _world(make_world, "numpy", tof=ToFConfig(noise=tof_noise))
            w.reset_random(np.random.default_rng(20 + k))
            out.append(w)
        return out

    together, alone = worlds(), worlds()
    assert together[0].tof.closed_form is not None
    hits = 0
    for k in range(30):
        for ws in (together, alone):
            for w in ws:
                w.set_velocity_setpoint(np.array([0.2 * math.sin(0.2 * k), -0.1, -0.1, 0.0]))
        advance(together)  # what World.step does for one world, for the three at once
        hits += sum(w.tof.prefetched is not None for w in together)
        for w in alone:
            w.step()
        for a, b in zip(together, alone, strict=True):
            ra, rb = a.sensing.read_sensors(), b.sensing.read_sensors()
            assert a.tof.prefetched is None  # taken by the reading
            np.testing.assert_array_equal(ra["ranges"], rb["ranges"])
            np.testing.assert_array_equal(ra["ranges_valid"], rb["ranges_valid"])
    assert hits == 3 * 30


def test_a_numpy_world_is_its_own_class_and_world_step_is_pybullet_only() -> None:
    import inspect

    from ihrcf_env.sim.batched.world import NumpyPhysicsWorld
    from ihrcf_env.sim.world import World

    w = World(WorldConfig(camera=None, physics="numpy"))
    try:
        assert type(w) is NumpyPhysicsWorld and isinstance(w, World)
    finally:
        w.close()
    plain = World(WorldConfig(camera=None))
    try:
        assert type(plain) is World
    finally:
        plain.close()
    # no batched-physics branch or vector-env handshake in the reference world's step
    source = inspect.getsource(World.step)
    assert "numpy" not in source and "advance" not in source
