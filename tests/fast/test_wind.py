"""Wind (ihrcf_env.fast.wind) against sim.disturbances.Wind, float64: the episode's mean wind and
gusts from the same draws, the wind over time and the force it adds."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from ihrcf_env.config.wind import WindParams
from ihrcf_env.fast.wind import wind_constants, wind_episode, wind_force, wind_velocity
from ihrcf_env.sim.disturbances import Wind

from .fast_helpers import rel_err

TIMES = np.linspace(0.0, 15.0, 301)
BLOCKS = 2  # gust samples drawn: 2 blocks of Wind.BLOCK


def draws(seed: int):
    """The draws Wind.reset makes from a generator of ``seed`` (mean speed, direction, the gust
    generator's seed, its stationary start and blocks of normals)."""
    rng = np.random.default_rng(seed)
    u_speed, u_dir = rng.random(), rng.random()
    child = np.random.default_rng(int(rng.integers(2**63)))
    normals = [child.standard_normal(3)[None]] + [
        child.standard_normal((Wind.BLOCK, 3)) for _ in range(BLOCKS)
    ]
    return u_speed, u_dir, np.concatenate(normals)


@pytest.mark.parametrize(
    "params",
    [
        WindParams(),
        WindParams(turbulence=0.0),
        WindParams(mean_speed_min=3.0, mean_speed_max=8.0, turbulence=2.0),
    ],
)
def test_wind_matches_simulator(params: WindParams) -> None:
    c = wind_constants(params)
    velocities, forces, wants, want_forces = [], [], [], []
    v = np.random.default_rng(99).normal(0, 2, (len(TIMES), 3))  # the drone's velocities

    @jax.jit
    def run(us, ud, nm, t):
        ep = wind_episode(us, ud, nm, c)
        return jax.vmap(lambda ti: wind_velocity(ti, ep, c))(t)

    for seed in range(4):
        w = Wind(params)
        w.reset(np.random.default_rng(seed))
        us, ud, nm = draws(seed)
        air = run(us, ud, nm, TIMES)
        want = w.velocity_at(TIMES)
        velocities.append(np.asarray(air))
        wants.append(want)
        f = jax.vmap(lambda vv, aa: wind_force(vv, aa, c.drag))(v, air)
        forces.append(np.asarray(f))
        want_forces.append(
            np.array([w(t, (0.0, 0.0, 0.0), tuple(vi)) for t, vi in zip(TIMES, v, strict=True)])
        )
    assert rel_err(np.stack(velocities), np.stack(wants)) < 1e-12
    gusts = np.stack(wants) - np.stack(wants)[:, :1]
    assert (np.abs(gusts).max() > 0.05) == (params.turbulence > 0)
    assert rel_err(np.stack(forces), np.stack(want_forces)) < 1e-12
