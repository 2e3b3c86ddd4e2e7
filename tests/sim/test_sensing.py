"""The world's sensing (:class:`~ihrcf_env.sim.sensing.Sensing`, ``World.sensing``): owned by the
world, reset with it, and released with it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import connected_clients

from ihrcf_env import tasks
from ihrcf_env.config.sensors import ToFConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.sensing import Sensing, Snapshot
from ihrcf_env.sim.world import World


def test_the_world_owns_its_sensing(make_world) -> None:
    w = make_world(WorldConfig(camera=None, tof=ToFConfig(rate_hz=30.0)))
    assert isinstance(w.sensing, Sensing) and set(w.sensing.clocks) == {"tof"}
    w.reset(StaticProfile(), 10.0, altitude=1.0)
    w.reset_random(np.random.default_rng(0))
    r = w.sensing.read_sensors()
    assert r["ranges"].shape == (4,) and w.sensing.sample_times["imu"] == 0.0
    w.step()
    w.sensing.read_sensors()
    assert w.sensing.sample_times["imu"] == pytest.approx(w.time)
    w.reset(StaticProfile(), 10.0, altitude=1.0)  # a new episode: nothing read yet
    assert all(math.isnan(t) for t in w.sensing.sample_times.values())


def test_snapshot_is_the_task_rules_state(make_world) -> None:
    w = make_world(WorldConfig(camera=None))
    w.reset(StaticProfile(), 10.0, altitude=0.8)
    s = w.sensing.snapshot()
    assert isinstance(s, Snapshot) and w.sensing.snapshot() is s  # memoised until the state changes
    state = s.task_state()
    assert isinstance(state, tasks.TaskState) and state.drone_position is s.drone_position
    assert s.relative_tilt == float(tasks.relative_tilt(s.drone_rotation, s.deck_rotation))
    assert float(tasks.tag_offset(state)) == pytest.approx(0.0, abs=1e-9)


def test_touchdown_uses_the_task_rules(make_world) -> None:
    w = make_world(WorldConfig(camera=None))
    w.reset(StaticProfile(), 10.0, altitude=0.8)
    td = w.touchdown("deck", (0.0, 0.0, -0.3))
    s = w.sensing.snapshot()
    closing = float((np.array([0.0, 0.0, -0.3]) - s.deck_point_velocity) @ s.deck_rotation[:, 2])
    assert td.body == "deck" and td.on_deck and td.relative_vertical_speed == closing
    arrays = td.task_state()
    assert int(arrays.contact) == tasks.CONTACT_DECK and bool(arrays.on_deck)


def test_a_dropped_world_releases_its_client_though_its_sensing_is_kept() -> None:
    before = connected_clients()
    w = World(WorldConfig(camera=None))
    sensing = w.sensing
    assert connected_clients() == before + 1
    del w  # no cycle through the sensing: released at once
    assert connected_clients() == before
    with pytest.raises(RuntimeError, match="closed"):
        sensing.snapshot()
