"""The deck driven tick by tick (ihrcf_env.fast.deck_motion.deck_track) against
sim.deck.DeckTrajectory, float64: the profile's poses, then the stall at the first pose out of the
legs' stroke."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.core.profiles import SumOfSines, paper_profile
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.fast.deck_motion import DeckTrack, deck_pose, deck_track, sines_arrays, sum_of_sines
from ihrcf_env.sim.deck import DeckTrajectory

from .fast_helpers import rel_err

GEOM = StewartGeometry()
DT = 1.0 / 240.0
HALF = 0.01


@pytest.mark.parametrize("gain", [1.0, 4.0])
def test_deck_track_matches_trajectory(gain: float) -> None:
    base = paper_profile()
    prof = SumOfSines(tuple(tuple((a * gain, f, p) for a, f, p in dof) for dof in base.components))
    traj = DeckTrajectory(prof, GEOM, DT, 20.0, HALF, chunk_s=5.0, stroke_checked=True)
    ticks = np.arange(0, int(20.0 / DT))
    want_q, want_b = zip(*(traj.body_target(int(k)) for k in ticks), strict=True)
    a, f, p = sines_arrays(prof.components)
    geo = (
        jnp.asarray(GEOM.home_position), jnp.asarray(GEOM.top_joints), jnp.asarray(GEOM.base_joints),
        GEOM.min_leg, GEOM.max_leg, HALF,
    )  # fmt: skip

    @jax.jit
    def run(times):
        off0, rpy0 = sum_of_sines(times[0], a, f, p)
        pos0, R0 = deck_pose(off0, rpy0, geo[0])
        start = DeckTrack(pos0, R0, pos0 - R0[:, 2] * HALF, jnp.asarray(False))

        def body(prev, t):
            off, rpy = sum_of_sines(t, a, f, p)
            d = deck_track(prev, off, rpy, *geo)
            return d, d

        _, out = jax.lax.scan(body, start, times)
        return out

    out = run(ticks * DT)
    R_want = Rotation.from_quat(np.array(want_q)).as_matrix()
    assert rel_err(out.body, np.array(want_b)) < 1e-12
    assert rel_err(out.rotation, R_want) < 1e-12
    stalled = np.asarray(out.stalled)
    assert stalled.any() == (traj.stalled_at is not None) == (gain > 1.0)
    if traj.stalled_at is not None:
        first = int(np.argmax(stalled))
        assert abs(first * DT - traj.stalled_at) < 1e-9
