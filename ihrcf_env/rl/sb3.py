"""stable-baselines3 pieces for ``examples/train_ppo.py``: an observation normaliser stored in the
policy, curve-logging, held-out evaluation and resumable checkpoint callbacks.

Needs the ``[rl]`` extra (stable-baselines3, torch). A policy trained with
:class:`RunningNormExtractor` is one self-contained ``.zip`` (the normaliser's statistics are
buffers of the policy): ``PPO.load(path)`` needs only this module importable.
"""

from __future__ import annotations

import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env import VecNormalize

from ihrcf_env.rl.curves import EVAL_FIELDS, TRAIN_FIELDS, CsvLog, read_csv


class RunningNormExtractor(BaseFeaturesExtractor):
    """Flattens a Box observation, keeps the entries ``inputs`` (indices into the flat observation;
    None: all) and standardises them with running statistics:
    ``clip((x - mean) / sqrt(var + eps), -clip, clip)``.

    The statistics (buffers ``mean``, ``var``, ``count``, over the whole observation) change only
    through :meth:`update` (called by :class:`NormUpdateCallback`), never inside ``forward``; they
    are saved with the policy, and so are ``inputs`` (the policy's own choice of what it reads: the
    observation space, and so the env, stay the same)."""

    mean: th.Tensor
    var: th.Tensor
    count: th.Tensor
    inputs: th.Tensor

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        clip: float = 10.0,
        eps: float = 1e-4,
        inputs: Sequence[int] | None = None,
    ):
        n = int(np.prod(observation_space.shape))
        keep = np.arange(n) if inputs is None else np.asarray(list(inputs), dtype=np.int64)
        if (
            keep.ndim != 1
            or len(keep) == 0
            or keep.min() < 0
            or keep.max() >= n
            or len(set(keep)) != len(keep)
        ):
            raise ValueError(f"inputs must be distinct indices in [0, {n}), got {inputs!r}")
        super().__init__(observation_space, features_dim=len(keep))
        if not clip > 0 or not eps > 0:
            raise ValueError(f"clip and eps must be > 0, got clip={clip!r}, eps={eps!r}")
        self.clip = float(clip)
        self.eps = float(eps)
        self.size = n
        self.register_buffer("inputs", th.as_tensor(keep), persistent=False)  # from the constructor
        self.register_buffer("mean", th.zeros(n, dtype=th.float64))
        self.register_buffer("var", th.ones(n, dtype=th.float64))
        self.register_buffer("count", th.zeros((), dtype=th.float64))

    def forward(self, observations: th.Tensor) -> th.Tensor:
        x = th.flatten(observations, start_dim=1).float()[:, self.inputs]
        mean, std = self.mean[self.inputs].float(), th.sqrt(self.var[self.inputs] + self.eps).float()
        return th.clamp((x - mean) / std, -self.clip, self.clip)

    @th.no_grad()
    def update(self, batch: np.ndarray) -> None:
        """Merge a batch of observations (any leading shape, then the observation's) into the
        statistics (Chan et al.'s parallel mean/variance); non-finite rows are ignored."""
        x = np.asarray(batch, dtype=np.float64).reshape(-1, self.size)
        x = x[np.isfinite(x).all(axis=1)]
        if len(x) == 0:
            return
        b_mean, b_var, b_n = x.mean(axis=0), x.var(axis=0), float(len(x))
        mean, var, n = self.mean.cpu().numpy(), self.var.cpu().numpy(), float(self.count)
        if n == 0:
            new_mean, new_var = b_mean, b_var
        else:
            tot = n + b_n
            delta = b_mean - mean
            new_mean = mean + delta * b_n / tot
            new_var = (var * n + b_var * b_n + delta**2 * n * b_n / tot) / tot
        self.mean.copy_(th.as_tensor(new_mean))
        self.var.copy_(th.as_tensor(new_var))
        self.count.fill_(n + b_n)


def norm_extractors(model: BaseAlgorithm) -> list[RunningNormExtractor]:
    """Every :class:`RunningNormExtractor` in the model's policy (one if shared, else actor + critic)."""
    return [m for m in model.policy.modules() if isinstance(m, RunningNormExtractor)]


def set_initial_action_mean(model: BaseAlgorithm, mean: Sequence[float]) -> None:
    """Set the bias of a fresh Gaussian policy's action layer to ``mean`` (action units). SB3
    initialises that layer's weights 100x smaller than the others, so the untrained policy's mean
    action is ``mean`` (up to ~1e-2): e.g. a landing policy that starts by descending."""
    net = getattr(model.policy, "action_net", None)
    if not isinstance(net, th.nn.Linear):
        raise TypeError(f"the policy has no linear action_net, got {type(net).__name__}")
    m = np.asarray(mean, dtype=np.float64)
    if m.shape != (net.out_features,) or not np.isfinite(m).all():
        raise ValueError(f"mean must be {net.out_features} finite numbers, got {list(mean)!r}")
    with th.no_grad():
        net.bias.copy_(th.as_tensor(m, dtype=net.bias.dtype))


class NormUpdateCallback(BaseCallback):
    """Feeds each rollout's observations to the policy's :class:`RunningNormExtractor` after the
    update that trains on them, so that a rollout is collected and trained on with the same
    statistics (PPO's first-epoch ratio stays exactly 1)."""

    def __init__(self) -> None:
        super().__init__()
        self._pending: np.ndarray | None = None

    def _on_rollout_end(self) -> None:
        if not isinstance(self.model, OnPolicyAlgorithm):
            raise TypeError(
                f"NormUpdateCallback needs an on-policy algorithm, got {type(self.model).__name__}"
            )
        self._pending = np.array(self.model.rollout_buffer.observations, copy=True)

    def _on_rollout_start(self) -> None:
        if self._pending is not None:
            for ext in norm_extractors(self.model):
                ext.update(self._pending)
            self._pending = None

    def _on_step(self) -> bool:
        return True


class EpisodeCsvCallback(BaseCallback):
    """Appends one row per finished training episode (from VecMonitor's ``info["episode"]`` and
    ``info["is_success"]``) to a :class:`~ihrcf_env.rl.curves.CsvLog` with ``TRAIN_FIELDS``."""

    def __init__(self, log: CsvLog):
        super().__init__()
        if log.fields != TRAIN_FIELDS:
            raise ValueError(f"log must have the fields {TRAIN_FIELDS}, got {log.fields}")
        self.log = log

    def _on_step(self) -> bool:
        for info in self.locals.get("infos", ()):
            ep = info.get("episode")
            if ep is not None:
                succ = ep.get("is_success", info.get("is_success", False))
                row = {"timesteps": self.num_timesteps, "return": float(ep["r"]), "length": int(ep["l"])}
                self.log.write(row | {"is_success": int(bool(succ))})
        return True


@dataclass(frozen=True)
class EvalResult:
    """Episodes of one evaluation: ``returns``, ``lengths`` (steps), ``successes`` (0/1), per seed."""

    seeds: tuple[int, ...]
    returns: tuple[float, ...]
    lengths: tuple[int, ...]
    successes: tuple[int, ...]

    @property
    def success_rate(self) -> float:
        return float(np.mean(self.successes)) if self.successes else math.nan

    @property
    def mean_return(self) -> float:
        return float(np.mean(self.returns)) if self.returns else math.nan


def evaluate_on_seeds(
    model: BaseAlgorithm, env: gym.Env, seeds: Sequence[int], deterministic: bool = True
) -> EvalResult:
    """Run one episode per seed (``env.reset(seed=s)``) with ``model.predict``; success is
    ``info["is_success"]`` at the episode's end."""
    rets, lens, succ = [], [], []
    for s in seeds:
        obs, info = env.reset(seed=int(s))
        ret, n, done = 0.0, 0, False
        while not done:
            action, _ = model.predict(obs, deterministic=deterministic)
            obs, reward, terminated, truncated, info = env.step(action)
            ret, n, done = ret + float(reward), n + 1, bool(terminated or truncated)
        rets.append(ret)
        lens.append(n)
        succ.append(int(bool(info.get("is_success", False))))
    return EvalResult(tuple(int(s) for s in seeds), tuple(rets), tuple(lens), tuple(succ))


class HeldOutEvalCallback(BaseCallback):
    """Between updates, once every ``every`` environment steps, and after the last update,
    evaluates the deterministic policy on ``seeds`` (never used for training) in
    ``make_eval_env()``, appends a row to ``log`` (``EVAL_FIELDS``) and saves the best policy so far
    (success rate, then mean return) to ``best_path``. ``start_time`` (``time.time()``) is the run's
    start for ``wall_s`` (default: now, less the last kept row's ``wall_s`` when ``log`` kept rows
    of a resumed run)."""

    def __init__(
        self,
        make_eval_env: Callable[[], gym.Env],
        seeds: Sequence[int],
        every: int,
        log: CsvLog,
        best_path: str | os.PathLike[str] | None = None,
        start_time: float | None = None,
        verbose: int = 1,
    ):
        super().__init__(verbose)
        if every < 1 or not seeds:
            raise ValueError(f"every must be >= 1 and seeds non-empty, got every={every!r}, seeds={seeds!r}")
        if log.fields != EVAL_FIELDS:
            raise ValueError(f"log must have the fields {EVAL_FIELDS}, got {log.fields}")
        self.make_eval_env, self.seeds, self.every, self.log = make_eval_env, tuple(seeds), every, log
        self.best_path = None if best_path is None else Path(best_path)
        kept = read_csv(log.path)  # a resumed run's rows: its best, last evaluation and wall time go on
        self.best = max(
            ((float(r["success_rate"]), float(r["mean_return"])) for r in kept), default=(-math.inf,) * 2
        )
        self._evaluated_at = int(float(kept[-1]["timesteps"])) if kept else -1
        offset = float(kept[-1]["wall_s"]) if kept else 0.0
        self.start_time = (time.time() - offset) if start_time is None else start_time
        self._env: gym.Env | None = None
        self._last = 0

    def _init_callback(self) -> None:
        n = self.model.num_timesteps
        self._last = n - n % self.every

    def evaluate(self) -> None:
        """Evaluate the model now (it must be set: ``init_callback(model)`` or training)."""
        if self._env is None:
            self._env = self.make_eval_env()
        n = self.model.num_timesteps
        res = evaluate_on_seeds(self.model, self._env, self.seeds)
        row = {
            "timesteps": n,
            "wall_s": round(time.time() - self.start_time, 1),
            "mean_return": res.mean_return,
            "std_return": float(np.std(res.returns)),
            "success_rate": res.success_rate,
            "mean_length": float(np.mean(res.lengths)),
        }
        self.log.write(row)
        self._evaluated_at = n
        score = (res.success_rate, res.mean_return)
        if score > self.best:
            self.best = score
            if self.best_path is not None:
                self.model.save(self.best_path)
        if self.verbose:
            print(
                f"eval @ {n} steps: success {sum(res.successes)}/{len(self.seeds)}, "
                f"return {res.mean_return:.1f}, length {row['mean_length']:.0f}, wall {row['wall_s']:.0f} s",
                flush=True,
            )

    def _on_rollout_start(self) -> None:  # the policy was just updated on every step so far
        n = self.model.num_timesteps
        if n - self._last >= self.every:
            self._last = n - n % self.every
            self.evaluate()

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:  # the last update, unless already evaluated
        if self.model.num_timesteps > self._evaluated_at:
            self.evaluate()
        if self._env is not None:
            self._env.close()
            self._env = None


class WallClockBudgetCallback(BaseCallback):
    """Stops training (after the current step; the other callbacks' end-of-training work still runs)
    once ``time.time()`` passes ``deadline`` (a ``time.time()`` value), so a run fits a wall-clock
    budget and ends with its final evaluation and checkpoint."""

    def __init__(self, deadline: float):
        super().__init__()
        self.deadline = float(deadline)
        self.stopped = False

    def _on_step(self) -> bool:
        if time.time() >= self.deadline:
            self.stopped = True
            return False
        return True


class CurriculumCallback(BaseCallback):
    """Raises the level of every training env's :class:`~ihrcf_env.rl.curriculum.StartCurriculum`
    linearly from 0 to 1 over the first ``steps`` environment steps (set before each rollout, so a
    resumed run goes on at its level)."""

    def __init__(self, steps: int):
        super().__init__()
        if steps < 1:
            raise ValueError(f"steps must be >= 1, got {steps!r}")
        self.steps = int(steps)
        self.level = 0.0

    def _set_level(self) -> None:
        self.level = min(1.0, self.model.num_timesteps / self.steps)
        self.training_env.env_method("set_curriculum_level", self.level)

    def _on_training_start(self) -> None:
        self._set_level()

    def _on_rollout_start(self) -> None:
        self._set_level()

    def _on_step(self) -> bool:
        return True


class CriticWarmupCallback(BaseCallback):
    """Trains only the critic for the first ``steps`` environment steps: the actor (its network,
    action layer and log std) is frozen, so a warm-started actor (e.g. :mod:`ihrcf_env.rl.imitation`)
    is not moved by the advantages of a critic that has not learnt the returns yet."""

    def __init__(self, steps: int):
        super().__init__()
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps!r}")
        self.steps = int(steps)

    def _actor_parameters(self) -> list[th.nn.Parameter]:
        p = self.model.policy
        return [*p.mlp_extractor.policy_net.parameters(), *p.action_net.parameters(), p.log_std]

    def _on_rollout_end(self) -> None:  # the update follows: freeze or release the actor for it
        train_actor = self.model.num_timesteps > self.steps
        for param in self._actor_parameters():
            param.requires_grad_(train_actor)

    def _on_training_end(self) -> None:
        for param in self._actor_parameters():
            param.requires_grad_(True)

    def _on_step(self) -> bool:
        return True


class ResumableCheckpointCallback(BaseCallback):
    """Between updates, once every ``every`` environment steps, and at the end, saves the model to
    ``<directory>/latest.zip`` (and a :class:`VecNormalize` wrapper's statistics to
    ``<directory>/vecnormalize.pkl``), each through a temporary file, so a run stopped at any moment
    resumes from the last complete checkpoint. With ``keep`` (default) a copy of each model stays as
    ``<directory>/steps_<N>.zip``, for choosing a checkpoint afterwards on validation episodes."""

    def __init__(self, directory: str | os.PathLike[str], every: int, keep: bool = True):
        super().__init__()
        if every < 1:
            raise ValueError(f"every must be >= 1, got {every!r}")
        self.directory, self.every, self._last, self.keep = Path(directory), every, 0, keep

    @property
    def model_path(self) -> Path:
        return self.directory / "latest.zip"

    @property
    def vecnormalize_path(self) -> Path:
        return self.directory / "vecnormalize.pkl"

    def _init_callback(self) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        self._last = self.model.num_timesteps

    def save(self) -> None:
        """Write the checkpoint now."""
        tmp = self.directory / "latest.tmp.zip"
        self.model.save(tmp)
        vn = self.model.get_vec_normalize_env()
        if vn is not None:
            tmp_vn = self.directory / "vecnormalize.tmp.pkl"
            vn.save(str(tmp_vn))
            os.replace(tmp_vn, self.vecnormalize_path)
        if self.keep:
            shutil.copyfile(tmp, self.directory / f"steps_{self.model.num_timesteps}.zip")
        os.replace(tmp, self.model_path)

    def _on_rollout_start(self) -> None:  # between updates: policy, optimizer and step count agree
        if self.model.num_timesteps - self._last >= self.every:
            self._last = self.model.num_timesteps
            self.save()

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        self.save()


def load_vecnormalize(path: Path, venv: Any) -> Any:
    """``VecNormalize.load`` of a checkpoint's statistics around ``venv`` (training mode)."""
    vn = VecNormalize.load(str(path), venv)
    vn.training = True
    return vn


__all__ = [
    "CriticWarmupCallback",
    "CurriculumCallback",
    "EpisodeCsvCallback",
    "EvalResult",
    "HeldOutEvalCallback",
    "NormUpdateCallback",
    "ResumableCheckpointCallback",
    "RunningNormExtractor",
    "WallClockBudgetCallback",
    "evaluate_on_seeds",
    "load_vecnormalize",
    "norm_extractors",
    "set_initial_action_mean",
]
