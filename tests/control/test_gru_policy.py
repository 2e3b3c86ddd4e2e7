"""The numpy GRU policy: its equations, its file, its checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import corrupt_policy_files, policy_header, write_policy

from ihrcf_env.control.gru_policy import WEIGHTS, GruPolicy


def random_policy(
    d: int = 5, e: int = 6, h: int = 4, f: int = 3, obs_size: int = 8, seed: int = 0
) -> GruPolicy:
    rng = np.random.default_rng(seed)
    sizes = {"D": d, "E": e, "H": h, "3H": 3 * h, "F": f, "A": 4}
    w = {k: rng.normal(scale=0.5, size=tuple(sizes[x] for x in dims)) for k, dims in WEIGHTS.items()}
    w["std"] = np.abs(w["std"]) + 0.5
    return GruPolicy(w, list(range(1, 1 + d)), obs_size, {"note": "test"})


def reference_step(p: GruPolicy, obs: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """PyTorch's GRU cell written out gate by gate, one scalar at a time."""
    w = p.weights
    x = np.clip((obs[p.inputs] - w["mean"]) / w["std"], -10, 10)
    e = np.tanh(w["w_e"] @ x + w["b_e"])
    n_h = len(h)
    out = np.zeros(n_h)
    for k in range(n_h):

        def gate(g: int, k: int = k) -> tuple[float, float]:
            row = g * n_h + k
            return float(w["w_ih"][row] @ e + w["b_ih"][row]), float(w["w_hh"][row] @ h + w["b_hh"][row])

        r = 1 / (1 + np.exp(-sum(gate(0))))
        z = 1 / (1 + np.exp(-sum(gate(1))))
        i_n, h_n = gate(2)
        n = np.tanh(i_n + r * h_n)
        out[k] = (1 - z) * n + z * h[k]
    a = w["w_o"] @ np.tanh(w["w_h"] @ out + w["b_h"]) + w["b_o"]
    return np.clip(a, -1, 1), out


def test_a_step_follows_the_gru_equations_and_carries_the_state() -> None:
    p = random_policy()
    rng = np.random.default_rng(1)
    h = np.zeros(p.hidden_size)
    for _ in range(5):
        obs = rng.normal(size=p.obs_size).astype(np.float32)
        want, h = reference_step(p, obs.astype(np.float64), h)
        got = p.act(obs)
        assert got.dtype == np.float32 and got.shape == (4,)
        np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)
    assert np.abs(h).max() > 0  # the state moved: the next action depends on the past


def test_reset_starts_the_episode_over_and_batches_match_single_steps() -> None:
    p = random_policy()
    seq = np.random.default_rng(2).normal(size=(6, p.obs_size)).astype(np.float32)
    first = np.stack([p.act(o) for o in seq])
    p.reset()
    again = np.stack([p.act(o) for o in seq])
    np.testing.assert_array_equal(first, again)
    h = np.zeros((2, p.hidden_size))
    rows = []
    for o in seq:  # two episodes at once, the second one step behind the first
        a, h = p.step(np.stack([o, seq[0]]).astype(np.float64), h)
        rows.append(a[0])
    np.testing.assert_allclose(np.stack(rows), first, rtol=1e-6, atol=1e-7)


def test_save_and_load_give_the_same_policy(tmp_path: Path) -> None:
    p = random_policy()
    p = GruPolicy({k: v.astype(np.float32) for k, v in p.weights.items()}, p.inputs, p.obs_size, p.meta)
    path = tmp_path / "gru.npz"
    p.save(path)
    q = GruPolicy.load(path)
    assert q.inputs == p.inputs and q.obs_size == p.obs_size and q.meta == {"note": "test"}
    seq = np.random.default_rng(3).normal(size=(4, p.obs_size)).astype(np.float32)
    np.testing.assert_array_equal(np.stack([p.act(o) for o in seq]), np.stack([q.act(o) for o in seq]))


def test_bad_weights_inputs_files_and_observations_are_named(tmp_path: Path) -> None:
    p = random_policy()
    w = dict(p.weights)
    with pytest.raises(ValueError, match="w_ih"):
        GruPolicy({**w, "w_ih": np.zeros((3, 3))}, p.inputs, p.obs_size)
    with pytest.raises(ValueError, match="missing"):
        GruPolicy({k: v for k, v in w.items() if k != "b_o"}, p.inputs, p.obs_size)
    with pytest.raises(ValueError, match="not finite"):
        GruPolicy({**w, "b_e": np.full_like(w["b_e"], np.nan)}, p.inputs, p.obs_size)
    with pytest.raises(ValueError, match="std"):
        GruPolicy({**w, "std": np.zeros_like(w["std"])}, p.inputs, p.obs_size)
    with pytest.raises(ValueError, match="inputs"):
        GruPolicy(w, [0, 1, 2, 3, 99], p.obs_size)
    with pytest.raises(ValueError, match="obs"):
        p.act(np.zeros(p.obs_size + 1, np.float32))
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a policy")
    with pytest.raises(ValueError, match="junk.npz"):
        GruPolicy.load(junk)
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with pytest.raises(ValueError, match="other.npz"):
        GruPolicy.load(other)


def test_corrupt_policy_files_raise_the_package_error_naming_file_and_problem(tmp_path: Path) -> None:
    from ihrcf_env.control.gru_policy import PolicyFileError

    assert GruPolicy.load(write_policy(tmp_path / "ok.npz", policy_header())).obs_size == 8
    for kind, (path, word) in corrupt_policy_files(tmp_path).items():
        with pytest.raises(PolicyFileError) as exc:
            GruPolicy.load(path)
        text = str(exc.value)
        assert path.name in text and word in text, (kind, text)
        assert "allow_pickle" not in text and "\n" not in text, (kind, text)
