"""ihrcf_env: UAV landing on a moving Stewart-platform deck, with the IHRCF pose estimator as a sensor.

Layers: the pure core (``ihrcf_env.core``: frames, geometry, Stewart kinematics, estimators;
numpy/scipy/cv2 only), the PyBullet simulation (``ihrcf_env.sim``), the Gymnasium envs
(``ihrcf_env.envs``) and the wrappers on top. Importing this package registers the env ids below
without importing PyBullet:

* ``ihrcf_env/DeckHover-v0``: the paper's hover-and-track experiment (estimates beside ground truth);
* ``ihrcf_env/DeckHoverRaw-v0``: its raw env (camera, ToF, IMU; no estimators);
* ``ihrcf_env/DeckLanding-v1``: the landing task (flat RL observation; ``raw=True`` for the raw env);
* ``ihrcf_env/DeckLanding-v2``: the landing task in a ship's motion, wind and ground effect, graded
  by ``level`` (``"calm"``, ``"moderate"``, ``"rough"``).

The ids ``ihrcf_env/DeckLanding-v0`` and ``ihrcf_env/DeckLandingRaw-v0`` are deprecated aliases of
the hover ids.
"""

from __future__ import annotations

import warnings
from typing import Any

from gymnasium.envs.registration import register, registry

from ihrcf_env._components import register_component_checks
from ihrcf_env._version import __version__

__all__ = [
    "DEPRECATED_IDS",
    "ENV_IDS",
    "HOVER_ID",
    "HOVER_RAW_ID",
    "LANDING_V1_ID",
    "LANDING_V2_ID",
    "VECTOR_IDS",
    "__version__",
    "make_config",
    "register_estimator",
    "register_fault",
    "register_noise_model",
    "register_sensor",
]

HOVER_ID = "ihrcf_env/DeckHover-v0"
HOVER_RAW_ID = "ihrcf_env/DeckHoverRaw-v0"
LANDING_V1_ID = "ihrcf_env/DeckLanding-v1"
LANDING_V2_ID = "ihrcf_env/DeckLanding-v2"
#: Deprecated ids -> the ids they stand for.
DEPRECATED_IDS: dict[str, str] = {
    "ihrcf_env/DeckLanding-v0": HOVER_ID,
    "ihrcf_env/DeckLandingRaw-v0": HOVER_RAW_ID,
}
#: Every id this package registers.
ENV_IDS: tuple[str, ...] = (HOVER_ID, HOVER_RAW_ID, LANDING_V1_ID, LANDING_V2_ID, *DEPRECATED_IDS)


def _deprecated(old: str, **kwargs: Any) -> Any:
    """The env the deprecated id ``old`` stands for, made with ``kwargs``, after a
    DeprecationWarning naming the id to use."""
    import importlib

    new = DEPRECATED_IDS[old]
    warnings.warn(f"{old} is deprecated: use {new} (same env)", DeprecationWarning, stacklevel=4)
    module, _, name = _ENTRY[new].partition(":")
    return getattr(importlib.import_module(module), name)(**kwargs)


def _deck_landing_v0(**kwargs: Any) -> Any:
    """Entry point of the deprecated ``ihrcf_env/DeckLanding-v0``."""
    return _deprecated("ihrcf_env/DeckLanding-v0", **kwargs)


def _deck_landing_raw_v0(**kwargs: Any) -> Any:
    """Entry point of the deprecated ``ihrcf_env/DeckLandingRaw-v0``."""
    return _deprecated("ihrcf_env/DeckLandingRaw-v0", **kwargs)


#: Deprecated id -> its entry point (module-level functions named by string: the specs serialise).
_DEPRECATED_ENTRY = {
    "ihrcf_env/DeckLanding-v0": "ihrcf_env:_deck_landing_v0",
    "ihrcf_env/DeckLandingRaw-v0": "ihrcf_env:_deck_landing_raw_v0",
}


_ENTRY = {
    HOVER_ID: "ihrcf_env.wrappers.estimates:make_deck_hover",
    HOVER_RAW_ID: "ihrcf_env.envs.deck_landing:DeckLandingEnv",
    LANDING_V1_ID: "ihrcf_env.wrappers.landing_obs:make_deck_landing_v1",
    LANDING_V2_ID: "ihrcf_env.wrappers.landing_obs:make_deck_landing_v2",
}


#: ``gym.make_vec``'s entry point of each id with a native vector env (:mod:`ihrcf_env.vector`).
_VECTOR_ENTRY = {
    LANDING_V1_ID: "ihrcf_env.vector:make_landing_v1",
    LANDING_V2_ID: "ihrcf_env.vector:make_landing_v2",
}


#: The ids with a native vector env (``gym.make_vec(id, num_envs=N)``).
VECTOR_IDS: tuple[str, ...] = tuple(_VECTOR_ENTRY)
for _id, _entry in _ENTRY.items():
    if _id not in registry:
        vec = _VECTOR_ENTRY.get(_id)
        register(id=_id, entry_point=_entry, vector_entry_point=vec, max_episode_steps=600)
for _old, _new in DEPRECATED_IDS.items():
    if _old not in registry:
        register(id=_old, entry_point=_DEPRECATED_ENTRY[_old], max_episode_steps=600)


def _simulator_components() -> Any:
    """The simulator's registries of sensors, noise models and faults (imported when an option
    naming them is first checked): the checks :func:`make_config` applies to those options."""
    import ihrcf_env.sim.registry as components

    return components


register_component_checks(_simulator_components)


def make_config(**options: Any) -> Any:
    """The resolved :class:`~ihrcf_env.config.landing.DeckLandingConfig` of ``options`` (see
    :func:`ihrcf_env.config.make.make_config`)."""
    from ihrcf_env.config.make import make_config as _make

    return _make(**options)


def register_estimator(name: str, factory: Any, *, replace: bool = False) -> None:
    """Register a deck-pose estimator from user code (see
    :func:`ihrcf_env.core.estimators.registry.register_estimator`)."""
    from ihrcf_env.core.estimators.registry import register_estimator as _register

    _register(name, factory, replace=replace)


def register_sensor(name: str, factory: Any, outputs: Any, *, replace: bool = False) -> None:
    """Register a sensor from user code (see :func:`ihrcf_env.sim.registry.register_sensor`)."""
    from ihrcf_env.sim.registry import register_sensor as _register

    _register(name, factory, outputs, replace=replace)


def register_noise_model(name: str, factory: Any, *, replace: bool = False) -> None:
    """Register a measurement-noise model from user code (see
    :func:`ihrcf_env.sim.registry.register_noise_model`)."""
    from ihrcf_env.sim.registry import register_noise_model as _register

    _register(name, factory, replace=replace)


def register_fault(name: str, factory: Any, acts_on: Any = (), *, replace: bool = False) -> None:
    """Register a sensor fault from user code (see :func:`ihrcf_env.sim.registry.register_fault`)."""
    from ihrcf_env.sim.registry import register_fault as _register

    _register(name, factory, acts_on, replace=replace)
