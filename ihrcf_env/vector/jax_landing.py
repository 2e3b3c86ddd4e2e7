"""The landing task as one functional env for the JAX backend: the physics/sensor step and the
observation joined, with its Gymnasium spaces.

:class:`LandingFunctional` joins :mod:`ihrcf_env.fast.step` (physics, sensors, task rules; its
observation hook returns the raw reading and the truth) and :mod:`ihrcf_env.fast.observe` (the
estimators and the normalised observation, in the layout of the PyBullet env's
``LandingObservation``) into the functions a trainer or :class:`~ihrcf_env.vector.jax_env.JaxVectorEnv`
steps, one env per call: ``draw``, ``draw_host``, ``reset_from``, ``reset``, ``step``. Its state
is ``(EnvState, ObserveState)``; its ``info`` holds the outcome code, the reward terms, the episode
time, the truth and, with ``deck_forecast``, the forecast (``info["forecast"]``: ``horizons`` (H,) s,
``mean`` and ``std`` (H, 4) in the observation block's frames and units, ``quiet_probability``,
``valid``, ``samples``, as the PyBullet env's).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.core.landing_layout import FORECAST
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.fast import observe as ob
from ihrcf_env.fast import step as st
from ihrcf_env.fast.episode import draw_episode, host_episode
from ihrcf_env.fast.params import make_params
from ihrcf_env.tasks import SUCCESS as _SUCCESS

__all__ = ["LM_ITERATIONS", "LandingFunctional"]

#: The LM steps that polish each of ATDA's IPPE poses on the JAX backend (cv2 stops after at most
#: 20 by its own rules; a fixed count runs every step for every env, so it is kept small: the
#: difference to the 20-step pose is bounded in tests/fast/test_pnp.py).
LM_ITERATIONS = 5


def _raw_and_truth(raw: Any, truth: Any) -> Any:
    return raw, truth


class LandingFunctional:
    """The landing task of a resolved ``config`` as pure functions of one env (module
    docstring); ``dtype`` the float type (float64 needs x64 while tracing and running);
    ``max_steps`` the episode's step limit; ``lm_iterations`` the LM steps polishing each IPPE pose
    (:data:`LM_ITERATIONS`; 20 gives cv2's poses)."""

    def __init__(
        self,
        config: DeckLandingConfig,
        dtype: Any = jnp.float64,
        max_steps: int = 600,
        lm_iterations: int = LM_ITERATIONS,
    ) -> None:
        self.config = config
        self.step_params = make_params(config, observe=_raw_and_truth, dtype=dtype, max_steps=max_steps)
        self.observe_params = ob.observe_params(config, lm_iterations)
        op = self.observe_params
        self.obs_slices = dict(op.slices)
        self.obs_scales = dict(op.scales)
        self.observation_space = spaces.Box(
            np.asarray(op.low, np.float32), np.asarray(op.high, np.float32), dtype=np.float32
        )
        self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
        self.params: Any = ()

    def draw_host(self, rng: np.random.Generator) -> tuple[int, Any]:
        """The episode key and episode the PyBullet env draws next from its generator ``rng``."""
        streams = SeedStreams.from_generator(rng)
        return streams.key, host_episode(self.step_params, streams)

    def draw(self, key: Any, params: Any) -> Any:
        return draw_episode(key, self.step_params)

    def reset_from(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any]:
        (raw, truth), env_state = st.reset_from(episode, key, self.step_params)
        op = self.observe_params
        obs, obs_state, _ = ob.observe(op, ob.observe_init(op), raw, truth)
        return obs, (env_state, obs_state)

    def reset(self, key: Any, params: Any) -> tuple[Any, Any]:
        k1, k2 = jax.random.split(key)
        return self.reset_from(self.draw(k1, params), k2, params)

    def step(self, key: Any, state: Any, action: Any, params: Any) -> tuple[Any, Any, Any, Any, Any]:
        env_state, obs_state = state
        (raw, truth), env_state, reward, done, info = st.step_env(key, env_state, action, self.step_params)
        obs, obs_state, estimates = ob.observe(self.observe_params, obs_state, raw, truth)
        out = {
            "outcome": info.outcome,
            "is_success": info.outcome == jnp.asarray(_SUCCESS),
            "time": info.time,
            "drone_position_world": truth.drone_position_world,
            "deck_position_world": truth.deck_position_world,
            "deck_position_body": truth.deck_position_body,
        }
        for name, e in estimates.items():
            out[f"{name}_valid"] = e.valid
        fc, feed, fp = obs_state.forecast, obs_state.feed, self.observe_params.forecast
        if fc is not None and feed is not None and fp is not None:
            out[FORECAST] = {
                "horizons": jnp.asarray(fp.forecast.horizons, fc.mean.dtype),
                "mean": fc.mean,
                "std": fc.std,
                "quiet_probability": fc.quiet,
                "valid": fc.valid,
                "samples": feed.samples,
            }
        return obs, (env_state, obs_state), reward, done, out

    # -- the staged form: the estimator stage once per env and step -------------------------------
    def step_stage(self, key: Any, state: Any, action: Any, params: Any) -> tuple[Any, Any, Any, Any, Any]:
        """:meth:`step` without the estimator stage: ``(reading, state, reward, terminated, info)``,
        ``reading`` the step's ``(RawReading, Truth)`` for :meth:`finish`; ``info`` holds
        ``outcome`` and ``is_success``."""
        env_state, obs_state = state
        reading, env_state, reward, done, info = st.step_env(key, env_state, action, self.step_params)
        out = {"outcome": info.outcome, "is_success": info.outcome == jnp.asarray(_SUCCESS)}
        return reading, (env_state, obs_state), reward, done, out

    def reset_stage(self, key: Any, params: Any) -> tuple[Any, Any]:
        """:meth:`reset` without the estimator stage: ``(reading, state)``, the stage's state that
        of an episode's start (:meth:`finish` makes the first observation)."""
        k1, k2 = jax.random.split(key)
        reading, env_state = st.reset_from(self.draw(k1, params), k2, self.step_params)
        return reading, (env_state, ob.observe_init(self.observe_params))

    def finish(self, reading: Any, state: Any) -> tuple[Any, Any]:
        """The observation of ``reading`` (:meth:`step_stage` or :meth:`reset_stage`) and the state
        with the estimator stage advanced: ``reset_stage`` then ``finish`` is :meth:`reset`,
        ``step_stage`` then ``finish`` is :meth:`step`."""
        env_state, obs_state = state
        raw, truth = reading
        obs, obs_state, _ = ob.observe(self.observe_params, obs_state, raw, truth)
        return obs, (env_state, obs_state)

    def privileged(self, reading: Any) -> Any:
        """The ground truth of a reading as a critic's privileged inputs (20,): the drone's
        position relative to the deck origin (world, m), the deck origin in the body frame (m), the
        velocity relative to the deck point under the drone (world, m/s), the drone's and the deck's
        quaternions (x, y, z, w) and the wind (world, m/s)."""
        _, truth = reading
        return jnp.concatenate(
            [
                truth.drone_position_world - truth.deck_position_world,
                truth.deck_position_body,
                truth.relative_velocity,
                truth.drone_quaternion_world,
                truth.deck_quaternion_world,
                truth.wind_velocity,
            ]
        )
