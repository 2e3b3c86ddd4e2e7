"""The vector env's batched estimator stage against each env's own wrapper chain."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import ihrcf_env
from ihrcf_env.core.estimators import ESTIMATORS, EstimatorConfig, PoseEstimate, SensorFrame
from ihrcf_env.vector import BATCH_FROM, DeckLandingVectorEnv
from ihrcf_env.wrappers.landing_obs import landing_obs_fields

V2 = ihrcf_env.LANDING_V2_ID
#: camera latency, lost frames (moderate), both optional observation blocks
OPTIONS: dict[str, Any] = {
    "camera_model": "projected",
    "level": "moderate",
    "deck_motion": True,
    "privileged": True,
    "max_episode_steps": 40,
}
#: observations and rewards of the two stages agree to this (the batched estimators' rounding)
TOL = 1e-6


def _run(batch: bool, steps: int = 90) -> list[Any]:
    v = DeckLandingVectorEnv(V2, 3, autoreset_mode=AutoresetMode.SAME_STEP, batch_estimators=batch, **OPTIONS)
    try:
        assert v.batch_estimators == batch
        rng = np.random.default_rng(4)
        obs, info = v.reset(seed=[11, 12, 13])
        out = [(obs, info)]
        for _ in range(steps):
            a = rng.uniform(-1, 1, (3, 4)) * [0.4, 0.4, 0.3, 0.2] + [0.0, 0.0, -0.25, 0.0]
            out.append(v.step(a.astype(np.float32)))
        return out
    finally:
        v.close()


def test_batched_estimators_reproduce_each_envs_own() -> None:
    """Same seeds and actions through latency, lost frames, deck motion, the privileged block and
    same-step autoresets: observations within TOL, the same endings and reasons."""
    a, b = _run(True), _run(False)
    worst = 0.0
    ended = 0
    for ra, rb in zip(a[1:], b[1:], strict=True):
        obs_a, rew_a, term_a, trunc_a, info_a = ra
        obs_b, rew_b, term_b, trunc_b, info_b = rb
        np.testing.assert_array_equal(term_a, term_b)
        np.testing.assert_array_equal(trunc_a, trunc_b)
        worst = max(worst, float(np.abs(obs_a - obs_b).max()), float(np.abs(rew_a - rew_b).max()))
        for key in ("fused_reason", "atda_reason", "ihrcf_reason"):
            assert list(info_a[key]) == list(info_b[key])
        if "final_obs" in info_a:
            ended += int(info_a["_final_obs"].sum())
            for i in np.flatnonzero(info_a["_final_obs"]):
                worst = max(worst, float(np.abs(info_a["final_obs"][i] - info_b["final_obs"][i]).max()))
    assert worst < TOL, worst
    assert ended >= 3
    slices = landing_obs_fields(privileged=True, deck_motion=True)[0]
    valid = np.array([r[0][:, slices["fused.valid"]] for r in a[1:]])
    assert valid.mean() > 0.3, valid.mean()
    print(f"max |batched - own chains| = {worst:.3g} over {len(a) - 1} steps of 3 envs, {ended} endings")


def test_a_single_env_with_batch_estimators_reproduces_a_sub_env(make_env: Callable[..., gym.Env]) -> None:
    """gym.make(id, batch_estimators=True) runs the batched estimators with one row: it equals a
    batched vector env's sub-env bit for bit (through latency, deck motion and autoresets)."""
    n = 3
    v = DeckLandingVectorEnv(V2, n, autoreset_mode=AutoresetMode.SAME_STEP, batch_estimators=True, **OPTIONS)
    try:
        singles = [make_env(V2, batch_estimators=True, **OPTIONS) for _ in range(n)]
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
                    np.testing.assert_array_equal(info["final_obs"][i], o)
                    o, _ = e.reset()
                np.testing.assert_array_equal(obs[i], o)
    finally:
        v.close()


def test_other_estimators_step_their_own_chains(toy_registered: None) -> None:
    v = DeckLandingVectorEnv(V2, 2, camera_model="projected", estimators=("ihrcf", "toy"))
    try:
        assert not v.batch_estimators
        obs, _ = v.reset(seed=0)
        assert obs.shape == (2, 40)
    finally:
        v.close()
    with pytest.raises(ValueError, match="batch_estimators"):  # no batched form of "toy"
        DeckLandingVectorEnv(
            V2, 2, camera_model="projected", estimators=("ihrcf", "toy"), batch_estimators=True
        )


class BelowAtHeight:
    """A toy estimator without a batched form: the deck straight below at 1 m, level."""

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


def test_bad_batch_option_and_step_before_reset(no_leaks: None, closing: Callable[[Any], Any]) -> None:
    with pytest.raises(TypeError, match="batch_estimators"):
        DeckLandingVectorEnv(V2, 2, camera_model="projected", batch_estimators="yes")
    v = closing(gym.make_vec(V2, num_envs=2, camera_model="projected"))
    with pytest.raises(gym.error.ResetNeeded, match="reset"):
        v.step(np.zeros((2, 4), np.float32))
    assert not v.batch_estimators  # by default from BATCH_FROM envs on
    assert closing(gym.make_vec(V2, num_envs=BATCH_FROM, camera_model="projected")).batch_estimators
