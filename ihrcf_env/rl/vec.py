"""A Gymnasium vector env as a stable-baselines3 ``VecEnv`` (SB3 does not take Gymnasium vector envs).

SB3's convention: ``reset()`` returns the observations only; when an episode ends, ``step`` returns
the NEXT episode's first observation, with the final observation in
``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]`` (truncated and not
terminated); ``info`` is a list of one dict per env. Gymnasium's same-step autoreset
(``AutoresetMode.SAME_STEP``) gives exactly that in vector form (the new first observation
returned, the final one in ``info["final_obs"]``, the final step's info in ``info["final_info"]``),
so :class:`Sb3VectorEnv` takes vector envs in that mode and only unbatches.

The next-step autoreset of :class:`~ihrcf_env.vector.env.DeckLandingVectorEnv` cannot be
translated exactly through the vector env API: the next episode's first observation only comes
from the next ``step()``, which also advances every other env (and resets of single envs are not
part of that API). :func:`make_sb3_vec_env` therefore makes the native vector env with
``autoreset_mode=AutoresetMode.SAME_STEP`` when it takes that option, and otherwise Gymnasium's
``SyncVectorEnv`` of the same envs in same-step mode (``gym.make_vec(..., vectorization_mode="sync")``:
sub-env ``i`` of ``reset(seed=s)`` is again ``gym.make(id)`` reset with ``s + i``).

Needs the ``[rl]`` extra (stable-baselines3).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from ihrcf_env.vector.info import unbatch_info


def _autoreset_mode(env: VectorEnv) -> Any:
    return env.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)


class Sb3VectorEnv(VecEnv):
    """SB3 ``VecEnv`` over a Gymnasium vector env in ``AutoresetMode.SAME_STEP`` (module docstring).

    ``seed(s)`` seeds the next ``reset()`` (env ``i`` with ``s + i``), ``set_options`` its options
    (one dict for every env). ``get_attr``, ``set_attr``, ``env_method`` and ``env_is_wrapped`` act
    on the sub-envs (the vector env's ``envs``). Closing closes the vector env."""

    def __init__(self, vector_env: VectorEnv) -> None:
        if not isinstance(vector_env, VectorEnv):
            raise TypeError(f"vector_env must be a gymnasium VectorEnv, got {type(vector_env).__name__}")
        mode = _autoreset_mode(vector_env)
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"vector_env: autoreset mode {mode} cannot give SB3's convention (the next episode's "
                "first observation in the ending step); make it with autoreset_mode SAME_STEP "
                "(make_sb3_vec_env does)"
            )
        self.venv = vector_env
        super().__init__(
            vector_env.num_envs, vector_env.single_observation_space, vector_env.single_action_space
        )
        self._actions: np.ndarray | None = None

    def _sub_envs(self, indices: VecEnvIndices = None) -> list[gym.Env]:
        envs = getattr(self.venv, "envs", None)
        if envs is None:
            raise AttributeError(f"{type(self.venv).__name__} does not expose its sub-envs (no `envs`)")
        return [envs[i] for i in self._get_indices(indices)]

    def reset(self) -> VecEnvObs:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        opts = self._options
        if any(o != opts[0] for o in opts):
            raise ValueError("set_options: a vector env resets every env with the same options (one dict)")
        obs, infos = self.venv.reset(seed=cast(Any, seeds), options=opts[0] or None)  # one seed per env
        self.reset_infos = [unbatch_info(infos, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        if isinstance(self.action_space, gym.spaces.Discrete):
            actions = actions.reshape(self.num_envs)
        obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        dones = np.logical_or(terminated, truncated)
        final_obs = infos.get("final_obs")
        final_info = infos.get("final_info", {})
        out: list[dict[str, Any]] = []
        for i in range(self.num_envs):
            if dones[i]:
                info = unbatch_info(final_info, i)
                self.reset_infos[i] = unbatch_info(infos, i)
                self.reset_infos[i].pop("final_obs", None)
                self.reset_infos[i].pop("final_info", None)
                info["terminal_observation"] = None if final_obs is None else final_obs[i]
            else:
                info = unbatch_info(infos, i)
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            out.append(info)
        return obs, np.asarray(rewards, dtype=np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs  # the vector envs do not render

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [env.get_wrapper_attr(attr_name) for env in self._sub_envs(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        for env in self._sub_envs(indices):
            env.set_wrapper_attr(attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        return [
            env.get_wrapper_attr(method_name)(*method_args, **method_kwargs)
            for env in self._sub_envs(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        from stable_baselines3.common import env_util

        return [env_util.is_wrapped(env, wrapper_class) for env in self._sub_envs(indices)]


def make_sb3_vec_env(
    env_id: str | None = None, n_envs: int = 8, seed: int | None = None, **options: Any
) -> Sb3VectorEnv:
    """An :class:`Sb3VectorEnv` of ``n_envs`` envs of ``env_id`` (default v1) made with ``options``
    (``camera_model`` defaults to ``"projected"``, as :func:`~ihrcf_env.rl.envs.make_env`); its
    first ``reset()`` seeds env ``i`` with ``seed + i`` (``seed`` None: unseeded). The native vector
    env when it takes ``autoreset_mode``, else Gymnasium's SyncVectorEnv (module docstring)."""
    from ihrcf_env.rl.envs import default_env_id

    env_id = default_env_id() if env_id is None else env_id
    if isinstance(n_envs, bool) or not isinstance(n_envs, int | np.integer) or n_envs < 1:
        raise ValueError(f"n_envs must be an int >= 1, got {n_envs!r}")
    options.setdefault("camera_model", "projected")
    venv: VectorEnv
    try:
        venv = gym.make_vec(env_id, num_envs=int(n_envs), autoreset_mode=AutoresetMode.SAME_STEP, **options)
    except TypeError as e:
        if "autoreset_mode" not in str(e):
            raise
        sync = {"autoreset_mode": AutoresetMode.SAME_STEP}
        venv = gym.make_vec(env_id, int(n_envs), vectorization_mode="sync", vector_kwargs=sync, **options)
    try:
        out = Sb3VectorEnv(venv)
    except BaseException:
        venv.close()
        raise
    if seed is not None:
        out.seed(seed)
    return out


__all__ = [
    "Sb3VectorEnv",
    "make_sb3_vec_env",
]
