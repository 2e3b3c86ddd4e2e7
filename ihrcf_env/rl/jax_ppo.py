"""PPO on the JAX backend, exported as a numpy policy: ``python -m ihrcf_env.rl.jax_ppo``.

The envs of a functional env (:class:`~ihrcf_env.vector.jax_env.FunctionalEnv`; the landing task's
:class:`~ihrcf_env.vector.jax_landing.LandingFunctional`) step as one batch
(:func:`~ihrcf_env.vector.jax_rollout.batch_step`: the step limit, same-step autoreset of the envs
that ended, the batch spread over the host's devices). One compiled function, :func:`transition`,
takes the policy's action and steps the batch; it serves the first reset (every env forced to
reset), the training rollouts (sampled actions) and the evaluations (the mean action), so the
env's step compiles once per run. PPO's update (:mod:`ihrcf_env.rl.ppo_learner`) is a second,
small compiled function.

The critic reads the env's ground truth beside the observation (an asymmetric actor-critic) when
the functional env provides it (``privileged``); the actor reads the observation only, and the
exported policy is the actor (:func:`export_policy`, an
:class:`~ihrcf_env.control.mlp_policy.MlpPolicy`: numpy inference, no JAX). :func:`train` runs
in chunks: after each, a checkpoint, an evaluation (the mean action over one episode of every env)
and a row of the learning curve; a stopped run resumes from its folder; ``time_budget_s`` stops
it in time to evaluate and export. Needs the ``[rl]`` extra (rejax, flax, optax).
"""

from __future__ import annotations

import time

_START = time.monotonic()  # the command's start, for --time-budget (before the heavy imports)

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import numpy as np  # noqa: E402

from ihrcf_env.control.mlp_policy import MlpPolicy, mlp_from_arrays  # noqa: E402

__all__ = [
    "CURVE_FIELDS",
    "PPOSettings",
    "Run",
    "curve_csv",
    "export_policy",
    "load_checkpoint",
    "load_policy",
    "main",
    "make_learner",
    "mean_action_fn",
    "train",
]


@dataclass(frozen=True)
class PPOSettings:
    """The recipe: PPO's hyperparameters, the batch and the critic's inputs.

    ``asymmetric``: the critic reads the env's privileged ground truth beside the observation
    (where the functional env provides it); ``devices``: devices the batch is spread over (None:
    all JAX has, as many as split ``num_envs`` evenly); ``curriculum_steps``, ``curriculum_share``:
    the start curriculum (:func:`start_scales`); ``init_log_std``: the Gaussian's log standard
    deviation (in action units) a new run starts from; ``reward_scale``, ``clip_value``: the
    critic's target scale and loss (:class:`~ihrcf_env.rl.ppo_learner.Learner`);
    ``init_output_scale``, ``init_action_mean``: a new actor's output layer is scaled by the first
    and its bias set to the second (None: zero), so that its first actions are near that mean for
    every observation."""

    num_envs: int = 256
    num_steps: int = 64
    num_epochs: int = 4
    num_minibatches: int = 16
    learning_rate: float = 3e-4
    max_grad_norm: float = 0.5
    gamma: float = 0.995
    gae_lambda: float = 0.95
    clip_eps: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    hidden: tuple[int, ...] = (128, 128)
    activation: str = "swish"
    asymmetric: bool = True
    devices: int | None = None
    curriculum_steps: int = 1_000_000
    curriculum_share: float = 0.25
    init_log_std: float = -1.0
    reward_scale: float = 0.05
    clip_value: bool = False
    init_output_scale: float = 0.01
    init_action_mean: tuple[float, ...] | None = None


def start_scales(settings: PPOSettings, steps: int, rng: np.random.Generator) -> np.ndarray:
    """The start curriculum's scale of each env's next episode (1: the task's own start; below 1:
    nearer the deck, :meth:`~ihrcf_env.vector.jax_landing.LandingFunctional.reset_stage`): a share
    of the envs starts as the task does, from ``curriculum_share`` at the first step to all of them
    after ``curriculum_steps`` env steps; the others start at a scale uniform in [0, 1]."""
    n = settings.num_envs
    if settings.curriculum_steps <= 0 or steps >= settings.curriculum_steps:
        return np.ones(n, np.float32)
    share = settings.curriculum_share + (1.0 - settings.curriculum_share) * steps / settings.curriculum_steps
    full = rng.random(n) < share
    return np.where(full, 1.0, rng.random(n)).astype(np.float32)


class Run(NamedTuple):
    """The batch between steps (a row per env): the env state, the raw observation rows, whether the
    last step ended an episode, the running return, and the episodes ended and successful since
    the counters were last zeroed."""

    state: Any
    obs: Any
    done: Any
    returns: Any
    ended: Any
    succeeded: Any


def make_learner(fenv: Any, settings: PPOSettings) -> Any:
    """The :class:`~ihrcf_env.rl.ppo_learner.Learner` of ``fenv`` (its spaces) and ``settings``."""
    from ihrcf_env.rl.ppo_learner import Learner

    n_obs = int(np.prod(fenv.observation_space.shape))
    extra = _privileged_size(fenv) if settings.asymmetric else 0
    return Learner(
        actor_inputs=n_obs, inputs=n_obs + extra, action_dim=int(np.prod(fenv.action_space.shape)),
        hidden=tuple(settings.hidden), activation=settings.activation, learning_rate=settings.learning_rate,
        max_grad_norm=settings.max_grad_norm, gamma=settings.gamma, gae_lambda=settings.gae_lambda,
        clip_eps=settings.clip_eps, ent_coef=settings.ent_coef, vf_coef=settings.vf_coef,
        num_epochs=settings.num_epochs, num_minibatches=settings.num_minibatches,
        low=float(np.min(fenv.action_space.low)), high=float(np.max(fenv.action_space.high)),
        reward_scale=settings.reward_scale, clip_value=settings.clip_value,
    )  # fmt: skip


def _privileged_size(fenv: Any) -> int:
    import jax

    from ihrcf_env.vector.jax_rollout import has_stages

    if not (has_stages(fenv) and callable(getattr(fenv, "privileged", None))):
        return 0
    reading = jax.eval_shape(lambda k: fenv.reset_stage(k, fenv.params)[0], jax.random.PRNGKey(0))
    return int(jax.eval_shape(fenv.privileged, reading).shape[0])


class _Compiled(NamedTuple):
    transition: Callable[..., Any]
    update: Callable[..., Any]
    zero_counts: Callable[..., Any]
    start: Callable[..., Any]
    tally: Callable[..., Any]
    rows: Any
    whole: Any
    ids: Any


def _compile(fenv: Any, learner: Any, settings: PPOSettings, max_steps: int) -> tuple[_Compiled, Any]:
    """The run's compiled functions and its device mesh.

    The transition is a ``shard_map`` over the mesh with no communication between devices: each
    device steps its share of the envs with its own copy of the networks, and every env draws its
    action noise and its step from its own key (``fold_in`` of the call's key and the env's index),
    so its result does not depend on how the batch is split. What needs the whole batch (the
    update, the observation statistics, the counters) runs on replicated arrays copied to every
    device: no collective operation runs between the CPU devices."""
    import jax
    import jax.numpy as jnp
    from jax.sharding import NamedSharding, PartitionSpec

    from ihrcf_env.rl.ppo_learner import Trajectory, normalise, update_stats
    from ihrcf_env.vector.jax_devices import ENV_AXIS, check_devices, env_mesh
    from ihrcf_env.vector.jax_rollout import batch_step, has_stages, placeholder_state

    n = settings.num_envs
    devices = check_devices(settings.devices, n)
    mesh = env_mesh(devices)
    privileged = getattr(fenv, "privileged", None) if learner.inputs > learner.actor_inputs else None
    curriculum = has_stages(fenv)
    step = batch_step(fenv, max_steps, privileged=privileged, curriculum=curriculum)

    def local(params: Any, run: Run, key: Any, force: Any, deterministic: Any, ids: Any, scale: Any) -> Any:
        """One step of this device's envs (every argument but ``params``, ``key`` and
        ``deterministic`` holds this device's rows)."""
        actor, critic, stats = params
        keys = jax.vmap(lambda i: jax.random.split(jax.random.fold_in(key, i)))(ids)
        x = normalise(stats, run.obs)
        action, taken, log_prob, value = learner.act(actor, critic, x, keys[:, 0], deterministic)
        if curriculum:
            obs, state, reward, done, success = step(keys[:, 1], run.state, action, force, scale)
        else:
            obs, state, reward, done, success = step(keys[:, 1], run.state, action, force)
        live = ~force
        reward = jnp.where(live, reward, 0.0).astype(jnp.float32)
        done = done & live
        returns = run.returns + reward
        traj = Trajectory(run.obs, taken, log_prob, reward, value, done)
        new = Run(
            state, obs.astype(jnp.float32), done, jnp.where(done, 0.0, returns),
            run.ended + done.astype(jnp.int32), run.succeeded + (done & success).astype(jnp.int32),
        )  # fmt: skip
        return new, traj, done & success

    row, one = PartitionSpec(ENV_AXIS), PartitionSpec()
    if devices > 1:
        sharded = jax.shard_map(
            local,
            mesh=mesh,
            in_specs=(one, row, one, row, one, row, row),
            out_specs=(row, row, row),
            check_vma=False,
        )
    else:
        sharded = local

    def transition(ts: Any, run: Run, key: Any, force: Any, deterministic: Any, ids: Any, scale: Any) -> Any:
        params = (ts.actor_ts.params, ts.critic_ts.params, ts.obs_rms_state)
        return sharded(params, run, key, force, deterministic, ids, scale)

    def update(ts: Any, trajs: list[Any], last_obs: Any, last_done: Any) -> Any:
        """PPO's update on the rollout (raw observations, normalised with the statistics the
        actions were taken with), then the statistics updated with the rollout's observations."""
        traj = jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *trajs)
        stats = ts.obs_rms_state
        ts = learner.update(
            ts, traj.replace(obs=normalise(stats, traj.obs)), normalise(stats, last_obs), last_done
        )
        stats = update_stats(stats, traj.obs.reshape((-1, traj.obs.shape[-1])))
        return ts.replace(obs_rms_state=stats, global_step=ts.global_step + traj.done.size)

    def zero_counts(run: Run) -> Run:
        z = jnp.zeros(n, jnp.int32)
        return run._replace(ended=z, succeeded=z)

    def start() -> Run:
        state = placeholder_state(fenv, n)
        obs = jnp.zeros((n, learner.inputs), jnp.float32)
        z = jnp.zeros(n, jnp.int32)
        return Run(state, obs, jnp.zeros(n, bool), jnp.zeros(n, jnp.float32), z, z)

    def tally(acc: Any, traj: Any, succeeded: Any) -> Any:
        """An evaluation's per-env sums over the first episode: (ended, success, return, length)."""
        first, success, ret, length = acc
        live = ~first
        return (
            first | traj.done,
            success | (live & succeeded),
            ret + jnp.where(live, traj.reward, 0.0),
            length + live,
        )

    # every array keeps one placement across calls (the batch split over the mesh, the rest
    # replicated), so nothing is compiled again for another placement
    rows, whole = NamedSharding(mesh, row), NamedSharding(mesh, one)
    run_shape = jax.eval_shape(start)
    run_sh = Run(jax.tree_util.tree_map(lambda _: rows, run_shape.state), rows, rows, rows, rows, rows)
    traj_sh = Trajectory(rows, rows, rows, rows, rows, rows)
    acc_sh = (rows, rows, rows, rows)
    compiled = _Compiled(
        jax.jit(
            transition, donate_argnums=(1,), in_shardings=(whole, run_sh, whole, rows, whole, rows, rows),
            out_shardings=(run_sh, traj_sh, rows),
        ),
        jax.jit(update, in_shardings=(whole, whole, whole, whole), out_shardings=whole),
        jax.jit(zero_counts, in_shardings=(run_sh,), out_shardings=run_sh),
        jax.jit(start, out_shardings=run_sh),
        jax.jit(tally, in_shardings=(acc_sh, traj_sh, rows), out_shardings=acc_sh),
        rows,
        whole,
        jax.device_put(jnp.arange(n, dtype=jnp.uint32), rows),
    )  # fmt: skip
    return compiled, mesh


def _reset(c: _Compiled, ts: Any, n: int, key: Any, scale: Any) -> Run:
    """A fresh batch: every env reset (through the transition, so nothing compiles again)."""
    import jax
    import jax.numpy as jnp

    run = c.start()
    force = jax.device_put(jnp.ones(n, bool), c.rows)
    run, _, _ = c.transition(ts, run, key, force, jax.device_put(jnp.asarray(False), c.whole), c.ids, scale)
    return c.zero_counts(run)


def _evaluate(c: _Compiled, ts: Any, n: int, max_steps: int, key: Any) -> tuple[float, float, float]:
    """(success rate, mean return, mean length) of the first episode of each of ``n`` envs flown
    with the actor's mean action, from ``key``."""
    import jax
    import jax.numpy as jnp

    key, k0 = jax.random.split(key)
    ones = jax.device_put(jnp.ones(n, jnp.float32), c.rows)
    run = _reset(c, ts, n, jax.device_put(k0, c.whole), ones)
    acc = jax.device_put((jnp.zeros(n, bool), jnp.zeros(n, bool), jnp.zeros(n), jnp.zeros(n)), c.rows)
    force = jax.device_put(jnp.zeros(n, bool), c.rows)
    det = jax.device_put(jnp.asarray(True), c.whole)
    for step in range(max_steps):
        run, traj, succeeded = c.transition(
            ts, run, jax.device_put(jax.random.fold_in(key, step), c.whole), force, det, c.ids, ones
        )
        acc = c.tally(acc, traj, succeeded)
        if step % 25 == 24 and np.asarray(acc[0]).all():  # read back now and then: the steps stay queued
            break
    _, success, ret, length = (np.asarray(a) for a in acc)
    return float(success.mean()), float(ret.mean()), float(length.mean())


def train(
    fenv: Any,
    out: str | Path,
    total_timesteps: int,
    max_steps: int,
    settings: PPOSettings | None = None,
    chunk_timesteps: int = 1_000_000,
    seed: int = 0,
    time_budget_s: float | None = None,
    log: Callable[[str], None] = print,
    init_policy: str | Path | None = None,
    init_log_std: float = -1.0,
    started: float | None = None,
) -> tuple[Any, Any, list[dict[str, float]]]:
    """Train PPO on ``fenv`` for ``total_timesteps`` env steps (module docstring), checkpointing
    every ``chunk_timesteps`` into ``out`` (``checkpoint.msgpack``, ``best.msgpack``: the chunk with
    the best evaluated success, ``curve.json``) and resuming a run left there. ``time_budget_s``:
    wall seconds from ``started`` (a ``time.monotonic()`` reading; default this call) by which the
    run has stopped, evaluated its last state and left the time to export it. A new run may start
    from the actor of ``init_policy`` (an exported ``.npz``) with ``init_log_std``. Returns (learner,
    train state, curve: one row per chunk with steps, wall s, the evaluation's success, return and
    length, and the training episodes' success). Runs in 32-bit JAX."""
    import jax

    with jax.enable_x64(False):
        return _train(
            fenv, out, total_timesteps, max_steps, settings or PPOSettings(), chunk_timesteps, seed,
            time_budget_s, log, init_policy, init_log_std, time.monotonic() if started is None else started,
        )  # fmt: skip


def _check_train_args(
    total_timesteps: Any, chunk_timesteps: Any, time_budget_s: Any, settings: PPOSettings
) -> None:
    for name, value in (("total_timesteps", total_timesteps), ("chunk_timesteps", chunk_timesteps)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    if time_budget_s is not None and not (
        isinstance(time_budget_s, int | float)
        and not isinstance(time_budget_s, bool)
        and 0 < time_budget_s < 1e7
    ):
        raise ValueError(f"time_budget_s must be a positive number of seconds, got {time_budget_s!r}")
    for name in ("num_envs", "num_steps", "num_epochs", "num_minibatches"):
        value = getattr(settings, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} must be a positive int, got {value!r}")
    if not (isinstance(settings.init_log_std, int | float) and -5.0 <= settings.init_log_std <= 1.0):
        raise ValueError(f"init_log_std must be a number in [-5, 1], got {settings.init_log_std!r}")
    if not (isinstance(settings.init_output_scale, int | float) and 0 < settings.init_output_scale <= 1):
        raise ValueError(f"init_output_scale must be in (0, 1], got {settings.init_output_scale!r}")
    mean = settings.init_action_mean
    if mean is not None and not (len(mean) > 0 and all(abs(float(m)) <= 1 for m in mean)):
        raise ValueError(f"init_action_mean must hold numbers in [-1, 1], got {mean!r}")
    if not (isinstance(settings.reward_scale, int | float) and 0 < settings.reward_scale < 1e6):
        raise ValueError(f"reward_scale must be a positive number, got {settings.reward_scale!r}")
    if not (0.0 <= settings.curriculum_share <= 1.0) or settings.curriculum_steps < 0:
        raise ValueError(
            "curriculum_share must be in [0, 1] and curriculum_steps >= 0, got "
            f"{settings.curriculum_share!r}, {settings.curriculum_steps!r}"
        )
    if (settings.num_envs * settings.num_steps) % settings.num_minibatches:
        raise ValueError(
            f"num_minibatches={settings.num_minibatches} must divide num_envs x num_steps "
            f"({settings.num_envs * settings.num_steps})"
        )


def _train(
    fenv: Any, out: str | Path, total_timesteps: int, max_steps: int, settings: PPOSettings,
    chunk_timesteps: int, seed: int, time_budget_s: float | None, log: Callable[[str], None],
    init_policy: str | Path | None, init_log_std: float, started: float,
) -> tuple[Any, Any, list[dict[str, float]]]:  # fmt: skip
    import jax
    import jax.numpy as jnp
    from flax import serialization

    _check_train_args(total_timesteps, chunk_timesteps, time_budget_s, settings)
    if not (isinstance(init_log_std, int | float) and -5.0 <= init_log_std <= 1.0):
        raise ValueError(f"init_log_std must be a number in [-5, 1], got {init_log_std!r}")
    learner = make_learner(fenv, settings)
    mean = settings.init_action_mean
    if mean is not None and len(mean) != learner.action_dim:
        raise ValueError(
            f"init_action_mean needs {learner.action_dim} numbers (one per action), got {mean!r}"
        )
    compiled, mesh = _compile(fenv, learner, settings, max_steps)
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    n = settings.num_envs
    per_iteration = n * settings.num_steps
    chunk = max(1, -(-chunk_timesteps // per_iteration)) * per_iteration  # whole PPO iterations
    ts = learner.init(jax.random.PRNGKey(seed))
    ckpt, curve_file, best_file = (
        folder / "checkpoint.msgpack",
        folder / "curve.json",
        folder / "best.msgpack",
    )
    curve: list[dict[str, float]] = []
    if ckpt.exists() and curve_file.exists():
        ts = serialization.from_bytes(ts, ckpt.read_bytes())
        curve = json.loads(curve_file.read_text())
        log(f"resumed at {curve[-1]['steps'] if curve else 0:.0f} steps from {ckpt}")
    elif init_policy is not None:
        ts = load_policy(ts, MlpPolicy.load(init_policy), init_log_std)
        log(f"actor initialised from {init_policy}")
    else:
        ts = _with_log_std(ts, settings.init_log_std)
        ts = _with_output_layer(ts, settings.init_output_scale, settings.init_action_mean)
    log(
        f"{mesh.devices.size} device(s), {n} envs, "
        f"{learner.inputs - learner.actor_inputs} privileged critic inputs"
    )
    # the checkpoint's own count: a run stopped mid-chunk saved steps the curve has no row for
    done_steps = int(ts.global_step)
    wall0 = curve[-1]["wall_s"] if curve else 0.0
    # the curve's wall time: from the command's start for a new run (setup and compilation
    # included), from this call on top of the folder's last row for a resumed one
    t_call = time.monotonic() if curve else started
    key = jax.random.fold_in(jax.random.PRNGKey(seed), 1_000_003 + done_steps // per_iteration)
    rng = np.random.default_rng([seed, done_steps])

    def scales() -> Any:
        return jax.device_put(jnp.asarray(start_scales(settings, done_steps, rng)), compiled.rows)

    t_compile = time.monotonic()
    run = _reset(compiled, ts, n, jax.device_put(key, compiled.whole), scales())
    jax.block_until_ready(run.obs)
    log(f"the batched step compiled and the envs reset in {time.monotonic() - t_compile:.0f} s")
    force = jax.device_put(jnp.zeros(n, bool), compiled.rows)
    sample = jax.device_put(jnp.asarray(False), compiled.whole)
    iteration = done_steps // per_iteration
    eval_s = 0.0
    iteration_s = 0.0
    evaluated = True
    stop = False

    def left() -> float:
        return math_inf if time_budget_s is None else time_budget_s - (time.monotonic() - started)

    math_inf = float("inf")
    try:
        while done_steps < total_timesteps and not stop:
            chunk_end = min(done_steps + chunk, total_timesteps)
            while done_steps < chunk_end:
                # leave the time of one more iteration, an evaluation and the export (a margin of 10 s)
                if left() < iteration_s + eval_s + 10.0 and done_steps > 0:
                    stop = True
                    break
                t0 = time.monotonic()
                trajs = []
                scale = scales()
                for t in range(settings.num_steps):
                    k = jax.random.fold_in(key, iteration * settings.num_steps + t)
                    run, traj, _ = compiled.transition(
                        ts, run, jax.device_put(k, compiled.whole), force, sample, compiled.ids, scale
                    )
                    trajs.append(traj)
                iteration += 1
                # the rollout copied to every device (a transfer, no collective operation)
                trajs, last_obs, last_done = jax.device_put((trajs, run.obs, run.done), compiled.whole)
                ts = compiled.update(ts, trajs, last_obs, last_done)
                jax.block_until_ready(ts.global_step)
                iteration_s = time.monotonic() - t0
                done_steps += per_iteration
                evaluated = False
            if done_steps == (int(curve[-1]["steps"]) if curve else 0):
                break
            t0 = time.monotonic()
            ev = _evaluate(compiled, ts, n, max_steps, jax.random.PRNGKey(10_000 + len(curve)))
            eval_s = time.monotonic() - t0
            evaluated = True
            ended = int(np.asarray(run.ended).sum())
            train_success = float(np.asarray(run.succeeded).sum()) / ended if ended else 0.0
            run = compiled.zero_counts(run)
            wall = wall0 + time.monotonic() - t_call
            row = {
                "steps": float(done_steps),
                "wall_s": wall,
                "success": ev[0],
                "return": ev[1],
                "length": ev[2],
            }
            row["train_success"] = train_success
            curve.append(row)
            _save(
                ts,
                curve,
                folder,
                best_file if ev[0] > max((r["success"] for r in curve[:-1]), default=-1.0) else None,
            )
            log(
                f"{row['steps']:.3g} steps  {wall:7.1f} s  success {ev[0]:5.1%} (training episodes "
                f"{train_success:5.1%})  return {ev[1]:8.2f}  length {ev[2]:5.1f}"
            )
    except KeyboardInterrupt:
        if not evaluated:
            # a valid last checkpoint: the last complete iteration's state, not evaluated
            _write_whole(ckpt, serialization.to_bytes(ts))
        log(f"stopped at {done_steps} steps; the run resumes from {folder}")
        raise
    if stop:
        log(f"time budget: stopped after {time.monotonic() - started:.0f} s")
    return learner, ts, curve


def _save(ts: Any, curve: list[dict[str, float]], folder: Path, best: Path | None) -> None:
    """The checkpoint, the curve and (``best`` given) the best state, each written whole (a
    temporary file renamed), so a run stopped while writing leaves the previous ones."""
    from flax import serialization

    data = serialization.to_bytes(ts)
    for path, payload in (
        (folder / "checkpoint.msgpack", data),
        (folder / "curve.json", json.dumps(curve, indent=1).encode()),
        (folder / "curve.csv", curve_csv(curve).encode()),
        *(((best, data),) if best is not None else ()),
    ):
        _write_whole(path, payload)


#: The columns of ``curve.csv`` (env steps, wall s from the command's start, evaluated success
#: rate, mean return and length of the evaluation's episodes, the training episodes' success rate).
CURVE_FIELDS = ("steps", "wall_s", "success", "return", "length", "train_success")


def curve_csv(curve: list[dict[str, float]]) -> str:
    """The learning curve as CSV text (:data:`CURVE_FIELDS`, one row per evaluated chunk)."""
    lines = [",".join(CURVE_FIELDS)]
    for row in curve:
        lines.append(
            f"{row['steps']:.0f},{row['wall_s']:.1f},{row['success']:.4f},{row['return']:.3f},"
            f"{row['length']:.1f},{row.get('train_success', float('nan')):.4f}"
        )
    return "\n".join(lines) + "\n"


def _write_whole(path: Path, payload: bytes) -> None:
    """``payload`` written to ``path`` through a temporary file renamed over it."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(payload)
    os.replace(tmp, path)


def _with_log_std(ts: Any, log_std: float) -> Any:
    """``ts`` with the actor's Gaussian log standard deviation set to ``log_std`` for every action."""
    import jax.numpy as jnp

    p = dict(ts.actor_ts.params["params"])
    p["action_log_std"] = jnp.full_like(p["action_log_std"], log_std)
    return ts.replace(actor_ts=ts.actor_ts.replace(params={**ts.actor_ts.params, "params": p}))


def _with_output_layer(ts: Any, scale: float, mean: tuple[float, ...] | None) -> Any:
    """``ts`` with the actor's output layer (the Gaussian's mean) scaled by ``scale`` and its bias
    set to ``mean`` (action units; unchanged when None): a new policy's actions start near ``mean``
    for every observation."""
    import jax.numpy as jnp

    p = dict(ts.actor_ts.params["params"])
    layer = dict(p["action_mean"])
    layer["kernel"] = layer["kernel"] * scale
    if mean is not None:
        layer["bias"] = jnp.asarray(mean, layer["bias"].dtype).reshape(layer["bias"].shape)
    p["action_mean"] = layer
    return ts.replace(actor_ts=ts.actor_ts.replace(params={**ts.actor_ts.params, "params": p}))


def load_checkpoint(ts: Any, path: str | Path) -> Any:
    """``ts`` (a train state of the same learner) with the values saved at ``path``
    (``checkpoint.msgpack`` or ``best.msgpack`` of a run folder)."""
    from flax import serialization

    return serialization.from_bytes(ts, Path(path).read_bytes())


def mean_action_fn(learner: Any, ts: Any) -> Callable[[Any], Any]:
    """The actor's deterministic action (the Gaussian's mean, clipped) of one observation (the
    env's, without privileged inputs)."""
    import jax.numpy as jnp

    from ihrcf_env.rl.ppo_learner import normalise

    k = learner.actor_inputs
    stats = ts.obs_rms_state.replace(mean=ts.obs_rms_state.mean[:k], var=ts.obs_rms_state.var[:k])

    def act(obs: Any) -> Any:
        x = normalise(stats, jnp.asarray(obs)[None])
        return jnp.clip(learner.mean_action(ts.actor_ts.params, x)[0], learner.low, learner.high)

    return act


def export_policy(learner: Any, ts: Any, path: str | Path, **meta: Any) -> MlpPolicy:
    """Write the trained actor as an :class:`MlpPolicy` ``.npz`` at ``path``; returns it."""
    p = ts.actor_ts.params["params"]
    hidden = p["features"]
    layers = [(hidden[f"Dense_{k}"]["kernel"], hidden[f"Dense_{k}"]["bias"]) for k in range(len(hidden))]
    layers.append((p["action_mean"]["kernel"], p["action_mean"]["bias"]))
    k = learner.actor_inputs
    rms = ts.obs_rms_state
    activation = {"silu": "swish", "swish": "swish", "tanh": "tanh", "relu": "relu"}[learner.activation]
    policy = mlp_from_arrays(
        [(np.asarray(w), np.asarray(b)) for w, b in layers],
        np.asarray(rms.mean)[:k],
        np.asarray(rms.var)[:k],
        activation=activation,
        **meta,
    )
    policy.save(path)
    return policy


def load_policy(ts: Any, policy: MlpPolicy, log_std: float) -> Any:
    """``ts`` with its actor set to ``policy`` (hidden layers, action head and the actor's share of
    the observation statistics, as :func:`export_policy` wrote them) and the Gaussian's log
    standard deviation to ``log_std`` for every action (the file does not hold it); the critic and
    the optimiser's state are left as they are. The policy's layer sizes must be the actor's."""
    import jax.numpy as jnp

    p = ts.actor_ts.params["params"]
    hidden = p["features"]
    names = [f"Dense_{k}" for k in range(len(hidden))]
    if len(policy.weights) != len(names) + 1:
        raise ValueError(f"policy: {len(policy.weights) - 1} hidden layers, the actor has {len(names)}")
    new_hidden = {}
    for name, w, b in zip(names, policy.weights[:-1], policy.biases[:-1], strict=True):
        kernel = hidden[name]["kernel"]
        if kernel.shape != w.T.shape:
            raise ValueError(f"policy: layer {name} is {w.T.shape}, the actor's is {kernel.shape}")
        new_hidden[name] = {"kernel": jnp.asarray(w.T, kernel.dtype), "bias": jnp.asarray(b, kernel.dtype)}
    head = p["action_mean"]
    if head["kernel"].shape != policy.weights[-1].T.shape:
        raise ValueError(
            f"policy: action head is {policy.weights[-1].T.shape}, the actor's is {head['kernel'].shape}"
        )
    new_p = dict(p)
    new_p["features"] = new_hidden
    new_p["action_mean"] = {
        "kernel": jnp.asarray(policy.weights[-1].T, head["kernel"].dtype),
        "bias": jnp.asarray(policy.biases[-1], head["bias"].dtype),
    }
    actor_ts = ts.actor_ts.replace(params={**ts.actor_ts.params, "params": new_p})
    ts = _with_log_std(ts.replace(actor_ts=actor_ts), log_std)
    rms = ts.obs_rms_state
    k = policy.mean.shape[0]
    if k > rms.mean.shape[0] or kernel_inputs(ts) != k:
        raise ValueError(f"policy: observation size {k}, the actor's is {kernel_inputs(ts)}")
    # the running statistics weigh the loaded ones as many observations
    rms = rms.replace(
        mean=rms.mean.at[:k].set(jnp.asarray(policy.mean, rms.mean.dtype)),
        var=rms.var.at[:k].set(jnp.asarray(policy.var, rms.var.dtype)),
        count=jnp.asarray(1e6, jnp.asarray(rms.count).dtype),
    )
    return ts.replace(obs_rms_state=rms)


def kernel_inputs(ts: Any) -> int:
    """The actor's input size (its first layer's)."""
    return int(ts.actor_ts.params["params"]["features"]["Dense_0"]["kernel"].shape[0])


def _positive_number(name: str, kind: type) -> Callable[[str], Any]:
    def parse(text: str) -> Any:
        try:
            value = kind(float(text)) if kind is int else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a positive number, got {text!r}") from None
        if not (value > 0 and value < 1e13):
            raise argparse.ArgumentTypeError(f"{name} must be a positive number, got {text!r}")
        return value

    return parse


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m ihrcf_env.rl.jax_ppo``: train PPO on the JAX backend's landing env (float32,
    projected camera) and export the policy. Its defaults are the recipe."""
    d = PPOSettings()
    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--env-id", default="ihrcf_env/DeckLanding-v2")
    ap.add_argument("--level", default="moderate")
    ap.add_argument(
        "--timesteps", type=_positive_number("--timesteps", int), default=10**7, help="env steps in all"
    )
    ap.add_argument(
        "--chunk", type=_positive_number("--chunk", int), default=500_000,
        help="env steps between checkpoints and evaluations",
    )  # fmt: skip
    ap.add_argument(
        "--time-budget", type=_positive_number("--time-budget", float), default=None,
        help="s of wall time from the command's start to the exported policy",
    )  # fmt: skip
    ap.add_argument("--out", required=True, help="run folder (checkpoint, curve); resumes a run left there")
    ap.add_argument("--policy", default=None, help="write the trained policy here (.npz)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init-policy", default=None, help="start a new run from this exported policy (.npz)")
    ap.add_argument(
        "--init-log-std", type=float, default=-1.0, help="the Gaussian's log std with --init-policy"
    )
    ap.add_argument("--num-envs", type=_positive_number("--num-envs", int), default=d.num_envs)
    ap.add_argument("--num-steps", type=_positive_number("--num-steps", int), default=d.num_steps)
    ap.add_argument("--learning-rate", type=float, default=d.learning_rate)
    ap.add_argument(
        "--devices", type=_positive_number("--devices", int), default=None,
        help="devices (on a CPU: cores) to spread the envs over (default: the cores this process may use)",
    )  # fmt: skip
    ap.add_argument(
        "--symmetric", action="store_true", help="the critic reads the observation only (no privileged truth)"
    )
    ap.add_argument(
        "--curriculum-steps", type=float, default=d.curriculum_steps,
        help="env steps of the start curriculum (episodes started nearer the deck; 0: none)",
    )  # fmt: skip
    ap.add_argument(
        "--export", choices=("last", "best"), default="best",
        help="write the last chunk's actor, or the one with the best evaluated success rate",
    )  # fmt: skip
    ap.add_argument(
        "--reward-scale", type=_positive_number("--reward-scale", float), default=d.reward_scale,
        help="the critic's targets are the returns of the reward times this",
    )  # fmt: skip
    ap.add_argument(
        "--clip-value", action=argparse.BooleanOptionalAction, default=d.clip_value,
        help="clip the value loss around the rollout's values (PPO's original critic loss)",
    )  # fmt: skip
    ap.add_argument("--gamma", type=float, default=d.gamma, help="the discount (0, 1)")
    ap.add_argument("--num-epochs", type=_positive_number("--num-epochs", int), default=d.num_epochs)
    ap.add_argument(
        "--init-output-scale", type=float, default=d.init_output_scale,
        help="a new actor's output layer scaled by this (small: the first actions near --init-action-mean)",
    )  # fmt: skip
    ap.add_argument(
        "--init-action-mean", type=float, nargs="+", default=d.init_action_mean,
        help="a new actor's output bias (action units, one per action), e.g. 0 0 -0.3 0",
    )  # fmt: skip
    ap.add_argument("--ent-coef", type=float, default=d.ent_coef, help="the entropy bonus (>= 0)")
    args = ap.parse_args(argv)
    if not (0 < args.gamma < 1):
        ap.error(f"--gamma must be in (0, 1), got {args.gamma}")
    if not (0 <= args.ent_coef < 1):
        ap.error(f"--ent-coef must be in [0, 1), got {args.ent_coef}")
    if not (0 < args.learning_rate < 1):
        ap.error(f"--learning-rate must be in (0, 1), got {args.learning_rate}")
    from ihrcf_env.vector.jax_devices import host_cores, request_host_devices

    if args.devices is not None and args.devices > host_cores():
        ap.error(f"--devices {args.devices}: this process may use {host_cores()} core(s)")
    if args.num_envs % (args.devices or 1):
        ap.error(f"--num-envs {args.num_envs} does not split over --devices {args.devices}")
    request_host_devices(args.devices)
    from ihrcf_env.fast.cache import enable_compilation_cache
    from ihrcf_env.vector.checks import time_limit
    from ihrcf_env.vector.jax_make import make_functional

    enable_compilation_cache()
    max_steps = time_limit(args.env_id, None) or 600
    fenv = make_functional(args.env_id, "float32", max_steps=max_steps, level=args.level)
    settings = PPOSettings(
        num_envs=args.num_envs, num_steps=args.num_steps, learning_rate=args.learning_rate,
        asymmetric=not args.symmetric, devices=args.devices, curriculum_steps=int(args.curriculum_steps),
        reward_scale=args.reward_scale, clip_value=args.clip_value, gamma=args.gamma, ent_coef=args.ent_coef,
        num_epochs=args.num_epochs, init_output_scale=args.init_output_scale,
        init_action_mean=None if args.init_action_mean is None else tuple(args.init_action_mean),
    )  # fmt: skip
    try:
        learner, ts, curve = train(
            fenv, args.out, args.timesteps, max_steps, settings, args.chunk, args.seed,
            time_budget_s=args.time_budget, init_policy=args.init_policy, init_log_std=args.init_log_std,
            started=_START,
        )  # fmt: skip
    except KeyboardInterrupt:
        return 130
    if args.policy:
        last = curve[-1] if curve else {"steps": 0.0, "wall_s": 0.0}
        best = Path(args.out) / "best.msgpack"
        if args.export == "best" and curve and best.exists():
            ts = load_checkpoint(ts, best)
            last = max(curve, key=lambda r: r["success"])
        export_policy(
            learner, ts, args.policy, env_id=args.env_id, level=args.level, trainer="PPO (JAX backend)",
            steps=int(last["steps"]), wall_s=float(last["wall_s"]),
            asymmetric=bool(settings.asymmetric), devices=int(settings.devices or 0),
            **({"init_policy": Path(args.init_policy).name} if args.init_policy else {}),
        )  # fmt: skip
        print(f"policy written to {args.policy} ({time.monotonic() - _START:.0f} s after the start)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
