"""PPO on a functional JAX env (rejax), its checkpoints and the exported numpy policy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.rl
jax = pytest.importorskip("jax")
pytest.importorskip("rejax")

from functional_toy import Drop  # noqa: E402

from ihrcf_env.control.mlp_policy import MlpPolicy  # noqa: E402
from ihrcf_env.rl.jax_ppo import PPOSettings, _mean_action, export_policy, train  # noqa: E402

SETTINGS = PPOSettings(num_envs=16, num_steps=16, num_minibatches=4, hidden=(16, 16))


def test_train_runs_resumes_and_exports(tmp_path: Path) -> None:
    fenv = Drop()
    lines: list[str] = []
    algo, ts, curve = train(fenv, tmp_path, 6144, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert [r["steps"] for r in curve] == [2048, 4096, 6144]
    assert all(np.isfinite(r["return"]) for r in curve)
    # a second call resumes from the folder and trains on
    _, ts2, curve2 = train(fenv, tmp_path, 8192, 40, SETTINGS, chunk_timesteps=2048, log=lines.append)
    assert len(curve2) == 4 and any("resumed" in line for line in lines)
    # the exported policy acts as the trained actor's mean
    pol = export_policy(algo, ts2, tmp_path / "p.npz", trained="toy")
    back = MlpPolicy.load(tmp_path / "p.npz")
    act = _mean_action(algo, ts2)
    for obs in np.random.default_rng(0).normal(size=(5, 2)).astype(np.float32):
        np.testing.assert_allclose(back.act(obs), np.asarray(act(obs)), atol=2e-5)
    assert pol.meta == {"trained": "toy"}
