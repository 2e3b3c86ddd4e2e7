"""GNSS/INS errors (ihrcf_env.fast.navigation) against sim.navigation.GNSSINSNavigation, float64:
the stationary start and 600 physics steps from the same draws, and the estimates."""

from __future__ import annotations

import jax
import numpy as np

from ihrcf_env.config.vehicle import NavigationErrors
from ihrcf_env.fast.navigation import nav_constants, nav_estimate, nav_start, nav_step
from ihrcf_env.sim.navigation import GNSSINSNavigation

from .fast_helpers import rel_err

DT = 1.0 / 240.0
STEPS = 600


def test_errors_and_estimates_match() -> None:
    errors = NavigationErrors()
    c = nav_constants(errors, DT)

    @jax.jit
    def run(z0, zs, pos, vel):
        st = nav_start(z0, c)

        def body(s, inp):
            z, p, v = inp
            s = nav_step(s, z, c)
            return s, (s, nav_estimate(s, p, v, c))

        _, (states, est) = jax.lax.scan(body, st, (zs, pos, vel))
        return states, est

    rng_v = np.random.default_rng(5)
    pos, vel = rng_v.normal(0, 1, (STEPS, 3)), rng_v.normal(0, 1, (STEPS, 3))
    for seed in range(3):
        nav = GNSSINSNavigation(errors, DT)
        nav.reset(np.random.default_rng(seed))
        rng = np.random.default_rng(seed)  # the same draws: the child seed, its start, its blocks
        child = np.random.default_rng(int(rng.integers(0, 2**63 - 1)))
        z0 = child.standard_normal((3, 3))
        zs = np.concatenate([child.standard_normal((256, 6)) for _ in range(3)])[:STEPS]
        times = (np.arange(STEPS) + 1) * DT
        want = [nav.estimate(float(t), tuple(p), tuple(v)) for t, p, v in zip(times, pos, vel, strict=True)]
        states, (p_est, v_est) = run(z0, zs, pos, vel)
        assert rel_err(p_est, np.array([w[0] for w in want])) < 1e-12
        assert rel_err(v_est, np.array([w[1] for w in want])) < 1e-12
        assert rel_err(states.ep[-1], nav.position_error) < 1e-12
