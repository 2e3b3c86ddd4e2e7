"""DAgger on whole episodes for a recurrent landing policy (:class:`~ihrcf_env.control.gru_policy.GruPolicy`).

The scripted landing carries state from step to step (filtered heave and tilt, a low-passed lean,
a dead-reckoned tag, how long it has waited at the hold height) that one observation does not
show, so a memoryless policy imitates it only partly. Here the learner is a GRU (:class:`GruNet`)
and DAgger (Ross, Gordon and Bagnell 2011) is run on sequences: round 0 flies the scripted landing;
every later round flies the current learner (its action plus Gaussian ``noise``) while the scripted
landing runs alongside on the same observations and labels every step; after each round the GRU is
regressed (mean squared error, back-propagation through whole episodes) on every episode so far,
its input normaliser set to the data's statistics. After each round the learner also flies the
validation seeds without noise; the best round on them is kept (``best.npz``). The validation of
round r and the episodes of round r + 1 have the same pilot, so they are flown as one queue.

Episodes are flown (:mod:`ihrcf_env.rl.episodes`) by single envs in ``workers`` processes, each
with its own env and expert, or with ``vector_envs`` > 0 by one native vector env of that many envs
(over ``workers`` processes), an expert per env; the policy they fly is the numpy
:class:`~ihrcf_env.control.gru_policy.GruPolicy`, so the flyers do not need PyTorch. Needs the
``[rl]`` extra (torch) for the fit.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

from ihrcf_env.control.gru_policy import GruPolicy
from ihrcf_env.core.checks import check_int
from ihrcf_env.rl.curves import CsvLog
from ihrcf_env.rl.envs import input_indices, make_env
from ihrcf_env.rl.episodes import Episode, Flight, Pool, VectorFlyer
from ihrcf_env.rl.ppo_args import DAGGER_SEED_BASE

#: Columns of the recurrent DAgger log (``timesteps``: env steps flown so far; ``stage``: ``expert``
#: (round 0), ``learner`` (a DAgger round) or ``polish`` (the final fit after the last round, with
#: that round's number; no episodes flown)).
RECURRENT_FIELDS = (
    "timesteps",
    "round",
    "stage",
    "episodes",
    "successes",
    "samples",
    "loss",
    "val_episodes",
    "val_successes",
    "wall_s",
)


class GruNet(th.nn.Module):
    """The trainable form of :class:`~ihrcf_env.control.gru_policy.GruPolicy` (the same equations)."""

    mean: th.Tensor
    std: th.Tensor

    def __init__(
        self, n_in: int, embed: int = 128, hidden: int = 128, head: int = 64, n_act: int = 4
    ) -> None:
        super().__init__()
        self.register_buffer("mean", th.zeros(n_in))
        self.register_buffer("std", th.ones(n_in))
        self.embed = th.nn.Linear(n_in, embed)
        self.gru = th.nn.GRU(embed, hidden, batch_first=True)
        self.head = th.nn.Linear(hidden, head)
        self.out = th.nn.Linear(head, n_act)

    def forward(self, x: th.Tensor, h0: th.Tensor | None = None) -> tuple[th.Tensor, th.Tensor]:
        """Actions (B, T, A), unclipped, and the last state (1, B, H) for inputs (B, T, D)."""
        z = th.clamp((x - self.mean) / self.std, -10.0, 10.0)
        y, h = self.gru(th.tanh(self.embed(z)), h0)
        return self.out(th.tanh(self.head(y))), h

    def set_normaliser(self, x: np.ndarray, floor: float = 1e-2) -> None:
        """Input mean and std (floored at ``floor``) from the rows of ``x`` (N, D)."""
        self.mean.copy_(th.as_tensor(x.mean(axis=0), dtype=th.float32))
        self.std.copy_(th.as_tensor(np.maximum(x.std(axis=0), floor), dtype=th.float32))

    def export(self, inputs: Sequence[int], obs_size: int, meta: dict[str, Any]) -> GruPolicy:
        """This network as a numpy :class:`GruPolicy` reading ``inputs`` of the flat observation."""

        sd = {k: v.detach().cpu().numpy().astype(np.float64) for k, v in self.state_dict().items()}
        names = {
            "mean": "mean",
            "std": "std",
            "w_e": "embed.weight",
            "b_e": "embed.bias",
            "w_ih": "gru.weight_ih_l0",
            "w_hh": "gru.weight_hh_l0",
            "b_ih": "gru.bias_ih_l0",
            "b_hh": "gru.bias_hh_l0",
            "w_h": "head.weight",
            "b_h": "head.bias",
            "w_o": "out.weight",
            "b_o": "out.bias",
        }
        w = {k: sd[v] for k, v in names.items()}
        return GruPolicy(w, inputs, obs_size, meta)


@contextlib.contextmanager
def torch_threads(n: int) -> Iterator[None]:
    """torch's intra-op threads set to ``n`` (>= 1) inside the block, restored after it."""
    before = th.get_num_threads()
    th.set_num_threads(n)
    try:
        yield
    finally:
        th.set_num_threads(before)


def fit(
    net: GruNet,
    episodes: Sequence[Episode],
    inputs: Sequence[int],
    epochs: int,
    lr: float = 1e-3,
    batch: int = 16,
    seed: int = 0,
) -> float:
    """Regress ``net`` on the expert's labels of ``episodes`` (MSE over their steps, whole
    episodes back-propagated, Adam, gradient norm clipped at 1) after setting its normaliser to
    their observations; returns the last epoch's mean loss per step."""
    eps = [e for e in episodes if len(e.obs)]
    if not eps:
        raise ValueError("fit: no labelled steps")
    idx = list(inputs)
    net.set_normaliser(np.concatenate([e.obs[:, idx] for e in eps]))
    opt = th.optim.Adam(net.parameters(), lr=lr)
    gen = th.Generator().manual_seed(seed)
    loss_mean = float("nan")
    for _ in range(epochs):
        order = th.randperm(len(eps), generator=gen).tolist()
        total = steps = 0.0
        for start in range(0, len(order), batch):
            chunk = [eps[i] for i in order[start : start + batch]]
            t_max = max(len(e.obs) for e in chunk)
            x = np.zeros((len(chunk), t_max, len(idx)), np.float32)
            y = np.zeros((len(chunk), t_max, chunk[0].labels.shape[1]), np.float32)
            m = np.zeros((len(chunk), t_max), np.float32)
            for k, e in enumerate(chunk):
                x[k, : len(e.obs)] = e.obs[:, idx]
                y[k, : len(e.obs)] = e.labels
                m[k, : len(e.obs)] = 1.0
            pred, _ = net(th.as_tensor(x))
            mask = th.as_tensor(m)
            err = ((pred - th.as_tensor(y)) ** 2).mean(dim=-1)
            loss = (err * mask).sum() / mask.sum()
            opt.zero_grad()
            loss.backward()
            th.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
            total += loss.item() * float(mask.sum())
            steps += float(mask.sum())
        loss_mean = total / steps
    return loss_mean


@dataclass
class RunConfig:
    """A recurrent DAgger run (:func:`train`)."""

    env_id: str
    out: Path
    env_kw: dict[str, Any] = dataclasses.field(default_factory=dict)
    drop_inputs: tuple[str, ...] = ()
    rounds: int = 10
    episodes: int = 32
    val_seeds: tuple[int, ...] = ()
    seed_base: int = DAGGER_SEED_BASE
    noise: float = 0.05
    epochs: int = 20
    first_epochs: int = 60
    lr: float = 1e-3
    embed: int = 128
    hidden: int = 128
    head: int = 64
    workers: int = 2
    #: 0: single envs in ``workers`` processes; N: one vector env of N envs over ``workers``
    vector_envs: int = 0
    commit_below: float = 0.1
    polish_epochs: int = 0
    polish_lr: float = 3e-4
    max_wall_min: float | None = None
    seed: int = 0
    #: torch threads of the fit (the flyers wait meanwhile; the fitted weights do not depend on it)
    fit_threads: int = 1


def train(cfg: RunConfig, log: Callable[[str], None] = print) -> GruPolicy:
    """Recurrent DAgger (module docstring); writes ``round_R.npz`` per round, ``best.npz`` (the best
    round on ``val_seeds``, or the last without them), ``final.npz``, ``dagger.csv`` and
    ``checkpoint.pt`` (every episode and the network: a stopped run continues with :func:`train`
    on the same ``out``). With ``polish_epochs`` the last round is followed by a longer fit on all
    the episodes at ``polish_lr`` (``polished.npz``, validated and ranked like a round). Returns the
    best policy."""
    check_int("fit_threads", cfg.fit_threads, low=1, high=1024)
    th.manual_seed(cfg.seed)
    cfg.out.mkdir(parents=True, exist_ok=True)
    probe = make_env(cfg.env_id, "projected", **cfg.env_kw)
    try:
        inputs = input_indices(probe.get_wrapper_attr("obs_slices"), cfg.drop_inputs)
        obs_size = int(probe.observation_space.shape[0])  # type: ignore[index]
    finally:
        probe.close()
    net = GruNet(len(inputs), cfg.embed, cfg.hidden, cfg.head)
    meta = {
        "env_id": cfg.env_id,
        "env_options": cfg.env_kw,
        "drop_inputs": list(cfg.drop_inputs),
        "trainer": "ihrcf_env.rl.recurrent (DAgger on episodes)",
    }
    ckpt_path = cfg.out / "checkpoint.pt"
    data: list[Episode] = []
    history: list[dict[str, Any]] = []
    start_round, best_val, wall0, polished = 0, -1, 0.0, False
    if ckpt_path.exists():
        state = th.load(ckpt_path, weights_only=False)
        net.load_state_dict(state["net"])
        data, history = state["data"], state["history"]
        start_round, best_val, wall0 = state["round"] + 1, state["best_val"], state["wall"]
        polished = state.get("polished", False) and start_round > cfg.rounds
        log(f"resuming after round {state['round']} ({len(data)} episodes)")
    log_csv = CsvLog(cfg.out / "dagger.csv", RECURRENT_FIELDS)
    for row in history:
        log_csv.write(row)
    t0 = time.time() - wall0
    deadline = None if cfg.max_wall_min is None else t0 + 60.0 * cfg.max_wall_min
    pool: Pool | VectorFlyer = (
        VectorFlyer(cfg.env_id, cfg.env_kw, cfg.vector_envs, cfg.workers, cfg.commit_below)
        if cfg.vector_envs
        else Pool(cfg.env_id, cfg.env_kw, cfg.workers, cfg.commit_below)
    )
    policy = net.export(inputs, obs_size, meta)

    def seeds_of(r: int) -> range:
        return range(cfg.seed_base + 1000 * r, cfg.seed_base + 1000 * r + cfg.episodes)

    def validate(policy: GruPolicy, next_round: int | None) -> tuple[list[Episode], list[Episode] | None]:
        """``policy`` on the validation seeds, and (unless ``next_round`` is None) the episodes of
        ``next_round``, which ``policy`` flies with noise: one queue."""
        flights = [Flight.of(cfg.val_seeds, policy, 0.0, label=False)]
        if next_round is not None:
            flights.append(Flight.of(seeds_of(next_round), policy, cfg.noise))
        val, *following = pool.fly_all(flights)
        return val, following[0] if following else None

    def record(
        r: int,
        stage: str,
        flown: list[Episode],
        loss: float,
        policy: GruPolicy,
        done: bool,
        val: list[Episode],
    ) -> dict[str, Any]:
        """Keep ``policy`` as ``best.npz`` if its validation ``val`` is the best, log the row, save
        the checkpoint."""
        nonlocal best_val
        val_ok = sum(e.success for e in val)
        if not cfg.val_seeds or val_ok >= best_val:
            best_val = val_ok
            policy.save(cfg.out / "best.npz")
        row: dict[str, Any] = {
            "timesteps": sum(len(e.obs) for e in data),
            "round": r,
            "stage": stage,
            "episodes": len(flown),
            "successes": sum(e.success for e in flown),
            "samples": sum(len(e.obs) for e in data),
            "loss": loss,
            "val_episodes": len(val),
            "val_successes": val_ok,
            "wall_s": round(time.time() - t0, 1),
        }
        history.append(row)
        log_csv.write(row)
        state = {"net": net.state_dict(), "data": data, "history": history, "round": r}
        th.save({**state, "best_val": best_val, "wall": time.time() - t0, "polished": done}, ckpt_path)
        return row

    try:
        flown: list[Episode] | None = None  # this round's episodes when flown with the last validation
        for r in range(start_round, cfg.rounds + 1):
            if flown is None:
                flown = pool.fly(seeds_of(r), None if r == 0 else policy, cfg.noise)
            data += flown
            fit_start = time.time()
            with torch_threads(cfg.fit_threads):
                epochs = cfg.first_epochs if r == 0 else cfg.epochs
                loss = fit(net, data, inputs, epochs, cfg.lr, seed=cfg.seed + r)
            fit_s = time.time() - fit_start
            policy = net.export(inputs, obs_size, {**meta, "round": r})
            policy.save(cfg.out / f"round_{r}.npz")
            out_of_time = deadline is not None and time.time() > deadline
            last = r == cfg.rounds or out_of_time
            val, following = validate(policy, None if last else r + 1)
            row = record(r, "expert" if r == 0 else "learner", flown, loss, policy, False, val)
            log(
                f"round {r}: {row['stage']} landed {row['successes']}/{len(flown)}, "
                f"{row['samples']} samples, loss {loss:.2e}, validation {row['val_successes']}/"
                f"{row['val_episodes']}, wall {row['wall_s']:.0f} s (the fit {fit_s:.0f} s)"
            )
            if out_of_time:
                log(f"wall budget of {cfg.max_wall_min} min reached after round {r}")
                break
            flown = following
        if cfg.polish_epochs and not polished and data:
            with torch_threads(cfg.fit_threads):
                loss = fit(net, data, inputs, cfg.polish_epochs, cfg.polish_lr, seed=cfg.seed + 100_000)
            policy = net.export(inputs, obs_size, {**meta, "round": history[-1]["round"], "stage": "polish"})
            policy.save(cfg.out / "polished.npz")
            val = validate(policy, None)[0]
            row = record(int(history[-1]["round"]), "polish", [], loss, policy, True, val)
            log(
                f"polish: {cfg.polish_epochs} epochs at lr {cfg.polish_lr:g}, loss {loss:.2e}, validation "
                f"{row['val_successes']}/{row['val_episodes']}, wall {row['wall_s']:.0f} s"
            )
    finally:
        pool.close()
    policy.save(cfg.out / "final.npz")
    return GruPolicy.load(cfg.out / "best.npz")


__all__ = [
    "RECURRENT_FIELDS",
    "GruNet",
    "RunConfig",
    "fit",
    "torch_threads",
    "train",
]
