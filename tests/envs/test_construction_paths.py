"""Every way of building a deck env gives the same env: ``gym.make`` with options; ``make_config``
+ the env class + the observation wrapper; the wrapper over a raw env built from options (which
resolves the wrapper's options against the env's config). Compared: the resolved configs (equality)
and the first observation of a seed. The calibration file is read once per ``gym.make``."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.observation import ObservationConfig
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.envs.deck_landing import DeckLandingEnv
from ihrcf_env.envs.landing_v1 import DeckLandingV1Env, DeckLandingV2Env
from ihrcf_env.wrappers.estimates import DeckPoseObservation
from ihrcf_env.wrappers.landing_obs import LandingObservation

SEED = 11
#: id -> (task, env class, wrapper)
TASKS: dict[str, tuple[str, type[DeckLandingEnv], type[gym.Wrapper]]] = {
    ihrcf_env.LANDING_V2_ID: ("landing-v2", DeckLandingV2Env, LandingObservation),
    ihrcf_env.LANDING_V1_ID: ("landing-v1", DeckLandingV1Env, LandingObservation),
    ihrcf_env.HOVER_ID: ("hover", DeckLandingEnv, DeckPoseObservation),
}
#: Env options per id (the projected camera keeps the test fast; v2 also on a level of its own).
OPTIONS: list[tuple[str, dict[str, Any]]] = [
    (ihrcf_env.LANDING_V2_ID, {"camera_model": "projected"}),
    (ihrcf_env.LANDING_V2_ID, {"camera_model": "projected", "level": "rough", "sensor_preset": "ideal"}),
    (ihrcf_env.LANDING_V1_ID, {"camera_model": "projected"}),
    (ihrcf_env.HOVER_ID, {"camera_model": "projected"}),
    (ihrcf_env.HOVER_ID, {}),
]


def _observation(env: gym.Env) -> ObservationConfig:
    wrapper = env
    while not isinstance(wrapper, LandingObservation | DeckPoseObservation):
        assert isinstance(wrapper, gym.Wrapper), f"no observation wrapper in {env}"
        wrapper = wrapper.env
    return wrapper.observation_config


def _resolved(env: gym.Env) -> DeckLandingConfig:
    """The env's config with the observation its wrapper resolved (a raw env's config records
    ``raw=True``: the wrapper holds the resolved part)."""
    config = env.unwrapped.config  # type: ignore[attr-defined]
    assert isinstance(config, DeckLandingConfig)
    return dataclasses.replace(config, observation=_observation(env))


def _by_gym_make(env_id: str, options: dict[str, Any]) -> gym.Env:
    return gym.make(env_id, **options)


def _by_config(env_id: str, options: dict[str, Any]) -> gym.Env:
    task, cls, wrapper = TASKS[env_id]
    config = ihrcf_env.make_config(task=task, **options)
    return wrapper(cls(config), observation=config.observation)


def _by_wrapper(env_id: str, options: dict[str, Any]) -> gym.Env:
    _, cls, wrapper = TASKS[env_id]
    return wrapper(cls(**options))


PATHS: dict[str, Callable[[str, dict[str, Any]], gym.Env]] = {
    "gym.make": _by_gym_make,
    "make_config": _by_config,
    "wrapper": _by_wrapper,
}


def _same(a: Any, b: Any, where: str = "obs") -> None:
    if isinstance(a, Mapping):
        assert isinstance(b, Mapping) and set(a) == set(b), where
        for k in a:
            _same(a[k], b[k], f"{where}[{k!r}]")
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=where)


@pytest.mark.parametrize(("env_id", "options"), OPTIONS, ids=[f"{i}-{sorted(o)}" for i, o in OPTIONS])
def test_every_construction_path_gives_the_same_env(env_id: str, options: dict[str, Any]) -> None:
    envs = {name: make(env_id, options) for name, make in PATHS.items()}
    try:
        configs = {name: _resolved(env) for name, env in envs.items()}
        reference = configs["gym.make"]
        for name, config in configs.items():
            assert config == reference, name
        task = TASKS[env_id][0]
        assert reference.task_name == task
        assert (
            reference.level == ("moderate" if "level" not in options else options["level"])
            or task != "landing-v2"
        )
        fused = reference.observation.fused_params
        assert fused is not None and fused.reseed_agreeing == (task == "landing-v2")
        first = {name: env.reset(seed=SEED)[0] for name, env in envs.items()}
        for name, obs in first.items():
            _same(obs, first["gym.make"], f"{name} obs")
    finally:
        for env in envs.values():
            env.close()


def test_the_v2_wrapper_over_a_raw_env_resolves_the_v2_fused_filter() -> None:
    """``LandingObservation(DeckLandingV2Env())`` takes the landing-v2 fused parameters
    (``reseed_agreeing``), as ``gym.make("ihrcf_env/DeckLanding-v2")`` does."""
    env = LandingObservation(DeckLandingV2Env(camera_model="projected"))
    try:
        fused = env.observation_config.fused_params
        assert fused is not None and fused.reseed_agreeing
        assert env.stage.estimator.sources["fused"].params == fused  # type: ignore[attr-defined]
    finally:
        env.close()


@pytest.mark.parametrize("env_id", [ihrcf_env.LANDING_V2_ID, ihrcf_env.LANDING_V1_ID, ihrcf_env.HOVER_ID])
def test_gym_make_reads_the_calibration_file_once(env_id: str, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[object] = []
    load = Calibration.load.__func__  # type: ignore[attr-defined]

    def counting(cls: type[Calibration], path: Any) -> Calibration:
        calls.append(path)
        return load(cls, path)  # type: ignore[no-any-return]

    monkeypatch.setattr(Calibration, "load", classmethod(counting))
    env = gym.make(env_id, camera_model="projected")
    env.close()
    assert len(calls) == 1, calls


def test_a_given_calibration_is_not_read_from_a_file(monkeypatch: pytest.MonkeyPatch) -> None:
    from ihrcf_env.core.calibration import default_calibration_path

    cal = Calibration.load(default_calibration_path())
    calls: list[object] = []
    monkeypatch.setattr(Calibration, "load", classmethod(lambda cls, path: calls.append(path)))
    env = gym.make(ihrcf_env.LANDING_V2_ID, camera_model="projected", calibration=cal)
    try:
        assert calls == []
        assert _observation(env).calibration is cal
    finally:
        env.close()


LANDING_OPTIONS = [(i, o) for i, o in OPTIONS if i in ihrcf_env.VECTOR_IDS]


@pytest.mark.parametrize(
    ("env_id", "options"), LANDING_OPTIONS, ids=[f"{i}-{sorted(o)}" for i, o in LANDING_OPTIONS]
)
def test_gym_make_with_a_resolved_config_gives_the_same_env(env_id: str, options: dict[str, Any]) -> None:
    task = TASKS[env_id][0]
    by_options = gym.make(env_id, **options)
    by_config = gym.make(env_id, config=ihrcf_env.make_config(task=task, **options))
    try:
        assert _resolved(by_config) == _resolved(by_options)
        _same(by_config.reset(seed=SEED)[0], by_options.reset(seed=SEED)[0])
    finally:
        by_options.close()
        by_config.close()


def test_a_resolved_config_is_checked() -> None:
    with pytest.raises(ValueError, match="task 'landing-v1'"):
        gym.make(ihrcf_env.LANDING_V2_ID, config=ihrcf_env.make_config(task="landing-v1"))
    with pytest.raises(ValueError, match="not both"):
        gym.make(ihrcf_env.LANDING_V2_ID, config=ihrcf_env.make_config(task="landing-v2"), level="calm")
    with pytest.raises(TypeError, match="DeckLandingConfig"):
        gym.make(ihrcf_env.LANDING_V2_ID, config={"level": "calm"})


def test_a_vector_env_resolves_its_config_once(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[object] = []
    load = Calibration.load.__func__  # type: ignore[attr-defined]

    def counting(cls: type[Calibration], path: Any) -> Calibration:
        calls.append(path)
        return load(cls, path)  # type: ignore[no-any-return]

    monkeypatch.setattr(Calibration, "load", classmethod(counting))
    venv = gym.make_vec(ihrcf_env.LANDING_V2_ID, num_envs=3, camera_model="projected")
    try:
        assert len(calls) == 1, calls
        configs = [env.unwrapped.config for env in venv.unwrapped.envs]  # type: ignore[attr-defined]
        assert all(c is configs[0] for c in configs)
    finally:
        venv.close()
