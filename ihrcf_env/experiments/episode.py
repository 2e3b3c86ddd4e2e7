"""The one episode loop of the landing evaluations and its result.

:func:`run_episode` flies one seeded episode with a policy that has ``reset()`` and ``act(obs)``
(:class:`~ihrcf_env.control.policies.Policy`, :class:`~ihrcf_env.control.landing.LandingController`)
and reads how it ended from ``info`` after the fact (the policy never sees ``info``);
:func:`run_episodes` repeats it over consecutive seeds. Used by the landing evaluation
(:mod:`ihrcf_env.experiments.landing`) and the evaluate command line (:mod:`ihrcf_env.cli.evaluate`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ihrcf_env.core.metrics import EpisodeResult


class EpisodePolicy(Protocol):
    """What :func:`run_episode` flies: ``reset()`` at the episode start, ``act(obs)`` each step."""

    def reset(self) -> None:
        """Episode start."""

    def act(self, obs: Any) -> Any:
        """Normalised action in [-1, 1]^4 for one observation."""
        ...


def run_episode(env: gym.Env, policy: EpisodePolicy, seed: int, profile: str = "") -> EpisodeResult:
    """One episode of ``policy`` on ``env`` from ``reset(seed=seed)``, until it terminates or is
    truncated; its outcome read from the last ``info``. ``profile`` is recorded as given."""
    obs, info = env.reset(seed=seed)
    policy.reset()
    ret, steps = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        ret += float(reward)
        steps += 1
        if terminated or truncated:
            break
    outcome = info.get("outcome", "flying")
    speed = tilt = offset = None
    td = info.get("touchdown")
    if td is not None:
        speed = abs(float(td["relative_vertical_speed"]))
        tilt = float(td["relative_tilt"])
        if "tag_offset" in info:
            offset = float(info["tag_offset"])
        elif "drone_position_world" in info and "deck_position_world" in info:
            d = np.asarray(info["drone_position_world"])[:2] - np.asarray(info["deck_position_world"])[:2]
            offset = float(np.hypot(*d))
    commit = getattr(policy, "commit_time", None)
    return EpisodeResult(
        seed=seed,
        outcome="timeout" if outcome == "flying" else str(outcome),
        reason=str(info.get("crash_reason", "")) if outcome == "crash" else "",
        time=float(info.get("time", math.nan)),
        steps=steps,
        ret=ret,
        speed=speed,
        tilt=tilt,
        offset=offset,
        commit_time=None if commit is None else float(commit),
        profile=profile,
    )


def run_episodes(
    env: gym.Env,
    policy: EpisodePolicy,
    episodes: int,
    seed: int = 0,
    on_episode: Callable[[EpisodeResult], None] | None = None,
    profile: str = "",
) -> list[EpisodeResult]:
    """``episodes`` episodes (:func:`run_episode`) from seeds ``seed, seed + 1, ...``;
    ``on_episode`` is called with each result as soon as its episode ends (e.g. to print it)."""
    out = []
    for i in range(episodes):
        r = run_episode(env, policy, seed + i, profile)
        out.append(r)
        if on_episode is not None:
            on_episode(r)
    return out


__all__ = [
    "EpisodePolicy",
    "run_episode",
    "run_episodes",
]
