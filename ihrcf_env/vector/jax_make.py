"""The landing ids on the JAX backend: ``gym.make_vec(id, num_envs=N, backend="jax", **options)``.

:func:`make_functional` validates the options once (:func:`~ihrcf_env.config.make.make_config`, as
``gym.make`` does) and builds the functional env (:class:`~ihrcf_env.vector.jax_landing.LandingFunctional`);
:func:`make_jax_vector_env` puts the Gymnasium vector env front on it. The backend has one camera,
the projected one with corner output (:data:`JAX_DEFAULTS`); options it cannot honour (the rendered
camera, user sensors, estimators, noise models, faults or disturbances) raise ValueError naming
them before anything is compiled, as do the options no vector env takes (``render_mode``) and a
step limit whose episode draws would not fit in memory (:data:`MAX_DRAW_BYTES`).
"""

from __future__ import annotations

from typing import Any

from gymnasium.vector import AutoresetMode

from ihrcf_env.config.make import make_config
from ihrcf_env.core.checks import check_int
from ihrcf_env.vector.checks import check_options, time_limit
from ihrcf_env.vector.jax_env import MAX_JAX_ENVS, JaxVectorEnv

__all__ = [
    "BACKENDS",
    "JAX_DEFAULTS",
    "MAX_DRAW_BYTES",
    "check_episode_steps",
    "make_functional",
    "make_jax_vector_env",
]

#: The vector envs' backends.
BACKENDS = ("pybullet", "jax")
#: The camera of the JAX backend (the defaults it puts before the user's options).
JAX_DEFAULTS: dict[str, Any] = {"camera_model": "projected", "camera_output": "corners"}
#: Most bytes of the episode draws of all envs (each episode holds its gusts for the whole step
#: limit: three floats a control step).
MAX_DRAW_BYTES = 2**31


def check_episode_steps(max_episode_steps: int, num_envs: int, dtype: str) -> int:
    """``max_episode_steps`` checked against what the JAX backend draws per episode: at most
    :data:`~ihrcf_env.fast.params.MAX_STEPS`, and the gusts of all ``num_envs`` episodes within
    :data:`MAX_DRAW_BYTES`; ValueError naming it, with the bound, otherwise."""
    from ihrcf_env.fast.params import MAX_STEPS

    per_step = 3 * (8 if dtype == "float64" else 4) * num_envs
    bound = min(MAX_STEPS, MAX_DRAW_BYTES // per_step)
    if max_episode_steps > bound:
        raise ValueError(
            f"max_episode_steps={max_episode_steps}: the JAX backend draws each episode's gusts for "
            f"the whole step limit ({per_step // num_envs} bytes a step per env), so with "
            f"num_envs={num_envs} in {dtype} it takes at most {bound} steps (-1: no limit)"
        )
    return max_episode_steps


def _task_of(env_id: str) -> str:
    from ihrcf_env import LANDING_V1_ID, LANDING_V2_ID

    tasks = {LANDING_V1_ID: "landing-v1", LANDING_V2_ID: "landing-v2"}
    if env_id not in tasks:
        raise ValueError(f"backend='jax': only {sorted(tasks)} have a JAX backend, got {env_id!r}")
    return tasks[env_id]


def make_functional(env_id: str, dtype: str = "float64", max_steps: int = 600, **options: Any) -> Any:
    """The functional env of ``env_id`` with ``options`` (``gym.make``'s) in ``dtype``."""
    import jax
    import jax.numpy as jnp

    from ihrcf_env.vector.jax_landing import LandingFunctional

    task = _task_of(env_id)
    for name, value in JAX_DEFAULTS.items():
        if name in options and options[name] != value:
            raise ValueError(f"{name}={options[name]!r}: the JAX backend has only {name}={value!r}")
    if dtype not in ("float64", "float32"):
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    config = make_config(task=task, **{**JAX_DEFAULTS, **options})
    with jax.enable_x64(dtype == "float64"):
        return LandingFunctional(config, dtype=jnp.dtype(dtype), max_steps=max_steps)


def make_jax_vector_env(
    env_id: str,
    num_envs: int = 1,
    autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    max_episode_steps: int | None = None,
    seeding: str = "paired",
    dtype: str = "float64",
    devices: int | None = None,
    **options: Any,
) -> JaxVectorEnv:
    """The JAX vector env of ``num_envs`` episodes of ``env_id`` (module docstring). It carries the
    functional env's ``config``, ``obs_slices`` and ``obs_scales``. ``devices``: the devices the
    envs are spread over (None: as many as JAX has and split ``num_envs`` evenly; on a CPU, one
    per core this process may use when JAX has not started yet)."""
    from ihrcf_env.vector.jax_devices import check_device_count, request_host_devices

    check_options(options)
    n = check_int("num_envs", num_envs, low=1, high=MAX_JAX_ENVS)
    check_device_count(devices)
    request_host_devices(devices)
    if dtype not in ("float64", "float32"):
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    limit = time_limit(env_id, max_episode_steps)
    if limit is not None:
        check_episode_steps(limit, n, dtype)
    fenv = make_functional(env_id, dtype, max_steps=limit or 600, **options)
    env = JaxVectorEnv(env_id, fenv, num_envs, autoreset_mode, max_episode_steps, seeding, dtype, devices)
    env.config = fenv.config  # type: ignore[attr-defined]
    env.obs_slices = fenv.obs_slices  # type: ignore[attr-defined]
    env.obs_scales = fenv.obs_scales  # type: ignore[attr-defined]
    return env
