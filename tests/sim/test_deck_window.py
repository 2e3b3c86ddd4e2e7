"""The deck trajectory keeps a rolling window: memory does not grow with the episode, poses unchanged."""

from __future__ import annotations

import sys
import tracemalloc

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.profiles import paper_profile, sea_state_profile
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.sim.deck import DeckTrajectory

DT = 1 / 240
HALF = 0.02


def _reference(profile, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every tick's pose computed at once (what an unbounded trajectory holds)."""
    g = StewartGeometry()
    t = np.arange(n, dtype=np.float64) * DT
    offset, rpy = profile.sample(t)
    rot = Rotation.from_euler("ZYX", rpy[:, ::-1])
    position = g.home_position + offset
    body = position - rot.as_matrix()[:, :, 2] * HALF
    return position, rot.as_quat(), body


@pytest.mark.parametrize("profile", [paper_profile(), sea_state_profile(np.random.default_rng(3))])
def test_long_run_poses_are_those_of_the_whole_trajectory(profile) -> None:
    n = 30_000  # 125 s, 250 chunks of 0.5 s
    traj = DeckTrajectory(profile, StewartGeometry(), DT, 10.0, plate_half_thickness=HALF, chunk_s=0.5)
    position, quat, body = _reference(profile, n)
    for k in range(n):
        q, b = traj.body_target(k)
        assert q == quat[k].tolist() and b == body[k].tolist(), k  # bit-identical
        if k % 997 == 0:
            assert np.array_equal(traj.position[k], position[k])
            assert np.array_equal(traj.quaternion[k], quat[k])
            assert traj.times[k] == k * DT
    assert traj.first_tick > 0  # the early ticks were dropped


def test_stored_trajectory_does_not_grow_with_the_number_of_steps() -> None:
    traj = DeckTrajectory(paper_profile(), StewartGeometry(), DT, 10.0, HALF, chunk_s=1.0)
    assert traj.window == 480
    tracemalloc.start()
    try:
        sizes = {}
        for k in range(60_000):  # 250 s
            traj.body_target(k)
            assert traj.stored_ticks <= traj.window
            if k in (12_000, 59_999):
                sizes[k] = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert len(traj) >= 60_000
    # five times more steps, the same memory (the unbounded trajectory grew by ~5 KB per tick)
    assert sizes[59_999] - sizes[12_000] < 50_000


def test_a_chunk_is_kept_in_arrays_not_per_tick_python_objects() -> None:
    """Making a 30 s chunk allocates a few arrays, not two Python lists per tick (thousands of
    objects, and the garbage collector's passes over them, at every chunk)."""
    traj = DeckTrajectory(paper_profile(), StewartGeometry(), DT, 10.0, HALF, chunk_s=30.0)
    traj.body_target(0)
    before = sys.getallocatedblocks()
    traj.ensure(len(traj))  # the next chunk: 7200 ticks
    assert traj.stored_ticks == 2 * 7200
    assert sys.getallocatedblocks() - before < 1000
    q, b = traj.body_target(7300)
    assert isinstance(q, list) and len(q) == 4 and isinstance(b, list) and len(b) == 3
    assert all(isinstance(x, float) for x in q + b)


def test_ticks_out_of_the_window_are_refused() -> None:
    traj = DeckTrajectory(paper_profile(), StewartGeometry(), DT, 10.0, chunk_s=1.0)
    traj.ensure(2000)
    first = traj.first_tick
    assert first > 0
    with pytest.raises(IndexError, match=f"tick {first - 1}"):
        traj.position[first - 1]
    with pytest.raises(IndexError, match="tick 0"):
        traj.position[:10]
    with pytest.raises(IndexError, match="no longer kept"):
        traj.body_target(first - 1)
    rows = traj.position[first : first + 5]
    assert rows.shape == (5, 3)
    assert np.array_equal(rows[4], traj.position[first + 4])
    with pytest.raises(IndexError):
        traj.position[len(traj)]


def test_world_deck_poses_do_not_depend_on_the_window(make_world) -> None:
    """A long episode (past two 30 s chunks) drives the plate through the same poses as a trajectory
    that keeps everything."""
    runs = []
    for keep_all in (False, True):
        w = make_world(WorldConfig(camera=None))
        w.reset(paper_profile(), 30.0, altitude=1.0)
        traj = w.deck.trajectory
        assert traj is not None
        if keep_all:
            traj.window = 10**9
        poses = []
        for _ in range(1500):  # 75 s
            w.step()
            pos, R = w.deck.pose()
            poses.append(np.concatenate([pos, R.ravel()]))
        runs.append(np.array(poses))
        assert (traj.stored_ticks <= 2 * 7200) != keep_all
    assert np.array_equal(runs[0], runs[1])
