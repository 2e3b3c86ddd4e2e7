"""The closing fixtures of conftest.py: what they build is closed when the test ends (``no_leaks``
is set up first, so its check runs after their teardown)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
from conftest import connected_clients

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.sim.world import World

#: What the tests built, kept alive so that garbage collection cannot close it in their place.
_KEPT: list[Any] = []


def test_make_world_closes_its_worlds(no_leaks: None, make_world: Callable[..., World]) -> None:
    before = connected_clients()
    worlds = [make_world(WorldConfig(camera=None)), make_world()]
    _KEPT.extend(worlds)
    assert connected_clients() == before + 2 and not any(w.closed for w in worlds)


def test_closing_closes_what_it_is_given(no_leaks: None, closing: Callable[[Any], Any]) -> None:
    before = connected_clients()
    env = closing(DeckLandingEnv(camera=False))
    _KEPT.append(env)
    assert isinstance(env, DeckLandingEnv) and connected_clients() == before + 1


def test_make_v1_is_the_landing_task_with_a_60_s_horizon(
    no_leaks: None, make_v1: Callable[..., gym.Env]
) -> None:
    env = make_v1(raw=True, camera=False)
    assert env.spec is not None and env.spec.id == "ihrcf_env/DeckLanding-v1"
    assert env.unwrapped.config.task.deck.horizon_s == 60.0
    assert make_v1(raw=True, camera=False, horizon_s=30.0).unwrapped.config.task.deck.horizon_s == 30.0
