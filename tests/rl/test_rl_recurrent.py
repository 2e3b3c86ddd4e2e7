"""Recurrent DAgger (``rl`` marker): the torch network is the numpy policy, the fit learns what
needs memory, and a tiny run writes its files and continues from its checkpoint."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ihrcf_env.control.gru_policy import GruPolicy

pytestmark = pytest.mark.rl


@pytest.fixture
def th() -> Any:
    """torch (the test is skipped without the ``[rl]`` extra; imported here, not at collection, so
    the default run deselects these tests instead of skipping the module)."""
    return pytest.importorskip("torch")


@pytest.fixture
def rec(th: Any) -> Any:
    """``ihrcf_env.rl.recurrent`` (it imports torch)."""
    import ihrcf_env.rl.recurrent as rec

    return rec


def test_the_exported_policy_computes_what_the_network_does(th: Any, rec: Any) -> None:
    net = rec.GruNet(6, 16, 12, 8)
    net.set_normaliser(np.random.default_rng(0).normal(size=(50, 6)))
    policy = net.export(list(range(1, 7)), 7, {})
    x = np.random.default_rng(1).normal(size=(30, 7)).astype(np.float32)
    with th.no_grad():
        ref, _ = net(th.as_tensor(x[None, :, 1:]))
    got = np.stack([policy.act(o) for o in x])
    np.testing.assert_allclose(got, np.clip(ref[0].numpy(), -1, 1), atol=1e-5)


def test_the_fit_learns_a_label_that_needs_memory(th: Any, rec: Any) -> None:
    """The label is the sign shown at the first step only: a memoryless fit cannot beat a loss of
    about 1 on it (half the steps see no sign); the GRU carries it through the episode."""
    rng = np.random.default_rng(2)
    episodes = []
    for k in range(48):
        sign = 1.0 if k % 2 else -1.0
        obs = rng.normal(scale=0.1, size=(20, 3)).astype(np.float32)
        obs[0, 0] = sign
        labels = np.zeros((20, 4), np.float32)
        labels[:, 0] = 0.8 * sign
        episodes.append(rec.Episode(k, obs, labels, True, "success"))
    th.manual_seed(0)
    net = rec.GruNet(3, 16, 16, 16)
    loss = rec.fit(net, episodes, [0, 1, 2], epochs=60, lr=3e-3, batch=8)
    assert loss < 0.02  # 0.64 / 4 per step for a constant 0 prediction
    policy = net.export([0, 1, 2], 3, {})
    for sign in (-1.0, 1.0):
        policy.reset()
        seq = rng.normal(scale=0.1, size=(20, 3)).astype(np.float32)
        seq[0, 0] = sign
        actions = np.stack([policy.act(o) for o in seq])
        assert np.all(np.sign(actions[5:, 0]) == sign)


def test_a_tiny_run_writes_its_policies_and_resumes(tmp_path: Path, rec: Any) -> None:
    cfg = rec.RunConfig(
        "ihrcf_env/DeckLanding-v2",
        tmp_path,
        {"level": "calm", "max_episode_steps": 40},
        ("ihrcf", "atda"),
        rounds=1,
        episodes=2,
        val_seeds=(20_000,),
        epochs=2,
        first_epochs=2,
        embed=8,
        hidden=8,
        head=8,
        workers=1,
    )
    lines: list[str] = []
    best = rec.train(cfg, lines.append)
    assert isinstance(best, GruPolicy) and best.hidden_size == 8
    for name in ("best.npz", "final.npz", "round_0.npz", "round_1.npz", "dagger.csv", "checkpoint.pt"):
        assert (tmp_path / name).is_file(), name
    with (tmp_path / "dagger.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["round"] for r in rows] == ["0", "1"] and [r["stage"] for r in rows] == ["expert", "learner"]
    assert all(r["val_episodes"] == "1" for r in rows)
    assert int(rows[1]["samples"]) > int(rows[0]["samples"]) > 0
    # a longer run on the same folder continues after round 1 with the data kept, then polishes
    more = rec.RunConfig(**{**cfg.__dict__, "rounds": 2, "polish_epochs": 2})
    lines.clear()
    rec.train(more, lines.append)
    assert lines[0].startswith("resuming after round 1")
    assert lines[-1].startswith("polish: 2 epochs") and (tmp_path / "polished.npz").is_file()
    with (tmp_path / "dagger.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [(r["round"], r["stage"]) for r in rows] == [
        ("0", "expert"),
        ("1", "learner"),
        ("2", "learner"),
        ("2", "polish"),
    ]
    lines.clear()
    rec.train(more, lines.append)  # nothing left to do: no round flown, no second polish
    assert len(lines) == 1 and lines[0].startswith("resuming after round 2")


def test_a_run_flown_by_the_vector_env_logs_the_same_rounds(tmp_path: Path, rec: Any) -> None:
    """``vector_envs``: the rounds are flown by one vector env and logged as with
    single envs; the episodes of round 0 (the expert's) are those of single envs of the same
    options, so the logged samples and landings agree with a single-env run."""
    base = {
        "env_id": "ihrcf_env/DeckLanding-v2",
        "env_kw": {"level": "calm", "max_episode_steps": 30},
        "drop_inputs": ("ihrcf", "atda"),
        "rounds": 0,
        "episodes": 3,
        "val_seeds": (20_000, 20_001),
        "epochs": 1,
        "first_epochs": 1,
        "embed": 8,
        "hidden": 8,
        "head": 8,
        "workers": 1,
    }
    rows = []
    for k, vector in enumerate((0, 2)):
        out = tmp_path / str(k)
        rec.train(rec.RunConfig(out=out, vector_envs=vector, **base), lambda s: None)
        with (out / "dagger.csv").open() as f:
            rows.append(next(csv.DictReader(f)))
    keys = ("samples", "episodes", "successes", "val_episodes", "loss")
    assert [rows[0][k] for k in keys] == [rows[1][k] for k in keys]


def test_the_fit_gives_the_same_weights_on_any_number_of_threads(tmp_path: Path, rec: Any) -> None:
    """``fit_threads``: the fit of a round on 1 or 2 torch threads gives the same weights, and the
    caller's thread count is restored after it."""
    import torch as th

    base = {
        "env_id": "ihrcf_env/DeckLanding-v2",
        "env_kw": {"level": "calm", "max_episode_steps": 30},
        "rounds": 0,
        "episodes": 2,
        "first_epochs": 2,
        "embed": 16,
        "hidden": 16,
        "head": 8,
        "workers": 1,
    }
    before = th.get_num_threads()
    weights = []
    for k, threads in enumerate((1, 2)):
        out = tmp_path / str(k)
        rec.train(rec.RunConfig(out=out, fit_threads=threads, **base), lambda s: None)
        assert th.get_num_threads() == before
        with np.load(out / "round_0.npz") as z:
            weights.append({name: z[name] for name in z.files if name != "meta"})
    assert weights[0].keys() == weights[1].keys()
    for name in weights[0]:
        np.testing.assert_array_equal(weights[0][name], weights[1][name])
    with pytest.raises(ValueError, match="fit_threads"):
        rec.train(rec.RunConfig(out=tmp_path / "bad", fit_threads=0, **base), lambda s: None)
