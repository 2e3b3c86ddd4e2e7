"""The env factory shared by the learning scripts (SB3 and RLlib).

``ihrcf_env/DeckLanding-v1`` is the learning task (one-level float32 Box observation,
``info["is_success"]`` at episode end). ``ihrcf_env/DeckHover-v0`` is accepted too (made with
``flatten=True``, its ``info["outcome"]`` turned into ``info["is_success"]``) so that the scripts run
on the paper's hover env as well.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
from gymnasium.envs.registration import registry

import ihrcf_env

V1_ID = "ihrcf_env/DeckLanding-v1"
V0_ID = ihrcf_env.HOVER_ID


class SuccessInfo(gym.Wrapper[Any, Any, Any, Any]):
    """Sets ``info["is_success"]`` (bool) at the end of every episode from ``info["outcome"]``,
    unless the env sets it itself; SB3's Monitor/VecMonitor and EvalCallback read it."""

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        if (terminated or truncated) and "is_success" not in info:
            info["is_success"] = bool(info.get("outcome") == "success")
        return obs, reward, terminated, truncated, info


def default_env_id() -> str:
    """``ihrcf_env/DeckLanding-v1`` when registered, else ``ihrcf_env/DeckHover-v0``."""
    return V1_ID if V1_ID in registry else V0_ID


def make_env(
    env_id: str | None = None, camera_model: str = "projected", frame_stack: int = 1, **kwargs: Any
) -> gym.Env:
    """A learning env: ``gym.make(env_id, camera_model=camera_model, **kwargs)`` with
    ``info["is_success"]`` guaranteed at episode end (v0 is made with ``flatten=True``).

    ``camera_model="projected"`` (no rendering) is the fast training camera, ``"rendered"`` the
    TinyRenderer one. ``frame_stack`` > 1 gives the last ``frame_stack`` observations, oldest first
    (shape ``(frame_stack, D)``; Gymnasium's ``FrameStackObservation``, the first observation of an
    episode repeated before it): the memory of a policy without a recurrent state. Other keyword
    arguments go to the env (``max_episode_steps`` to ``gym.make``)."""
    env_id = default_env_id() if env_id is None else env_id
    if not isinstance(env_id, str) or env_id not in registry:
        raise ValueError(f"env_id must be a registered Gymnasium id, got {env_id!r}")
    if isinstance(frame_stack, bool) or not isinstance(frame_stack, int) or not 1 <= frame_stack <= 64:
        raise ValueError(f"frame_stack must be an int in [1, 64], got {frame_stack!r}")
    if env_id == V0_ID:
        kwargs.setdefault("flatten", True)
    env = gym.make(env_id, camera_model=camera_model, **kwargs)
    if not isinstance(env.observation_space, gym.spaces.Box):
        env.close()
        raise ValueError(f"{env_id} gives a {type(env.observation_space).__name__} observation: need a Box")
    if frame_stack > 1:
        return SuccessInfo(gym.wrappers.FrameStackObservation(env, frame_stack))
    return SuccessInfo(env)


def name_value(text: str) -> tuple[str, float]:
    """``"NAME=NUMBER"`` -> (NAME, NUMBER), e.g. a reward weight on a command line; ValueError else."""
    name, sep, value = text.partition("=")
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not sep or not name or not math.isfinite(number):
        raise ValueError(f"expected NAME=NUMBER, got {text!r}")
    return name, number


def input_indices(slices: Mapping[str, slice], drop: Sequence[str]) -> list[int]:
    """Indices of a flat observation with named ``slices`` (a v1 env's ``obs_slices``) that are in
    none of the slices named in ``drop`` (e.g. ``["ihrcf", "atda"]``: a policy that reads the fused
    estimate and the raw sensors only); ValueError naming an unknown name or an empty result."""
    unknown = [name for name in drop if name not in slices or name == "all"]
    if unknown:
        known = ", ".join(sorted(n for n in slices if n != "all"))
        raise ValueError(f"unknown observation field(s) {unknown}; known: {known}")
    size = slices["all"].stop
    dropped = {i for name in drop for i in range(size)[slices[name]]}
    keep = [i for i in range(size) if i not in dropped]
    if not keep:
        raise ValueError(f"dropping {list(drop)} leaves no observation")
    return keep


def policy_inputs(make: Callable[[], gym.Env], drop: Sequence[str]) -> list[int] | None:
    """:func:`input_indices` of the env ``make()`` makes (made, read, closed), in every frame of a
    stacked observation (indices into its flattened form); None if ``drop`` is empty (the policy
    reads everything)."""
    if not drop:
        return None
    env = make()
    try:
        keep = input_indices(env.get_wrapper_attr("obs_slices"), drop)
        shape = env.observation_space.shape or (0,)
    finally:
        env.close()
    frames, size = (1, shape[0]) if len(shape) == 1 else shape
    return [k * size + i for k in range(frames) for i in keep]


__all__ = [
    "V0_ID",
    "V1_ID",
    "SuccessInfo",
    "default_env_id",
    "input_indices",
    "make_env",
    "name_value",
    "policy_inputs",
]
