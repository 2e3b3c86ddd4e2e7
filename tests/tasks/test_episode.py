"""The episode draws (ihrcf_env.tasks.episode): the same starts, decks and winds per seed as the
envs drew before the draws moved below the env layer (values recorded then), and the wind's gust
normals as the wind consumes them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from ihrcf_env.config.make import make_config
from ihrcf_env.config.wind import WindParams
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.tasks import episode

# (task, level) -> per seed 0 and 7: altitude, offset x, offset y, yaw, deck time, deck heave at
# 3 s, wind x at 2.5 s (None: calm); recorded from the envs' own draws (np_random seeded, then
# SeedStreams.from_generator) before the move.
RECORDED: dict[tuple[str, str | None], list[list[Any]]] = {
    ("hover", None): [
        [1.0345730761048608, -0.018671290818263155, 0.00035151535260904423, 0.14291179574323976, 0.0,
         0.030632237076084777, None],
        [0.983517867564743, 0.06897526955254994, 0.006796412689901943, -0.12638283653242843, 0.0,
         0.030632237076084777, None],
    ],
    ("landing-v1", None): [
        [2.7685961415729112, -0.5116206726489393, -0.5732055704250973, 2.2448532380914354,
         55.28126915128495, 0.0030713451618652344, -1.236080109753283],
        [2.0027680134711456, -0.015273441903815898, -0.536849055203747, -1.9852169539505844,
         103.72852812471145, 0.02520672560899851, -2.446647163261235],
    ],
    ("landing-v2", "calm"): [
        [2.7685961415729112, -0.5116206726489393, -0.5732055704250973, 2.2448532380914354,
         55.28126915128495, -0.007979035825457507, -1.236080109753283],
        [2.0027680134711456, -0.015273441903815898, -0.536849055203747, -1.9852169539505844,
         103.72852812471145, -0.0020922866780049175, -2.446647163261235],
    ],
    ("landing-v2", "rough"): [
        [2.7685961415729112, -0.5116206726489393, -0.5732055704250973, 2.2448532380914354,
         55.28126915128495, 0.005642486895459297, -1.9995851388100108],
        [2.0027680134711456, -0.015273441903815898, -0.536849055203747, -1.9852169539505844,
         103.72852812471145, 0.005797350741257201, -13.805512184175774],
    ],
}  # fmt: skip


def _streams(seed: int) -> SeedStreams:
    rng = np.random.default_rng(np.random.SeedSequence(seed))  # gymnasium's np_random(seed)
    return SeedStreams.from_generator(rng)


@pytest.mark.parametrize("task_level", sorted(RECORDED, key=str))
def test_draws_match_recorded(task_level: tuple[str, str | None]) -> None:
    task, level = task_level
    kw = {"level": level} if level else {}
    cfg = make_config(task=task, camera_model="projected", camera_output="corners", raw=True, **kw)
    for seed, want in zip((0, 7), RECORDED[task_level], strict=True):
        s = _streams(seed)
        start = episode.draw_start(cfg, s.generator("start"), disc=task != "hover")
        got = [start.altitude, *start.offset, start.yaw, start.deck_time]
        assert got == want[:5]  # bit for bit: generator draws
        profile, checked = episode.draw_deck(cfg, s.generator("deck"), start.deck_time)
        assert checked == (task != "hover")
        assert float(profile(3.0)[0][2]) == pytest.approx(want[5], rel=1e-12, abs=1e-15)  # libm rounding
        if cfg.wind is None:
            assert want[6] is None
        else:
            wind = Wind(cfg.wind)
            wind.reset(s.generator("wind"))
            assert float(wind.velocity(2.5)[0]) == pytest.approx(want[6], rel=1e-12, abs=1e-15)


def test_env_draws_are_the_module_s() -> None:
    """The PyBullet env's reset draws through the module (same streams, same values)."""
    import gymnasium as gym

    import ihrcf_env  # noqa: F401  (registers the ids)

    env = gym.make("ihrcf_env/DeckLanding-v2", camera_model="projected", camera_output="corners")
    try:
        _, info = env.reset(seed=3)
        cfg = env.unwrapped.config  # type: ignore[attr-defined]
        s = _streams(3)
        start = episode.draw_start(cfg, s.generator("start"), disc=True)
        profile, _ = episode.draw_deck(cfg, s.generator("deck"), start.deck_time)
        deck0 = np.asarray(info["deck_position_world"])
        geom = cfg.world.stewart
        want = np.asarray(geom.home_position) + profile(0.0)[0]
        assert np.abs(deck0 - want).max() < 1e-9
        assert abs(float(info["drone_position_world"][2]) - (deck0[2] + start.altitude)) < 0.2  # trimmed
    finally:
        env.close()


def test_gust_normals_are_the_wind_s() -> None:
    """The gust normals of the draw are those the wind consumes (its stationary start, then its
    blocks), so a JAX wind from them is the env's wind."""
    params = WindParams(mean_speed_min=9.0, mean_speed_max=11.0)
    wind = Wind(params)
    wind.reset(np.random.default_rng(5))
    draw = episode.draw_wind(np.random.default_rng(5))
    speed = params.mean_speed_min + (params.mean_speed_max - params.mean_speed_min) * draw.u_speed
    assert wind.mean_speed == speed and wind.direction == 2.0 * math.pi * draw.u_direction
    n = episode.gust_normals(draw.gust_seed, 1 + 2 * Wind.BLOCK)
    sigma = np.asarray(wind.sigma)
    wind.gust(0.0)  # the first block
    assert np.array_equal(np.asarray(wind._samples[0]), _rot(wind.direction) @ (sigma * n[0]))


def _rot(direction: float) -> np.ndarray:
    c, s = math.cos(direction), math.sin(direction)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_bad_options_are_named() -> None:
    cfg = make_config(task="landing-v1", camera_model="projected", camera_output="corners", raw=True)
    with pytest.raises(ValueError, match="unknown keys"):
        episode.draw_start(cfg, np.random.default_rng(0), {"altitud": 2.0})
    with pytest.raises(ValueError, match="altitude"):
        episode.draw_start(cfg, np.random.default_rng(0), {"altitude": 100.0})
    assert episode.start_radius(cfg, 3.0) == 1.0
    assert 0.3 < episode.start_radius(cfg, 1.5) < 0.5
