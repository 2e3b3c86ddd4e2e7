"""DAgger warm start of a stable-baselines3 policy from the scripted landing controller.

PPO from scratch plateaus near 60 % success on ``ihrcf_env/DeckLanding-v1`` (README). The package's
:class:`~ihrcf_env.control.policies.ScriptedLanding` lands every time on the *same* observation the
policy sees (own sensing only, no ground truth), so it can teach the policy where PPO's exploration
finds little. DAgger (Ross, Gordon and Bagnell, AISTATS 2011): round 0 flies the expert and records
(observation, expert action); every later round flies the current learner (deterministic mean plus
Gaussian ``noise``) while one expert per env runs alongside on the learner's observations and labels
them; the policy's Gaussian mean is regressed (mean squared error) on all pairs so far after each
round. The policy's observation normaliser (:class:`~ihrcf_env.rl.sb3.RunningNormExtractor`) is set
to the statistics of the data. PPO then fine-tunes the result on the task's reward.

Needs the ``[rl]`` extra (torch). Seeds: the episodes of round ``r`` start from ``seed + 1000 r``
(env ``k`` of a vector env adds ``k``).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm

from ihrcf_env.control.policies import LANDING_CONFIGS, V1_LANDING_CONFIG, Policy, ScriptedLanding
from ihrcf_env.rl.curves import CsvLog
from ihrcf_env.rl.sb3 import norm_extractors

#: Columns of the DAgger log (``timesteps``: PPO steps so far, 0; ``expert_flies``: 1 in round 0).
DAGGER_FIELDS = ("timesteps", "round", "expert_flies", "episodes", "successes", "samples", "loss", "wall_s")


@dataclass
class Round:
    """One DAgger round: who flew, episodes flown and landed, samples so far, fit loss after it."""

    round: int
    pilot: str
    episodes: int
    successes: int
    samples: int
    loss: float


def collect(
    venv: Any,
    experts: Sequence[Policy],
    episodes: int,
    seed: int,
    learner: BaseAlgorithm | None = None,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Fly ``episodes`` episodes (at least; all envs run until the count is reached) on the SB3
    vector env ``venv`` with the expert (``learner=None``) or the learner's deterministic action plus
    ``noise`` (action units, from ``rng``); every step is labelled by ``experts[k]`` (one per env,
    reset at each episode start; it reads the newest frame of a stacked observation). Returns
    (observations, expert actions clipped to [-1, 1], successes, episodes flown)."""
    n = venv.num_envs
    if len(experts) != n:
        raise ValueError(f"need one expert per env ({n}), got {len(experts)}")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes!r}")
    if noise < 0 or (noise > 0 and rng is None):
        raise ValueError(f"noise must be >= 0 (and needs rng), got {noise!r}")
    venv.seed(seed)
    obs = venv.reset()
    for e in experts:
        e.reset()
    observations, actions = [], []
    flown = landed = 0
    while flown < episodes:
        label = np.stack([np.asarray(experts[k].act(_latest(obs[k])), dtype=np.float32) for k in range(n)])
        observations.append(np.array(obs, dtype=np.float32, copy=True))
        actions.append(np.clip(label, -1.0, 1.0))
        if learner is None:
            act = label
        else:
            act, _ = learner.predict(obs, deterministic=True)
            if noise > 0 and rng is not None:
                act = act + noise * rng.standard_normal(act.shape)
        obs, _, dones, infos = venv.step(np.clip(act, -1.0, 1.0).astype(np.float32))
        for k in range(n):
            if dones[k]:
                flown += 1
                landed += bool(infos[k].get("is_success", False))
                experts[k].reset()
    return np.concatenate(observations), np.concatenate(actions), landed, flown


def _latest(obs: np.ndarray) -> np.ndarray:
    """The newest frame of a stacked observation (``(frames, D)``, oldest first); a flat one as is."""
    return obs[-1] if np.ndim(obs) == 2 else obs


def fit_policy(
    model: BaseAlgorithm,
    observations: np.ndarray,
    actions: np.ndarray,
    epochs: int = 40,
    lr: float = 1e-3,
    batch_size: int = 256,
) -> float:
    """Regress the policy's Gaussian mean on ``actions`` (MSE, Adam) after setting its observation
    normaliser to the statistics of ``observations``; returns the last epoch's mean loss."""
    if len(observations) != len(actions) or len(actions) == 0:
        raise ValueError(f"need matching non-empty data, got {len(observations)} and {len(actions)} rows")
    for ext in norm_extractors(model):
        ext.mean.zero_()
        ext.var.fill_(1.0)
        ext.count.zero_()
        ext.update(observations)
    policy = model.policy
    obs_t = th.as_tensor(observations, dtype=th.float32)
    act_t = th.as_tensor(actions, dtype=th.float32)
    opt = th.optim.Adam(policy.parameters(), lr=lr)
    loss_mean = float("nan")
    for _ in range(epochs):
        order = th.randperm(len(obs_t))
        total = 0.0
        for start in range(0, len(obs_t), batch_size):
            idx = order[start : start + batch_size]
            mean = policy.get_distribution(obs_t[idx]).distribution.mean
            loss = th.mean((mean - act_t[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        loss_mean = total / len(obs_t)
    return loss_mean


def dagger(
    model: BaseAlgorithm,
    venv: Any,
    make_expert: Callable[[], Policy],
    rounds: int,
    episodes: int,
    seed: int,
    noise: float = 0.05,
    epochs: int = 40,
    log: Callable[[Round], None] | None = None,
) -> list[Round]:
    """DAgger (module docstring): round 0 (expert) plus ``rounds`` learner rounds of ``episodes``
    episodes each on ``venv``; ``model``'s policy ends fitted on all the data. Returns the rounds."""
    if rounds < 0:
        raise ValueError(f"rounds must be >= 0, got {rounds!r}")
    experts = [make_expert() for _ in range(venv.num_envs)]
    rng = np.random.default_rng(seed)
    data_o: list[np.ndarray] = []
    data_a: list[np.ndarray] = []
    history: list[Round] = []
    for r in range(rounds + 1):
        learner = model if r > 0 else None
        o, a, landed, flown = collect(venv, experts, episodes, seed + 1000 * r, learner, noise * (r > 0), rng)
        data_o.append(o)
        data_a.append(a)
        loss = fit_policy(model, np.concatenate(data_o), np.concatenate(data_a), epochs)
        history.append(
            Round(r, "expert" if r == 0 else "learner", flown, landed, sum(map(len, data_o)), loss)
        )
        if log is not None:
            log(history[-1])
    return history


def warm_start(
    model: BaseAlgorithm,
    venv: Any,
    make_env: Callable[[], gym.Env],
    rounds: int,
    episodes: int,
    seed: int,
    csv_path: str | Path,
    noise: float = 0.05,
    commit_below: float = 0.1,
) -> list[Round]:
    """:func:`dagger` with the scripted landing as the expert (its layout read from one
    ``make_env()`` env, closed after; the task's tunables
    (:data:`~ihrcf_env.control.policies.LANDING_CONFIGS`) with
    ``commit_below``: the learner cannot see the expert's wait-or-drop state, so once it has
    descended ``commit_below`` m under the hold height the expert labels a drop, not a climb back),
    one row per round in ``csv_path`` (:data:`DAGGER_FIELDS`) and a printed line."""
    probe = make_env()
    log = CsvLog(csv_path, DAGGER_FIELDS)
    t0 = time.time()

    def write(r: Round) -> None:
        wall = round(time.time() - t0, 1)
        log.write(
            {
                "timesteps": 0,
                "round": r.round,
                "expert_flies": int(r.pilot == "expert"),
                "episodes": r.episodes,
                "successes": r.successes,
                "samples": r.samples,
                "loss": r.loss,
                "wall_s": wall,
            }
        )
        print(
            f"DAgger round {r.round}: {r.pilot} landed {r.successes}/{r.episodes}, "
            f"{r.samples} samples, fit loss {r.loss:.2e}, wall {wall:.0f} s",
            flush=True,
        )

    try:
        task = str(getattr(probe.unwrapped, "task_name", ""))
        base = LANDING_CONFIGS.get(task, V1_LANDING_CONFIG)
        config = dataclasses.replace(base, commit_below=commit_below)
        expert = functools.partial(ScriptedLanding.from_env, probe, config=config)
        return dagger(model, venv, expert, rounds, episodes, seed, noise, log=write)
    finally:
        probe.close()


__all__ = [
    "DAGGER_FIELDS",
    "Round",
    "collect",
    "dagger",
    "fit_policy",
    "warm_start",
]
