"""Deck motion (ihrcf_env.fast.deck_motion) against core.profiles, core.ship and core.stewart,
float64: the ship's realisation from the same uniform draws, its poses over time, the
sum-of-sines profile and the Stewart leg lengths."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.core.ship import ShipOptions, ship_profile
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.fast.deck_motion import (
    deck_pose,
    leg_lengths,
    ship_constants,
    ship_motion,
    ship_phasor,
    ship_phasor_advance,
    ship_pose,
    ship_pose_of_phasor,
    sines_arrays,
    sum_of_sines,
)

from .fast_helpers import Counted, rel_err

GEOM = StewartGeometry()
TIMES = np.linspace(0.0, 30.0, 200)


@pytest.mark.parametrize("sea", [3, 5])
def test_ship_realisation_and_poses_match(sea: int) -> None:
    opts = ShipOptions(sea_state=sea)
    c = ship_constants(opts)
    n = opts.n_components
    want = ship_profile(np.random.default_rng(sea), opts)
    rng = np.random.default_rng(sea)  # the same stream: ship_profile's two uniform draws
    u_omega, u_phase = rng.random(n), rng.random(n)

    def poses(uo, up):
        m = ship_motion(uo, up, c)
        return m, jax.vmap(lambda t: ship_pose(t, m, c))(TIMES)

    m, (offset, rpy) = jax.jit(poses)(u_omega, u_phase)
    assert rel_err(m.omega_e, want.omega_e) < 1e-12
    scale = np.abs(want.amplitudes).max()
    # relative to the largest component (the far tail of the spectrum is ~1e-30 of it)
    assert np.abs(np.asarray(m.re) - want.amplitudes.real).max() < 1e-12 * scale
    assert np.abs(np.asarray(m.im) - want.amplitudes.imag).max() < 1e-12 * scale
    off_w, rpy_w = want.sample(TIMES)
    assert np.abs(np.asarray(offset) - off_w).max() < 1e-9 * max(np.abs(off_w).max(), 1e-3)
    assert np.abs(np.asarray(rpy) - rpy_w).max() < 1e-9 * max(np.abs(rpy_w).max(), 1e-3)


SINES = Counted(lambda t, a, f, p: sum_of_sines(t, a, f, p), in_axes=(0, None, None, None))


def test_sum_of_sines_matches() -> None:
    prof = paper_profile()
    a, f, p = sines_arrays(prof.components)
    offset, rpy = SINES(TIMES, a, f, p)
    off_w, rpy_w = prof.sample(TIMES)
    assert rel_err(offset, off_w) < 1e-12 and rel_err(rpy, rpy_w) < 1e-12


def _legs(off, rpy):
    pos, R = deck_pose(off, rpy, GEOM.home_position)
    return leg_lengths(pos, R, GEOM.top_joints, GEOM.base_joints), R


LEGS = Counted(_legs)


def test_leg_lengths_match() -> None:
    rng = np.random.default_rng(0)
    n = 256
    off = rng.uniform(-0.08, 0.08, (n, 3))
    rpy = rng.uniform(-0.15, 0.15, (n, 3))
    legs, R = LEGS(off, rpy)
    R_want = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    assert rel_err(R, R_want) < 1e-12
    want = GEOM.leg_lengths(GEOM.home_position + off, R_want)
    assert rel_err(legs, want) < 1e-12
    assert rel_err(LEGS(np.zeros((n, 3)), np.zeros((n, 3)))[0][0], GEOM.neutral_lengths) < 1e-12


def test_ship_phasor_recurrence_tracks_direct_poses() -> None:
    """10 s of physics ticks by the phasor recurrence against the pose evaluated at each time."""
    opts = ShipOptions(sea_state=5)
    c = ship_constants(opts)
    rng = np.random.default_rng(7)
    dt, steps = 1.0 / 240.0, 2400
    want = ship_profile(np.random.default_rng(7), opts)
    uo, up = rng.random(opts.n_components), rng.random(opts.n_components)

    @jax.jit
    def run(uo, up):
        m = ship_motion(uo, up, c)

        def body(ph, _):
            pose = ship_pose_of_phasor(ph, m, c)
            return ship_phasor_advance(ph), pose

        _, poses = jax.lax.scan(body, ship_phasor(0.5, dt, m, c), None, length=steps)
        return poses

    offset, rpy = run(uo, up)
    t = 0.5 + dt * np.arange(steps)
    off_w, rpy_w = want.sample(t)
    assert np.abs(np.asarray(offset) - off_w).max() < 1e-9 * np.abs(off_w).max()
    assert np.abs(np.asarray(rpy) - rpy_w).max() < 1e-9 * np.abs(rpy_w).max()
