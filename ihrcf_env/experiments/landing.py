"""Landing evaluation: run :class:`~ihrcf_env.control.landing.LandingController` over seeded episodes.

The controller flies from its own sensing; ``info`` is read only after each episode, to report how
it ended (:class:`~ihrcf_env.experiments.episode.EpisodeResult`, from the one episode loop
:func:`~ihrcf_env.experiments.episode.run_episodes`; summarised by
:func:`ihrcf_env.core.metrics.summarize_landings`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym

from ihrcf_env.control.landing import LandingController
from ihrcf_env.experiments.episode import EpisodeResult, run_episodes

#: Deck motion profiles of the env.
PROFILES = ("paper", "sea_state", "static")


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
    try:
        return run_episodes(env, ctrl, episodes, seed, on_episode, profile)
    finally:
        env.close()


__all__ = [
    "PROFILES",
    "evaluate",
]
