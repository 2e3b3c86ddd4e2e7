"""Shared fixtures: envs that close themselves, and counters of what an env may leak."""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import pybullet as p
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)

#: Highest PyBullet client id probed when counting connected clients.
_MAX_CLIENTS = 256


def connected_clients() -> int:
    """How many PyBullet clients are connected in this process."""
    return sum(bool(p.isConnected(physicsClientId=i)) for i in range(_MAX_CLIENTS))


def temp_dirs() -> set[str]:
    """The env's temporary directories that exist now."""
    return {d.name for d in Path(tempfile.gettempdir()).glob("ihrcf_env_*")}


@pytest.fixture
def make_env() -> Iterator[Callable[..., gym.Env]]:
    """``make_env(id, **options)``: ``gym.make`` whose envs are closed when the test ends, pass or fail."""
    envs: list[gym.Env] = []

    def make(env_id: str, **options: Any) -> gym.Env:
        env = gym.make(env_id, **options)
        envs.append(env)
        return env

    yield make
    for env in envs:
        env.close()


@pytest.fixture
def no_leaks() -> Iterator[None]:
    """Fails the test if it leaves a PyBullet client connected or an env temp dir behind."""
    clients, dirs = connected_clients(), temp_dirs()
    yield
    assert connected_clients() == clients, "a PyBullet client was left connected"
    assert temp_dirs() <= dirs, "an env temporary directory was left behind"
