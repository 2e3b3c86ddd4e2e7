"""Adding an estimator is one registry entry: the wrapper's spaces, obs keys, info reasons and flat
layout follow its name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.estimators import ESTIMATORS, EstimatorConfig, PoseEstimate, SensorFrame
from ihrcf_env.core.frames import matrix_from_euler
from ihrcf_env.wrappers.estimates import flat_slices

HOVER_ID = "ihrcf_env/DeckHover-v0"


class BelowAtHeight:
    """A toy estimator: the deck level, straight below, at a height of 1 m, valid only with an IMU
    sample and a known time."""

    name = "toy"

    def __init__(self, config: EstimatorConfig) -> None:
        self.config = config
        self.times: list[float] = []

    def reset(self) -> None:
        self.times = []

    def update(self, frame: SensorFrame) -> PoseEstimate:
        self.times.append(frame.time)
        if frame.imu is None or math.isnan(frame.time):
            return PoseEstimate.invalid("needs imu and time")
        return PoseEstimate.from_body_pose(matrix_from_euler(0.0, 0.0, 0.0), [0.0, 0.0, -1.0], 0.0)


@pytest.fixture
def toy(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(ESTIMATORS, "toy", BelowAtHeight)


def test_default_layout_is_untouched_by_a_registered_estimator(make_env, toy):
    env = make_env(HOVER_ID, flatten=True)
    assert env.observation_space.shape == (46,)  # ihrcf, atda, fused, ground_truth
    assert env.get_wrapper_attr("flat_slices") == flat_slices()


def test_opted_in_estimator_gets_its_key_reason_and_slices(make_env, toy):
    names = ("ihrcf", "atda", "toy")
    env = make_env(HOVER_ID, keep_image=False, estimators=names)
    obs, info = env.reset(seed=0)
    assert set(obs) >= {"ihrcf", "atda", "toy", "ground_truth"}
    assert obs["toy"]["valid"] == 1 and info["toy_reason"] == ""
    np.testing.assert_allclose(obs["toy"]["position"], [0.0, 0.0, -1.0])
    obs, _, _, _, info = env.step(np.zeros(4))
    assert info["toy_residual"] == 0.0
    toy_source = env.get_wrapper_attr("estimators")["toy"]
    assert toy_source.times == [0.0, info["time"]]  # reset, then one step, with the env's time
    flat = make_env(HOVER_ID, flatten=True, estimators=names)
    s = flat.get_wrapper_attr("flat_slices")
    assert s == flat_slices(names)
    assert (s["toy"], s["ground_truth"], s["all"]) == (slice(32, 39), slice(39, 46), slice(0, 46))
    obs, _ = flat.reset(seed=0)
    assert obs.shape == (46,) and flat.observation_space.contains(obs)
    np.testing.assert_allclose(obs[s["toy.position"]], [0.0, 0.0, -1.0])
