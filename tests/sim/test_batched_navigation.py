"""The GNSS/INS error processes of N worlds on arrays (sim.batched.navigation) equal each process's
own ``errors_at``, bit for bit, across block refills, clock jumps and a clock set back."""

from __future__ import annotations

import numpy as np

from ihrcf_env.config.vehicle import NavigationErrors
from ihrcf_env.sim.batched.navigation import error_tracks
from ihrcf_env.sim.navigation import GNSSINSNavigation

DT = 1 / 240
STEPS = 12


def _navs(seed: int) -> list[GNSSINSNavigation]:
    errors = [NavigationErrors(), NavigationErrors(horizontal_sigma=2.0, velocity_time_constant=0.5)]
    navs = []
    for k in range(4):
        nav = GNSSINSNavigation(errors[k % 2], DT)
        nav.reset(np.random.default_rng(seed + k))
        navs.append(nav)
    return navs


def test_rows_equal_errors_at_over_many_steps() -> None:
    batched, single = _navs(3), _navs(3)
    ticks = np.array([0, 0, 5, 0], dtype=np.int64)
    for step in range(40):  # 480 ticks: every block of draws is refilled at least once
        if step == 10:
            ticks[1] += 100  # a clock jump: that row is advanced by its own errors_at
        if step == 20:
            ticks[3] -= 30  # a clock set back: only the clock moves, then the steps resume
        times = (ticks[:, None] + np.arange(STEPS)) * DT
        got = error_tracks(batched, times)
        for i, nav in enumerate(single):
            want = nav.errors_at(times[i].tolist())
            for a, b in zip(got, want, strict=True):
                assert a[i].tolist() == b.tolist(), (step, i)
        ticks = ticks + STEPS
    for a, b in zip(batched, single, strict=True):
        assert (a.position_error, a.velocity_error, a._white, a._k, a._i) == (
            b.position_error,
            b.velocity_error,
            b._white,
            b._k,
            b._i,
        )


def test_no_rows_or_no_ticks() -> None:
    assert error_tracks([], np.zeros((0, STEPS)))[0].shape == (0, STEPS, 3)
    assert error_tracks(_navs(0), np.zeros((4, 0)))[0].shape == (4, 0, 3)
