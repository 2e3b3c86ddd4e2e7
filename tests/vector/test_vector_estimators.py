"""The vector env's estimators: each sub-env runs its own (a sub-env equals the single env bit for
bit), user-registered estimators included; the removed ``batch_estimators`` option is refused by
name."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import ihrcf_env
from ihrcf_env.core.estimators import ESTIMATORS, EstimatorConfig, PoseEstimate, SensorFrame
from ihrcf_env.vector import DeckLandingVectorEnv

V2 = ihrcf_env.LANDING_V2_ID
#: camera latency, lost frames (moderate), both optional observation blocks
OPTIONS: dict[str, Any] = {
    "camera_model": "projected",
    "level": "moderate",
    "deck_motion": True,
    "privileged": True,
    "max_episode_steps": 40,
}


def test_a_single_env_reproduces_a_sub_env(make_env: Callable[..., gym.Env]) -> None:
    """gym.make(id, **options) equals a vector env's sub-env bit for bit (through latency, lost
    frames, deck motion, the privileged block and same-step autoresets): each sub-env runs its own
    estimators."""
    n = 3
    v = DeckLandingVectorEnv(V2, n, autoreset_mode=AutoresetMode.SAME_STEP, **OPTIONS)
    try:
        singles = [make_env(V2, **OPTIONS) for _ in range(n)]
        ended = 0
        obs, _ = v.reset(seed=30)
        for i, e in enumerate(singles):
            np.testing.assert_array_equal(obs[i], e.reset(seed=30 + i)[0])
        rng = np.random.default_rng(5)
        for _ in range(60):
            a = (rng.uniform(-1, 1, (n, 4)) * [0.4, 0.4, 0.3, 0.2] + [0.0, 0.0, -0.25, 0.0]).astype(
                np.float32
            )
            obs, reward, terminated, truncated, info = v.step(a)
            for i, e in enumerate(singles):
                o, r, te, tr, _ = e.step(a[i])
                assert (reward[i], terminated[i], truncated[i]) == (r, te, tr)
                if te or tr:
                    ended += 1
                    np.testing.assert_array_equal(info["final_obs"][i], o)
                    o, _ = e.reset()
                np.testing.assert_array_equal(obs[i], o)
        assert ended >= 3
    finally:
        v.close()


def test_other_estimators_step_their_own_chains(toy_registered: None) -> None:
    v = DeckLandingVectorEnv(V2, 2, camera_model="projected", estimators=("ihrcf", "toy"))
    try:
        obs, _ = v.reset(seed=0)
        assert obs.shape == (2, 40)
    finally:
        v.close()


class BelowAtHeight:
    """A toy estimator registered by user code: the deck straight below at 1 m, level."""

    name = "toy"

    def __init__(self, config: EstimatorConfig) -> None:
        self.config = config

    def reset(self) -> None:
        pass

    def update(self, frame: SensorFrame) -> PoseEstimate:
        return PoseEstimate.from_body_pose(np.eye(3), [0.0, 0.0, -1.0], 0.0)


@pytest.fixture
def toy_registered(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(ESTIMATORS, "toy", BelowAtHeight)


REMOVED = r'batch_estimators: .*batched estimators were removed.*gym\.make_vec\(.*backend="jax"\)'


@pytest.mark.parametrize("value", [True, False, None, "yes"])
def test_the_removed_batch_estimators_option_is_refused_by_name(
    value: object, no_leaks: None, make_env: Callable[..., gym.Env]
) -> None:
    """Any value of ``batch_estimators`` (the batched estimators were removed) is a ValueError
    naming it and the batched path, before any env is built."""
    with pytest.raises(ValueError, match=REMOVED):
        DeckLandingVectorEnv(V2, 2, camera_model="projected", batch_estimators=value)
    with pytest.raises(ValueError, match=REMOVED):
        gym.make_vec(V2, num_envs=2, camera_model="projected", batch_estimators=value)
    with pytest.raises(ValueError, match=REMOVED):
        gym.make_vec(V2, num_envs=2, workers=2, camera_model="projected", batch_estimators=value)
    with pytest.raises(ValueError, match=REMOVED):
        make_env(V2, camera_model="projected", batch_estimators=value)
    with pytest.raises(ValueError, match=REMOVED):
        ihrcf_env.make_config(task="hover", batch_estimators=value)


def test_the_jax_backend_refuses_batch_estimators_by_name() -> None:
    pytest.importorskip("jax")
    with pytest.raises(ValueError, match=REMOVED):
        gym.make_vec(V2, num_envs=2, backend="jax", batch_estimators=True)


def test_step_before_reset(no_leaks: None, closing: Callable[[Any], Any]) -> None:
    v = closing(gym.make_vec(V2, num_envs=2, camera_model="projected"))
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        v.step(np.zeros((2, 4), np.float32))
