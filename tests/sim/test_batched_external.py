"""The navigation errors and disturbances of N worlds on arrays (sim.batched.external) equal each
world's own objects called tick by tick, bit for bit."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from ihrcf_env.config.vehicle import NavigationErrors
from ihrcf_env.config.wind import WindParams
from ihrcf_env.sim.batched.external import ExternalInputs
from ihrcf_env.sim.disturbances import ConstantForce, Wind
from ihrcf_env.sim.navigation import GNSSINSNavigation, TruthNavigation

DT = 1 / 240
STEPS = 12


class Push:
    """A user disturbance: a force growing with time and height."""

    def reset(self, rng: np.random.Generator) -> None:
        pass

    def __call__(self, t: float, position: Any, velocity: Any) -> tuple[float, float, float]:
        return (0.1 * t, -0.2 * position[2], 0.05 * velocity[0])


def _world(kind: int, seed: int) -> SimpleNamespace:
    rng = np.random.default_rng(seed)
    nav = TruthNavigation() if kind == 0 else GNSSINSNavigation(NavigationErrors(), DT)
    nav.reset(rng)
    wind = Wind(WindParams(mean_speed_min=4.0, mean_speed_max=12.0))
    wind.reset(rng)
    calm = Wind(WindParams(mean_speed_min=0.0, mean_speed_max=0.0))
    calm.reset(rng)
    disturbances = [
        [],
        [wind],
        [ConstantForce([0.5, -0.25, 0.125]), wind],
        [calm, Push()],
        [wind, Push(), ConstantForce([1.0, 0.0, 0.0])],
    ][kind]
    return SimpleNamespace(navigation=nav, disturbances=disturbances)


def test_rows_equal_the_worlds_own_calls() -> None:
    n = 5
    batched = [_world(k, 10 + k) for k in range(n)]
    single = [_world(k, 10 + k) for k in range(n)]
    rng = np.random.default_rng(0)
    ticks = np.array([0, 37, 240, 12, 1000], dtype=np.int64)
    for _ in range(3):  # three control steps
        outside = ExternalInputs(batched, ticks, STEPS, DT)  # type: ignore[arg-type]
        for j in range(STEPS):
            pos, vel = rng.normal(0, 2, (n, 3)), rng.normal(0, 3, (n, 3))
            pos_c, vel_c = outside.navigation(j, pos, vel)
            force = outside.forces(j, pos, vel)
            assert force is not None
            for i, w in enumerate(single):
                t = float((ticks[i] + j) * DT)
                p_i, v_i = tuple(pos[i].tolist()), tuple(vel[i].tolist())
                est_p, est_v = w.navigation.estimate(t, p_i, v_i)
                assert pos_c[i].tolist() == list(est_p) and vel_c[i].tolist() == list(est_v), (i, j)
                fx = fy = fz = 0.0
                for d in w.disturbances:
                    f = d(t, p_i, v_i)
                    fx, fy, fz = fx + f[0], fy + f[1], fz + f[2]
                assert force[i].tolist() == [fx, fy, fz], (i, j)
        ticks = ticks + STEPS
    assert outside.navigating


def test_no_disturbances_no_forces() -> None:
    worlds = [SimpleNamespace(navigation=TruthNavigation(), disturbances=[]) for _ in range(2)]
    outside = ExternalInputs(worlds, np.zeros(2, np.int64), STEPS, DT)  # type: ignore[arg-type]
    pos = np.ones((2, 3))
    assert outside.forces(0, pos, pos) is None and not outside.navigating


def test_wind_velocity_at_equals_its_scalar_gusts() -> None:
    """``Wind.velocity_at`` (on arrays) equals mean + ``gust(t)`` tick by tick, across block
    extensions, for a turbulent wind, a calm one and a wind without turbulence."""
    winds = [
        Wind(WindParams(mean_speed_min=4.0, mean_speed_max=12.0)),
        Wind(WindParams(mean_speed_min=0.0, mean_speed_max=0.0)),
        Wind(WindParams(mean_speed_min=3.0, mean_speed_max=3.0, turbulence=0.0)),
    ]
    for k, wind in enumerate(winds):
        wind.reset(np.random.default_rng(k))
        twin = Wind(wind.params)
        twin.reset(np.random.default_rng(k))
        for start in (0, 1, 5000, 5012, 90000):
            times = [float(t) for t in (start + np.arange(STEPS)) * DT]
            got = wind.velocity_at(times)
            for m, t in enumerate(times):
                g = twin.gust(t)
                want = [wind.mean[0] + g[0], wind.mean[1] + g[1], wind.mean[2] + g[2]]
                assert got[m].tolist() == want, (k, start, m)
