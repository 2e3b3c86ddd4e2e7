"""Ray RLlib pieces for ``examples/train_rllib.py``: the env creator (registered with Ray's
registry under :data:`RLLIB_ENV_NAME`), a success-rate metric and the result fields logged per
iteration. Needs the ``[rl]`` extra (``ray[rllib]``); this module imports Ray only inside functions,
and Ray imports it by name on every node, so each node needs ``ihrcf_env`` installed.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

from ihrcf_env import VECTOR_IDS
from ihrcf_env.rl.envs import default_env_id, make_env

RLLIB_ENV_NAME = "ihrcf_deck_landing"
PROGRESS_FIELDS = (
    "iteration",
    "timesteps",
    "wall_s",
    "episodes",
    "episode_return_mean",
    "episode_len_mean",
    "success_rate",
)


def env_creator(env_config: Mapping[str, Any]) -> gym.Env | gym.vector.VectorEnv:
    """RLlib env creator: ``env_config`` keys ``env_id`` (default v1), ``camera_model`` (default
    ``"projected"``) and any keyword of the env (e.g. ``max_episode_steps``).

    With ``num_envs`` in ``env_config`` (what RLlib adds when its env runners are configured with
    ``gym_env_vectorize_mode=gym.VectorizeMode.VECTOR_ENTRY_POINT``), the native vector env of the
    id (``gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point")``: next-step
    autoreset, as RLlib's env runners expect) instead of one env."""
    cfg = dict(env_config)  # an EnvContext (a dict with worker_index etc. as attributes)
    env_id, camera_model = cfg.pop("env_id", None), cfg.pop("camera_model", "projected")
    if "num_envs" not in cfg:
        return make_env(env_id, camera_model, **cfg)
    env_id = default_env_id() if env_id is None else env_id
    if env_id not in VECTOR_IDS:
        raise ValueError(f"env_id: {env_id!r} has no native vector env (those with one: {VECTOR_IDS})")
    n = cfg.pop("num_envs")
    mode = gym.VectorizeMode.VECTOR_ENTRY_POINT
    return gym.make_vec(env_id, num_envs=n, vectorization_mode=mode, camera_model=camera_model, **cfg)


def register() -> str:
    """Register :func:`env_creator` with ``ray.tune.registry.register_env``; returns the name."""
    from ray.tune.registry import register_env

    register_env(RLLIB_ENV_NAME, env_creator)
    return RLLIB_ENV_NAME


def log_success(*, episode: Any, metrics_logger: Any = None, **_: Any) -> None:
    """``on_episode_end`` callback: logs ``info["is_success"]`` of the episode's last step as the
    metric ``success_rate`` (mean over the last 100 episodes of each env runner)."""
    infos = episode.get_infos()
    last = infos[-1] if len(infos) else {}
    if metrics_logger is not None:
        metrics_logger.log_value("success_rate", float(bool(last.get("is_success", False))), window=100)


def progress_row(iteration: int, wall_s: float, result: Mapping[str, Any]) -> dict[str, float | int]:
    """The :data:`PROGRESS_FIELDS` of one ``Algorithm.train()`` result (``nan`` when RLlib has no
    finished episode to report yet)."""
    runners = result.get("env_runners", {})

    def num(key: str, default: float = float("nan")) -> float:
        value = runners.get(key, default)
        return float(value) if isinstance(value, int | float) else default

    steps = result.get("num_env_steps_sampled_lifetime", runners.get("num_env_steps_sampled_lifetime", 0))
    return {
        "iteration": iteration,
        "timesteps": int(steps),
        "wall_s": round(wall_s, 1),
        "episodes": int(num("num_episodes_lifetime", 0.0)),
        "episode_return_mean": num("episode_return_mean"),
        "episode_len_mean": num("episode_len_mean"),
        "success_rate": num("success_rate"),
    }


__all__ = [
    "PROGRESS_FIELDS",
    "RLLIB_ENV_NAME",
    "env_creator",
    "log_success",
    "progress_row",
    "register",
]
