"""The landing task's wind: per-episode mean, Dryden gusts (statistics), drag force, determinism."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from ihrcf_env.config.wind import Disturbance, DragModel, WindParams
from ihrcf_env.sim.disturbances import Wind, dryden_low_altitude


def test_dryden_low_altitude_figures() -> None:
    # MIL-F-8785C at 5 m (16.4 ft): sigma_u / sigma_w = 1 / (0.177 + 0.000823 h)^0.4, L_w = h
    s_h, s_w, l_h, l_w = dryden_low_altitude(5.0)
    h_ft = 5.0 / 0.3048
    k = 0.177 + 0.000823 * h_ft
    assert s_w == pytest.approx(0.1)
    assert s_h == pytest.approx(0.1 / k**0.4)
    assert l_w == pytest.approx(5.0)
    assert l_h == pytest.approx(h_ft / k**1.2 * 0.3048)
    assert 1.9 < s_h / s_w < 2.0 and 36 < l_h < 37


def test_mean_wind_is_drawn_per_episode() -> None:
    wind = Wind(WindParams(mean_speed_min=1.0, mean_speed_max=4.0))
    rng = np.random.default_rng(0)
    speeds, directions = [], []
    for _ in range(2000):
        wind.reset(rng)
        speeds.append(wind.mean_speed)
        directions.append(wind.direction)
        assert math.hypot(*wind.mean[:2]) == pytest.approx(wind.mean_speed)
        assert wind.mean[2] == 0.0
    speeds_a, dirs = np.array(speeds), np.array(directions)
    assert speeds_a.min() >= 1.0 and speeds_a.max() <= 4.0
    assert speeds_a.mean() == pytest.approx(2.5, abs=0.06)  # uniform: std of the mean 0.02
    assert dirs.min() >= 0 and dirs.max() < 2 * math.pi
    # uniform direction: the mean unit vector is ~0 (std 1/sqrt(2 n) = 0.016 per component)
    assert abs(np.cos(dirs).mean()) < 0.06 and abs(np.sin(dirs).mean()) < 0.06


def test_gust_statistics_match_dryden() -> None:
    """Gust std per component and the correlation time L / V of the Gauss-Markov process."""
    wind = Wind(WindParams(mean_speed_min=4.0, mean_speed_max=4.0))
    rng = np.random.default_rng(1)
    dt = 0.05
    t = np.arange(0.0, 300.0, dt)
    along, vertical = [], []
    for _ in range(30):
        wind.reset(rng)
        g = np.array([wind.gust(x) for x in t])
        c, s = math.cos(wind.direction), math.sin(wind.direction)
        along.append(g[:, 0] * c + g[:, 1] * s)  # in the mean-wind frame
        vertical.append(g[:, 2])
    s_h, s_w, l_h, l_w = dryden_low_altitude(5.0)
    assert wind.sigma == pytest.approx((4.0 * s_h, 4.0 * s_h, 4.0 * s_w))
    assert wind.tau == pytest.approx((l_h / 4.0, l_h / 4.0, l_w / 4.0))
    assert np.concatenate(along).std() == pytest.approx(4.0 * s_h, rel=0.1)
    assert np.concatenate(vertical).std() == pytest.approx(4.0 * s_w, rel=0.05)
    # autocorrelation at a lag of tau, pooled over the episodes: exp(-1)
    for series, tau in ((along, wind.tau[0]), (vertical, wind.tau[2])):
        lag = int(round(tau / dt))
        num = sum(float(np.dot(x[:-lag], x[lag:])) for x in series)
        den = sum(float(np.dot(x[:-lag], x[:-lag])) for x in series)
        assert num / den == pytest.approx(math.exp(-1), abs=0.06)


def test_wind_is_a_function_of_time_and_the_seed() -> None:
    a, b = Wind(), Wind()
    a.reset(np.random.default_rng(7))
    b.reset(np.random.default_rng(7))
    times = np.linspace(0.0, 25.0, 301)
    forward = [a.velocity(t) for t in times]
    backward = [b.velocity(t) for t in times[::-1]][::-1]  # other order, lazily generated blocks
    assert np.array_equal(np.array(forward), np.array(backward))
    c = Wind()
    c.reset(np.random.default_rng(8))
    assert not np.array_equal(np.array(forward), np.array([c.velocity(t) for t in times]))
    # a deep copy (as each env makes) is independent and equal
    d = copy.deepcopy(a)
    assert np.array_equal(d.velocity(30.0), a.velocity(30.0))


def test_force_from_relative_air_velocity() -> None:
    drag = DragModel()
    wind = Wind(WindParams(mean_speed_min=5.0, mean_speed_max=5.0, turbulence=0.0))
    assert isinstance(wind, Disturbance)
    assert wind(0.0, (0, 0, 1), (0, 0, 0)) == (0.0, 0.0, 0.0)  # calm before the first reset
    wind.reset(np.random.default_rng(3))
    w = wind.velocity(1.0)
    assert np.linalg.norm(w) == pytest.approx(5.0)
    # at rest the wind pushes along itself: mass (mcoef + 0.5 rho |w| / bcoef) w
    f = np.array(wind(1.0, (0, 0, 1), (0, 0, 0)))
    expected = drag.mass * (drag.mcoef_xy + 0.5 * drag.rho * 5.0 / drag.bcoef) * w
    assert f == pytest.approx(expected)
    assert np.linalg.norm(f) == pytest.approx(1.08375)  # 1.2 kg at 5 m/s: 0.9 + 0.18 N
    # moving with the air: the drone's own still-air drag is all that is left, so the wind adds
    # exactly minus that force
    f_with = np.array(wind(1.0, (0, 0, 1), tuple(w)))
    assert f_with == pytest.approx(-np.array(drag.force(w)))
    # no wind: no force
    calm = Wind(WindParams(mean_speed_min=0.0, mean_speed_max=0.0))
    calm.reset(np.random.default_rng(0))
    assert calm(3.0, (0, 0, 1), (1.0, 2.0, 0.5)) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"mean_speed_max": -1.0}, ValueError, "mean_speed"),
        ({"mean_speed_min": 3.0, "mean_speed_max": 2.0}, ValueError, "mean_speed"),
        ({"mean_speed_max": "5"}, TypeError, "mean_speed_max"),
        ({"turbulence": -0.1}, ValueError, "turbulence"),
        ({"height": 0.0}, ValueError, "height"),
        ({"sample_dt": math.nan}, ValueError, "sample_dt"),  # a number out of range, not a wrong kind
        ({"drag": 0.1}, TypeError, "drag"),
    ],
)
def test_bad_wind_parameters(kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        WindParams(**kwargs)


def test_bad_drag_parameters() -> None:
    with pytest.raises(ValueError, match="bcoef"):
        DragModel(bcoef=0.0)
    with pytest.raises(ValueError, match="mcoef_xy"):
        DragModel(mcoef_xy=-1.0)
