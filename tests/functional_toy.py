"""A small functional env for the tests of what runs functional envs (the JAX vector env's front,
the PPO adapter): a body falling from a drawn height under a commanded acceleration."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces

from ihrcf_env.core.seeding import SeedStreams

__all__ = ["Drop"]


class Drop:
    """A body falling under a commanded acceleration from a drawn height: ends below 0 (success if
    slower than 1 m/s then)."""

    def __init__(self) -> None:
        self.params = {"dt": 0.1, "g": 1.0}
        self.observation_space = spaces.Box(-np.inf, np.inf, (2,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.host_draws = 0

    def draw_host(self, rng: np.random.Generator) -> tuple[int, Any]:
        self.host_draws += 1
        streams = SeedStreams.from_generator(rng)
        h = streams.generator("start").uniform(1.0, 2.0)
        return streams.key, {"height": np.float64(h)}

    def draw(self, key: Any, params: Any) -> Any:
        return {"height": jax.random.uniform(key, (), minval=1.0, maxval=2.0)}

    def reset_from(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any]:
        h = episode["height"]
        state = {"h": h, "v": jnp.zeros_like(h), "noise": jax.random.normal(key, ())}
        return jnp.stack([h, state["v"]]).astype(jnp.float32), state

    def step(self, key: Any, state: Any, action: Any, params: Any) -> Any:
        a = action[0] - params["g"]
        v = state["v"] + a * params["dt"]
        h = state["h"] + v * params["dt"]
        new = {"h": h, "v": v, "noise": jax.random.normal(key, ())}
        obs = jnp.stack([h, v]).astype(jnp.float32)
        done = h < 0.0
        success = done & (jnp.abs(v) < 1.0)
        info = {"height": h, "noise": new["noise"], "is_success": success}
        return obs, new, -jnp.abs(v) * params["dt"] + 10.0 * success, done, info
