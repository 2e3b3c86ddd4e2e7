"""Lockstep: the JAX landing step (ihrcf_env.fast.step) against the PyBullet env, v2 with the
projected camera, one episode per level (float64). Both run the same episode draws
(fast.episode.host_episode of the env's seed) and the same per-step noise (drawn from the env's
generators in its order, given to fast.step.step_with) under a scripted descent: more than five
seconds of slow flight with lateral and yaw commands, then down onto the deck.

Before the touchdown both backends integrate the same flight (the JAX tick reproduces Bullet's
step, tests/fast/test_dynamics.py): drone and deck poses agree to rounding. The ToF ranges
differ where a cone's rays meet the deck's edge or the Stewart base (Bullet's collision shapes
against the closed-form scene): compared by their agreement fraction and median. Touchdown:
Bullet's contact may fire one physics tick apart from the closed-form test; the outcome class must
agree."""

from __future__ import annotations

import math

import numpy as np
import pytest

from .lockstep_run import SLOW_STEPS, angle_between, params, run

SEED = 4
#: Pose agreement (m, rad) over the flight before the touchdown step.
POSE_TOL = 1e-8


def _check_level(level: str) -> None:
    r = run(level, SEED)
    n = len(r["reward"])  # control steps flown by both before either touched down
    assert n >= SLOW_STEPS, "the scripted flight lasts at least five seconds before the touchdown"
    dp = np.abs(r["drone_position"][:, 0] - r["drone_position"][:, 1]).max()
    da = angle_between(r["drone_quaternion"][:, 0], r["drone_quaternion"][:, 1]).max()
    kp = np.abs(r["deck_position"][:, 0] - r["deck_position"][:, 1]).max()
    ka = angle_between(r["deck_quaternion"][:, 0], r["deck_quaternion"][:, 1]).max()
    assert dp < POSE_TOL and da < POSE_TOL and kp < POSE_TOL and ka < POSE_TOL, (dp, da, kp, ka)
    # the observation's float32 values against float64 ones
    assert np.abs(r["nav_velocity"][:, 0] - r["nav_velocity"][:, 1]).max() < 1e-5
    assert np.abs(r["camera_age"][:, 0] - r["camera_age"][:, 1]).max() < 1e-6
    assert np.abs(r["reward"][:, 0] - r["reward"][:, 1]).max() < 1e-6
    assert np.array_equal(r["tag_status"][:, 0], r["tag_status"][:, 1])
    both = (r["tag_status"][:, 0] == 0)[:, None, None]
    corners = np.where(both, r["tag_corners"][:, 0] - r["tag_corners"][:, 1], 0.0)
    assert np.abs(corners).max() < 1e-2  # px (float32 observation)
    assert np.array_equal(r["ranges_valid"][:, 0], r["ranges_valid"][:, 1])
    dr = np.abs(r["ranges"][:, 0] - r["ranges"][:, 1])
    assert np.median(dr) < 1e-5 and np.mean(dr < 1e-3) > 0.9 and dr.max() < 0.1, (np.median(dr), dr.max())
    # touchdown on the deck within a physics tick, the same outcome class
    (t_ref, ok_ref), (t_jax, ok_jax) = r["ref_end"][0], r["jax_end"][0]
    assert math.isfinite(t_ref) and math.isfinite(t_jax)
    assert abs(t_ref - t_jax) <= params(level).dt + 1e-9
    assert ok_ref == ok_jax


def test_lockstep_calm() -> None:
    _check_level("calm")


@pytest.mark.slow
@pytest.mark.parametrize("level", ["moderate", "rough"])
def test_lockstep_windy_levels(level: str) -> None:
    _check_level(level)
