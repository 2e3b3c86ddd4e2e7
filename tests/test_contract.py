"""The contract every registered env id keeps: Gymnasium's checker, determinism, the spec round
trip, and nothing left behind (PyBullet clients, temporary directories) by close, by an env dropped
without close, or by a failed construction."""

from __future__ import annotations

import gc
import pickle
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import connected_clients, temp_dirs
from gymnasium.utils.env_checker import check_env

import ihrcf_env

#: The fast camera model for every id (the rendered one costs ~50 ms a frame).
FAST = {"camera_model": "projected", "horizon_s": 30.0}


def _make(env_id: str, **options: Any) -> gym.Env:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the deprecated aliases warn
        return gym.make(env_id, **{**FAST, **options})


def _flat(obs: Any) -> np.ndarray:
    if isinstance(obs, dict):
        return np.concatenate([_flat(obs[k]) for k in sorted(obs)])
    return np.asarray(obs, dtype=np.float64).ravel()


def _rollout(env: gym.Env, seed: int, n: int = 8) -> np.ndarray:
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    out = [_flat(obs)]
    for _ in range(n):
        obs, reward, terminated, truncated, _ = env.step(rng.uniform(-0.3, 0.3, 4).astype(np.float32))
        out.append(np.append(_flat(obs), reward))
        if terminated or truncated:
            break
    return np.concatenate(out)


def test_every_id_is_listed_and_registered() -> None:
    assert set(ihrcf_env.ENV_IDS) == {k for k in gym.registry if k.startswith("ihrcf_env/")}


@pytest.mark.parametrize("env_id", ihrcf_env.ENV_IDS)
def test_contract(env_id: str, no_leaks: None) -> None:
    env = _make(env_id)
    try:
        # the render check builds render_mode="human" (a GUI) for every mode: skipped headless,
        # the GUI has its own test (tests/envs/test_gui.py)
        check_env(env.unwrapped if env_id.endswith("Raw-v0") else env, skip_render_check=True)
        first, again = _rollout(env, 3), _rollout(env, 3)
        assert first.tobytes() == again.tobytes()  # bitwise deterministic
        assert _rollout(env, 4).tobytes() != first.tobytes()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            copy = gym.make(env.spec)  # the spec round trip
        try:
            assert _rollout(copy, 3).tobytes() == first.tobytes()
        finally:
            copy.close()
    finally:
        env.close()
        env.close()  # twice is fine


@pytest.mark.parametrize("env_id", ihrcf_env.ENV_IDS)
def test_every_spec_serialises(env_id: str) -> None:
    """``spec.to_json()`` and pickle round trips, entry points named by string (vector ones too)."""
    spec = gym.spec(env_id)
    for entry in (spec.entry_point, spec.vector_entry_point):
        assert entry is None or isinstance(entry, str), entry
    assert gym.envs.registration.EnvSpec.from_json(spec.to_json()) == spec
    assert pickle.loads(pickle.dumps(spec)) == spec
    made = _make(spec.id)  # the spec of a made env, its kwargs included
    try:
        assert made.spec is not None
        assert pickle.loads(pickle.dumps(made.spec)) == made.spec
        assert gym.envs.registration.EnvSpec.from_json(made.spec.to_json()).id == spec.id
    finally:
        made.close()


@pytest.mark.parametrize("env_id", ihrcf_env.ENV_IDS)
def test_a_made_envs_spec_remakes_it_through_json(env_id: str) -> None:
    """``gym.make(EnvSpec.from_json(env.spec.to_json()))`` re-makes the env: the wrappers record
    their options in the form JSON gives back (lists, dicts of FusedParams' fields), so the
    re-made wrappers' specs match the saved ones; the same observations on a seed."""
    options: dict[str, Any] = {"estimators": ("ihrcf", "fused")} if "Raw" not in env_id else {}
    if env_id == ihrcf_env.LANDING_V2_ID:
        options["deck_forecast"] = True
    made = _make(env_id, **options)
    try:
        assert made.spec is not None
        text = made.spec.to_json()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            again = gym.make(gym.envs.registration.EnvSpec.from_json(text))
        try:
            assert again.spec is not None and again.spec.to_json() == text
            np.testing.assert_allclose(_flat(again.reset(seed=3)[0]), _flat(made.reset(seed=3)[0]))
        finally:
            again.close()
    finally:
        made.close()


@pytest.mark.parametrize("env_id", ihrcf_env.VECTOR_IDS)
def test_the_vector_entry_point_makes_the_vector_env(env_id: str) -> None:
    env = gym.make_vec(env_id, num_envs=2, **FAST)
    try:
        assert env.num_envs == 2 and type(env).__module__.startswith("ihrcf_env.")
        assert env.spec is not None and pickle.loads(pickle.dumps(env.spec)) == env.spec
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ihrcf_env.DEPRECATED_IDS)
def test_deprecated_ids_warn_and_make_the_new_env(env_id: str) -> None:
    with pytest.warns(DeprecationWarning, match=ihrcf_env.DEPRECATED_IDS[env_id]) as seen:
        env = gym.make(env_id, **FAST)
    ours = {Path(w.filename).name for w in seen if "is deprecated: use" in str(w.message)}
    assert ours == {Path(__file__).name}  # the warning points at the caller
    try:
        new = gym.make(ihrcf_env.DEPRECATED_IDS[env_id], **FAST)
        try:
            assert _rollout(env, 1).tobytes() == _rollout(new, 1).tobytes()
        finally:
            new.close()
    finally:
        env.close()


def test_current_ids_make_no_warning_and_v1_is_out_of_date() -> None:
    for env_id in (ihrcf_env.HOVER_ID, ihrcf_env.HOVER_RAW_ID, ihrcf_env.LANDING_V2_ID):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            gym.make(env_id, **FAST).close()
    with pytest.warns(DeprecationWarning, match="out of date"):  # Gymnasium's word for an older version
        gym.make(ihrcf_env.LANDING_V1_ID, **FAST).close()


def test_spec_round_trip_with_a_calibration_object(no_leaks: None) -> None:
    from ihrcf_env.core.calibration import Calibration, default_calibration_path

    cal = Calibration.load(default_calibration_path())
    for env_id in (ihrcf_env.HOVER_ID, ihrcf_env.LANDING_V1_ID):
        env = gym.make(env_id, calibration=cal, **FAST)
        try:
            again = gym.make(env.spec)
            again.close()
        finally:
            env.close()


def test_envs_dropped_without_close_release_their_clients(private_tmp: Path) -> None:
    gc.collect()
    clients, dirs = connected_clients(), temp_dirs()
    for seed in range(20):
        env = gym.make(ihrcf_env.HOVER_RAW_ID, camera=False)
        env.reset(seed=seed)
        del env
        gc.collect()
    assert connected_clients() <= clients
    assert temp_dirs() <= dirs


def test_failed_makes_leak_nothing(no_leaks: None) -> None:
    from ihrcf_env.core.calibration import CalibrationError

    for _ in range(5):
        with pytest.raises(CalibrationError):  # a calibration made for another camera
            gym.make(ihrcf_env.HOVER_ID, camera_fov=0.9)
        with pytest.raises(ValueError):
            gym.make(ihrcf_env.LANDING_V1_ID, tag_size=5.0)  # does not fit on the deck
