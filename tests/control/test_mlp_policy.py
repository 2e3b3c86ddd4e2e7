"""The numpy MLP policy: its arithmetic, its file, the evaluate CLI's dispatch by the header."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ihrcf_env.control.gru_policy import PolicyFileError
from ihrcf_env.control.mlp_policy import MlpPolicy, mlp_from_arrays


def _policy(rng: np.random.Generator, d: int = 6, hidden: int = 5, a: int = 4) -> MlpPolicy:
    layers = [
        (rng.normal(size=(d, hidden)), rng.normal(size=hidden)),
        (rng.normal(size=(hidden, hidden)), rng.normal(size=hidden)),
        (rng.normal(size=(hidden, a)) * 0.3, rng.normal(size=a) * 0.1),
    ]
    return mlp_from_arrays(layers, rng.normal(size=d), rng.uniform(0.5, 2.0, d), note="test")


def test_act_is_the_written_network() -> None:
    rng = np.random.default_rng(0)
    pol = _policy(rng)
    x = rng.normal(size=6)
    h = np.clip((x - pol.mean) / np.sqrt(pol.var + 1e-8), -10, 10)
    for w, b in zip(pol.weights[:-1], pol.biases[:-1], strict=True):
        z = w @ h + b
        h = z / (1.0 + np.exp(-z))  # swish
    want = np.clip(pol.weights[-1] @ h + pol.biases[-1], -1, 1)
    np.testing.assert_allclose(pol.act(x), want, rtol=1e-6, atol=1e-7)
    assert pol.act(x).dtype == np.float32 and pol.input_size == 6 and pol.action_size == 4


def test_save_load_round_trip(tmp_path: Path) -> None:
    pol = _policy(np.random.default_rng(1))
    path = tmp_path / "p.npz"
    pol.save(path)
    back = MlpPolicy.load(path)
    x = np.linspace(-1, 1, 6)
    np.testing.assert_array_equal(back.act(x), pol.act(x))
    assert back.meta == {"note": "test"} and MlpPolicy.is_mlp_file(path)


def test_bad_files_and_shapes_are_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(PolicyFileError, match="bad.npz"):
        MlpPolicy.load(bad)
    assert not MlpPolicy.is_mlp_file(bad)
    other = tmp_path / "other.npz"
    np.savez(other, header=np.array('{"format": 1}'))
    with pytest.raises(PolicyFileError, match="not an MLP policy"):
        MlpPolicy.load(other)
    rng = np.random.default_rng(2)
    with pytest.raises(ValueError, match="layer 1"):
        MlpPolicy([np.ones((3, 2)), np.ones((4, 2))], [np.ones(3), np.ones(4)], np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="activation"):
        MlpPolicy([np.ones((4, 2))], [np.ones(4)], np.zeros(2), np.ones(2), activation="gelu")
    with pytest.raises(ValueError, match="finite"):
        MlpPolicy([np.full((4, 2), np.nan)], [np.ones(4)], np.zeros(2), np.ones(2))
    with pytest.raises(ValueError, match="obs"):
        _policy(rng).act(np.zeros(5))


def test_make_policy_loads_an_mlp_file_for_a_matching_env(tmp_path: Path) -> None:
    import gymnasium as gym

    from ihrcf_env.experiments.policies import PolicyError, make_policy

    env = gym.make("ihrcf_env/DeckLanding-v2", camera_model="projected", camera_output="corners")
    try:
        d = env.observation_space.shape[0]  # type: ignore[index]
        rng = np.random.default_rng(3)
        good, wrong = tmp_path / "good.npz", tmp_path / "wrong.npz"
        _policy(rng, d=d).save(good)
        _policy(rng, d=d + 1).save(wrong)
        pol = make_policy(str(good), env)
        assert isinstance(pol, MlpPolicy)
        obs, _ = env.reset(seed=0)
        assert np.all(np.abs(pol.act(obs)) <= 1.0)
        with pytest.raises(PolicyError, match="flat observation"):
            make_policy(str(wrong), env)
    finally:
        env.close()
