"""Policies by name for evaluation: ``scripted``, ``scripted-forecast``, ``blind:VZ``, a saved
recurrent policy (``.npz``) or a saved stable-baselines3 model (``.zip``).

:func:`make_policy` turns a POLICY spec into a :class:`~ihrcf_env.control.policies.Policy` for an
env; :func:`make_env_for` builds the env a saved policy was trained on (with ``deck_motion=True`` if
its observation needs it). stable-baselines3 (the ``[rl]`` extra) is imported only for a ``.zip``; a
``.npz`` (:class:`~ihrcf_env.control.gru_policy.GruPolicy` or
:class:`~ihrcf_env.control.mlp_policy.MlpPolicy`, by the file's header) runs in numpy.
"""

from __future__ import annotations

import importlib
import os
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env import LANDING_V1_ID
from ihrcf_env.control.forecast_landing import FORECAST_POLICY_OPTIONS, ForecastLanding
from ihrcf_env.control.gru_policy import GruPolicy
from ihrcf_env.control.mlp_policy import MlpPolicy
from ihrcf_env.control.policies import BlindDescent, Policy, ScriptedLanding

SB3_ALGOS = ("PPO", "SAC", "TD3", "A2C", "DDPG")
#: The estimate the scripted policy flies on.
SCRIPTED_ESTIMATOR = "fused"
#: The scripted landing that commits to a forecast quiet window (its env has ``deck_forecast``).
FORECAST_POLICY = "scripted-forecast"


class PolicyError(ValueError):
    """A POLICY argument that cannot be used (the message names ``--policy``)."""


class SB3Policy:
    """A saved stable-baselines3 model as a :class:`~ihrcf_env.control.policies.Policy`.

    ``frames`` > 1: the model reads the last ``frames`` flat observations, oldest first (trained with
    ``make_env(frame_stack=frames)``); the policy keeps them, the first of an episode repeated before
    it as Gymnasium's ``FrameStackObservation`` does, so it acts on the env's own observation."""

    def __init__(self, model: Any, frames: int = 1) -> None:
        self.model = model
        self.frames = frames
        self._stack: np.ndarray | None = None

    def reset(self) -> None:
        self._stack = None

    def act(self, obs: np.ndarray) -> np.ndarray:
        x = np.asarray(obs)
        if self.frames > 1:
            if self._stack is None:
                self._stack = np.repeat(x[None], self.frames, axis=0)
            else:
                self._stack = np.concatenate([self._stack[1:], x[None]])
            x = self._stack
        action, _ = self.model.predict(x, deterministic=True)
        return np.asarray(action, dtype=np.float32)


def _brief(space: Any) -> str:
    """A short description of a space: ``Box(50,)`` or ``Dict(keys...)``."""
    if isinstance(space, gym.spaces.Box):
        return f"Box{space.shape}"
    if isinstance(space, gym.spaces.Dict):
        return f"Dict({', '.join(space.spaces)})"
    return type(space).__name__


def load_sb3(path: str, algo: str, env: gym.Env) -> SB3Policy:
    """Load ``path`` with stable-baselines3's ``algo`` class and check its spaces against ``env``'s."""
    try:
        sb3 = importlib.import_module("stable_baselines3")
    except ImportError:
        raise PolicyError(
            f"--policy {path!r} is a stable-baselines3 model, but stable-baselines3 is not installed "
            "(pip install 'ihrcf_env[rl]' or pip install stable-baselines3)"
        ) from None
    cls = getattr(sb3, algo)
    try:
        model = cls.load(path, device="cpu")
    except Exception as e:  # a zip that is not an SB3 model of this class
        raise PolicyError(
            f"--policy {path!r}: cannot be loaded as a stable-baselines3 {algo} model: {e}"
        ) from None
    space, want = model.observation_space, env.observation_space
    frames = 1
    if isinstance(space, gym.spaces.Box) and isinstance(want, gym.spaces.Box) and len(space.shape) == 2:
        frames = space.shape[0]  # a frame-stacked policy: compare with the env's space stacked
        want = gym.spaces.Box(np.stack([want.low] * frames), np.stack([want.high] * frames), dtype=np.float32)
    same = (
        isinstance(space, gym.spaces.Box)
        and isinstance(want, gym.spaces.Box)
        and space.shape == want.shape
        and np.allclose(space.low, want.low)
        and np.allclose(space.high, want.high)
    )
    if not same:
        raise PolicyError(
            f"--policy {path!r}: its observation space {_brief(space)} does not match the env's "
            f"{_brief(want)} (another env id, estimator set, privileged observation or --deck-motion?)"
        )
    if getattr(model.action_space, "shape", None) != env.action_space.shape:
        raise PolicyError(
            f"--policy {path!r}: its action space {model.action_space} does not match the env's "
            f"{env.action_space}"
        )
    return SB3Policy(model, frames)


def load_gru(path: str, env: gym.Env) -> GruPolicy:
    """Load the recurrent policy ``path`` (a ``.npz``) and check its observation against ``env``'s."""
    try:
        policy = GruPolicy.load(path)
    except ValueError as e:
        raise PolicyError(f"--policy {e}") from None
    shape = getattr(env.observation_space, "shape", None)
    if shape != (policy.obs_size,):
        raise PolicyError(
            f"--policy {path!r}: it reads a flat observation of {policy.obs_size} values, the env gives "
            f"{_brief(env.observation_space)} (another env id, estimator set or --deck-motion?)"
        )
    if env.action_space.shape != (policy.weights["w_o"].shape[0],):
        raise PolicyError(f"--policy {path!r}: its actions do not match the env's {env.action_space}")
    return policy


def load_mlp(path: str, env: gym.Env) -> MlpPolicy:
    """Load the MLP policy ``path`` (a ``.npz``) and check its observation against ``env``'s."""
    try:
        policy = MlpPolicy.load(path)
    except ValueError as e:
        raise PolicyError(f"--policy {e}") from None
    shape = getattr(env.observation_space, "shape", None)
    if shape != (policy.input_size,):
        raise PolicyError(
            f"--policy {path!r}: it reads a flat observation of {policy.input_size} values, the env gives "
            f"{_brief(env.observation_space)} (another env id, estimator set or --deck-motion?)"
        )
    if env.action_space.shape != (policy.action_size,):
        raise PolicyError(f"--policy {path!r}: its actions do not match the env's {env.action_space}")
    return policy


def with_deck_motion(
    env_id: str, kwargs: dict[str, Any], spec: str, algo: str
) -> tuple[gym.Env, Policy] | None:
    """(env, policy) with ``deck_motion=True`` if a saved policy fits that observation, else None."""
    if not spec.endswith((".zip", ".npz")):
        return None
    try:
        env = gym.make(env_id, **kwargs, deck_motion=True)
    except (TypeError, ValueError):  # an env without that option
        return None
    try:
        return env, make_policy(spec, env, algo)
    except PolicyError:
        env.close()
        return None


def action_mode(env: gym.Env) -> str:
    """The ``action_mode`` ("velocity" or "motors") of a landing env (wrapped or not); "velocity"
    for an env without one."""
    base: Any = env.unwrapped
    config = getattr(base, "config", None)
    world = getattr(config, "world", None)
    return str(getattr(world, "action_mode", getattr(config, "action_mode", "velocity")))


def make_policy(spec: str, env: gym.Env, algo: str = "PPO") -> Policy:
    """The policy of a POLICY argument (see DESCRIPTION) for ``env``; PolicyError naming
    ``--policy`` if it cannot be."""
    base: Any = env.unwrapped
    max_velocity = tuple(float(v) for v in getattr(base, "max_velocity", np.ones(4)))
    baseline = spec in ("scripted", FORECAST_POLICY) or spec.startswith("blind:")
    if baseline and action_mode(env) != "velocity":
        raise PolicyError(
            f"--policy {spec!r}: the baselines fly velocity commands; the env has "
            f"action_mode={action_mode(env)!r}"
        )
    if spec == "scripted":
        try:
            return ScriptedLanding.from_env(env, estimator=SCRIPTED_ESTIMATOR)
        except AttributeError:
            raise PolicyError(
                "--policy scripted needs the v1 observation (obs_slices/obs_scales): use --env-id "
                + LANDING_V1_ID
            ) from None
        except ValueError as e:  # the layout lacks the fields it reads
            raise PolicyError(f"--policy scripted: {e}") from None
    if spec == FORECAST_POLICY:
        try:
            return ForecastLanding.from_env(env, estimator=SCRIPTED_ESTIMATOR)
        except AttributeError:
            raise PolicyError(
                f"--policy {FORECAST_POLICY} needs the landing observation (obs_slices/obs_scales) with "
                "deck_forecast"
            ) from None
        except ValueError as e:  # no forecast, or the layout lacks the fields it reads
            raise PolicyError(f"--policy {FORECAST_POLICY}: {e}") from None
    if spec.startswith("blind:"):
        text = spec.removeprefix("blind:")
        try:
            vz = float(text)
        except ValueError:
            raise PolicyError(f"--policy {spec!r}: VZ must be a number of m/s, e.g. blind:0.3") from None
        try:
            return BlindDescent(vz, max_velocity)
        except (TypeError, ValueError) as e:
            raise PolicyError(f"--policy {spec!r}: {e}") from None
    if spec.endswith((".zip", ".npz")) or os.path.exists(spec):
        if not os.path.isfile(spec):
            raise PolicyError(f"--policy {spec!r}: no such file")
        if spec.endswith(".npz"):
            return load_mlp(spec, env) if MlpPolicy.is_mlp_file(spec) else load_gru(spec, env)
        return load_sb3(spec, algo, env)
    raise PolicyError(
        f"--policy {spec!r}: not 'scripted', '{FORECAST_POLICY}', 'blind:VZ', a saved recurrent policy "
        "(.npz) or a saved stable-baselines3 model (.zip)"
    )


def make_env_for(env_id: str, kwargs: dict[str, Any], spec: str, algo: str = "PPO") -> tuple[gym.Env, Policy]:
    """``gym.make(env_id, **kwargs)`` and the policy of ``spec`` on it; a saved policy trained with
    the deck motion in its observation gets ``deck_motion=True``. PolicyError if it cannot be."""
    pair = with_deck_motion(env_id, kwargs, spec, algo)
    if pair is not None:
        return pair
    if spec == FORECAST_POLICY and "deck_forecast" not in kwargs:
        kwargs = {**kwargs, "deck_forecast": FORECAST_POLICY_OPTIONS}
    env = gym.make(env_id, **kwargs)
    try:
        return env, make_policy(spec, env, algo)
    except Exception:
        env.close()
        raise


__all__ = [
    "FORECAST_POLICY",
    "SB3_ALGOS",
    "PolicyError",
    "SB3Policy",
    "load_gru",
    "load_sb3",
    "make_env_for",
    "make_policy",
    "with_deck_motion",
]
