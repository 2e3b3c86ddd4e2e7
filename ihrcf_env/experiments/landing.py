"""Landing evaluation: run :class:`~ihrcf_env.control.landing.LandingController` over seeded episodes.

The controller flies from its own sensing; ``info`` is read only after each episode, to report how
it ended (:class:`~ihrcf_env.core.metrics.EpisodeResult`, summarised by
:func:`ihrcf_env.core.metrics.summarize_landings`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym

from ihrcf_env.control.landing import LandingController
from ihrcf_env.core.metrics import EpisodeResult

#: Deck motion profiles of the env.
PROFILES = ("paper", "sea_state", "static")


def run_episode(env: gym.Env, controller: LandingController, seed: int, profile: str = "") -> EpisodeResult:
    """Run one episode of ``env`` (velocity actions) with ``controller``; its outcome from ``info``."""
    obs, info = env.reset(seed=seed)
    controller.reset()
    while True:
        obs, _, terminated, truncated, info = env.step(controller.act(obs))
        if terminated or truncated:
            break
    td = info.get("touchdown")
    outcome = info.get("outcome", "flying")
    res = EpisodeResult(
        profile=profile,
        seed=seed,
        outcome="timeout" if outcome == "flying" else outcome,
        reason=info.get("crash_reason", "") if outcome == "crash" else "",
        time=float(info["time"]),
        commit_time=controller.commit_time,
    )
    if td is not None:
        res.speed = abs(float(td["relative_vertical_speed"]))
        res.tilt = float(td["relative_tilt"])
    return res


def evaluate(
    profile: str,
    episodes: int,
    seed: int = 0,
    tof_noise: str | None = None,
    max_seconds: float = 30.0,
    env_kwargs: Mapping[str, Any] | None = None,
    on_episode: Callable[[EpisodeResult], None] | None = None,
    estimator: str = "ihrcf",
) -> list[EpisodeResult]:
    """Run ``episodes`` landings (seeds ``seed .. seed + episodes - 1``) on one deck profile.

    Args:
        profile: deck motion, one of :data:`PROFILES`.
        episodes: number of episodes.
        seed: first seed.
        tof_noise: ``"ideal"`` or ``"realistic"`` ToF ranges (None: as the ``sensor_preset`` in
            ``env_kwargs`` says).
        max_seconds: episode limit (simulated s).
        env_kwargs: further ``gym.make`` arguments (e.g. ``control_hz``, ``random_deck_start``).
        on_episode: called with each result as soon as its episode ends (e.g. to print it).
        estimator: the deck-pose estimate the controller steers on (``"ihrcf"`` or ``"fused"``).
    """
    kwargs = dict(env_kwargs or {})
    if tof_noise is not None:
        kwargs["tof_noise"] = tof_noise
    hz = int(kwargs.get("control_hz", 20))
    env = gym.make(
        "ihrcf_env/DeckHover-v0",
        deck_profile=profile,
        keep_image=False,
        max_episode_steps=max(1, int(round(max_seconds * hz))),
        **kwargs,
    )
    base = env.unwrapped
    ctrl = LandingController(
        control_hz=hz,
        max_velocity=base.max_velocity,  # type: ignore[attr-defined]
        rig=base.rig,  # type: ignore[attr-defined]
        estimator=estimator,
    )
    results = []
    try:
        for i in range(episodes):
            r = run_episode(env, ctrl, seed + i, profile)
            results.append(r)
            if on_episode is not None:
                on_episode(r)
    finally:
        env.close()
    return results
