"""PPO on the JAX backend: rejax's PPO over a functional landing env, exported as a numpy policy.

:func:`gymnax_env` adapts a functional env (:class:`~ihrcf_env.vector.jax_env.FunctionalEnv`:
``draw`` / ``reset_from`` / ``step``, one env per call) to gymnax's ``Environment`` interface, which
rejax trains on (its autoreset draws a new episode on every reset; episodes end on termination or
after ``max_steps``). :class:`LandingPPO` steps the envs as one batch and resets only those that ended.
:func:`train` runs it in chunks, each one compiled call, saving a
checkpoint and the learning curve after every chunk (a stopped run resumes from its folder; a new
run may start from an exported policy's actor, :func:`load_policy`), and
:func:`export_policy` writes the actor as an :class:`~ihrcf_env.control.mlp_policy.MlpPolicy`
(numpy inference, no JAX needed to run it). Needs the ``[rl]`` extra (rejax, gymnax).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import serialization
from gymnax.environments import environment, spaces
from rejax import PPO

from ihrcf_env.control.mlp_policy import MlpPolicy, mlp_from_arrays
from ihrcf_env.vector.jax_batch import autoreset_step

__all__ = [
    "LandingPPO",
    "PPOSettings",
    "export_policy",
    "gymnax_env",
    "load_checkpoint",
    "load_policy",
    "main",
    "make_ppo",
    "train",
]


def gymnax_env(fenv: Any, max_steps: int) -> tuple[environment.Environment, Any]:
    """(gymnax env, its params) of the functional env ``fenv`` with episodes of at most
    ``max_steps`` steps (the id's step limit)."""
    obs_space = fenv.observation_space
    act_space = fenv.action_space

    class Landing(environment.Environment):
        @property
        def default_params(self) -> Any:
            return fenv.params

        def step_env(self, key: Any, state: Any, action: Any, params: Any) -> Any:
            inner, t = state
            obs, inner, reward, terminated, info = fenv.step(key, inner, action, params)
            t = t + 1
            done = jnp.logical_or(terminated, t >= max_steps)
            info = {"success": info.get("is_success", jnp.zeros((), bool)), "terminated": terminated}
            return obs, (inner, t), reward, done, info

        def reset_env(self, key: Any, params: Any) -> Any:
            k1, k2 = jax.random.split(key)
            obs, inner = fenv.reset_from(fenv.draw(k1, params), k2, params)
            return obs, (inner, jnp.zeros((), jnp.int32))

        def observation_space(self, params: Any) -> Any:
            return spaces.Box(obs_space.low, obs_space.high, obs_space.shape, jnp.float32)

        def action_space(self, params: Any) -> Any:
            return spaces.Box(act_space.low, act_space.high, act_space.shape, jnp.float32)

        @property
        def name(self) -> str:
            return "ihrcf-landing"

    return Landing(), fenv.params


class LandingPPO(PPO):  # type: ignore[misc,unused-ignore]  # Any without rejax installed
    """rejax's PPO whose N envs step as one batch: the step in chunks
    (:func:`~ihrcf_env.vector.jax_batch.map_envs`) and the reset run only for the envs that ended
    (:func:`~ihrcf_env.vector.jax_batch.autoreset_step`). gymnax's per-env autoreset under
    ``vmap`` would run a reset, about two steps' work, for every env on every step. Same
    transitions otherwise: an env that ended starts a new episode in the same step."""

    @property
    def vmap_step(self) -> Callable[..., Any]:
        env, params_default = self.env, self.env_params

        def step(keys: Any, state: Any, action: Any, params: Any = params_default) -> Any:
            return autoreset_step(
                lambda k, s, a: env.step_env(k, s, a, params),
                lambda k: env.reset_env(k, params),
                keys,
                state,
                action,
            )

        return step


@dataclass(frozen=True)
class PPOSettings:
    """rejax PPO's hyperparameters (the names of :class:`rejax.PPO`)."""

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
    extra: dict[str, Any] = field(default_factory=dict)


def make_ppo(
    fenv: Any,
    max_steps: int,
    settings: PPOSettings,
    chunk_timesteps: int,
    eval_envs: int = 64,
) -> Any:
    """rejax's PPO on ``fenv``, training ``chunk_timesteps`` per call of its ``train``; its
    evaluation (once per chunk) flies ``eval_envs`` episodes with the actor's mean action and
    returns (success rate, mean return, mean length)."""
    env, params = gymnax_env(fenv, max_steps)

    def evaluate(algo: Any, ts: Any, rng: Any) -> Any:
        act = _mean_action(algo, ts)
        keys = jax.random.split(rng, eval_envs)
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)

        def one(carry: Any, k: Any) -> Any:
            obs, state, done, ret, length, success = carry
            a = jax.vmap(act)(obs)
            ks = jax.random.split(k, eval_envs)
            obs2, state2, r, d, info = jax.vmap(env.step_env, in_axes=(0, 0, 0, None))(ks, state, a, params)
            live = ~done
            ret = ret + jnp.where(live, r, 0.0)
            length = length + live
            success = success | (live & info["success"])
            return (obs2, state2, done | d, ret, length, success), None

        zeros = jnp.zeros(eval_envs)
        carry = (obs, state, jnp.zeros(eval_envs, bool), zeros, zeros, jnp.zeros(eval_envs, bool))
        carry, _ = jax.lax.scan(one, carry, jax.random.split(rng, max_steps))
        _, _, _, ret, length, success = carry
        return jnp.stack([success.mean(), ret.mean(), length.mean()])

    algo = LandingPPO.create(
        env=env,
        env_params=params,
        num_envs=settings.num_envs,
        num_steps=settings.num_steps,
        num_epochs=settings.num_epochs,
        num_minibatches=settings.num_minibatches,
        learning_rate=settings.learning_rate,
        max_grad_norm=settings.max_grad_norm,
        gamma=settings.gamma,
        gae_lambda=settings.gae_lambda,
        clip_eps=settings.clip_eps,
        ent_coef=settings.ent_coef,
        vf_coef=settings.vf_coef,
        total_timesteps=chunk_timesteps,
        eval_freq=chunk_timesteps,
        skip_initial_evaluation=True,
        normalize_observations=True,
        agent_kwargs={"hidden_layer_sizes": settings.hidden, "activation": settings.activation},
        **settings.extra,
    )
    return algo.replace(eval_callback=evaluate)


def _mean_action(algo: Any, ts: Any) -> Callable[[Any], Any]:
    """The actor's deterministic action (the Gaussian's mean, clipped) of one observation."""

    def act(obs: Any) -> Any:
        x = algo.normalize_obs(ts.obs_rms_state, obs)
        features = algo.actor.apply(ts.actor_ts.params, x[None], method=lambda m, o: m.features(o))
        mean = algo.actor.apply(ts.actor_ts.params, features, method=lambda m, f: m.action_mean(f))
        return jnp.clip(mean[0], -1.0, 1.0)

    return act


def export_policy(algo: Any, ts: Any, path: str | Path, **meta: Any) -> MlpPolicy:
    """Write the trained actor as an :class:`MlpPolicy` ``.npz`` at ``path``; returns it."""
    p = ts.actor_ts.params["params"]
    hidden = p["features"]
    layers = [(hidden[f"Dense_{k}"]["kernel"], hidden[f"Dense_{k}"]["bias"]) for k in range(len(hidden))]
    layers.append((p["action_mean"]["kernel"], p["action_mean"]["bias"]))
    rms = ts.obs_rms_state
    name = getattr(algo.actor.activation, "__name__", "swish")
    activation = {"silu": "swish", "swish": "swish", "tanh": "tanh", "relu": "relu"}[name]
    policy = mlp_from_arrays(
        [(np.asarray(k), np.asarray(b)) for k, b in layers],
        np.asarray(rms.mean),
        np.asarray(rms.var),
        activation=activation,
        **meta,
    )
    policy.save(path)
    return policy


def load_policy(ts: Any, policy: MlpPolicy, log_std: float) -> Any:
    """``ts`` with its actor set to ``policy`` (hidden layers, action head and observation
    normalisation, as :func:`export_policy` wrote them) and the Gaussian's log standard deviation
    to ``log_std`` for every action (the file does not hold it); the critic and the optimiser's
    state are left as they are. The policy's layer sizes must be the actor's."""
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
    new_p["action_log_std"] = jnp.full_like(p["action_log_std"], log_std)
    actor_ts = ts.actor_ts.replace(params={**ts.actor_ts.params, "params": new_p})
    rms = ts.obs_rms_state
    if rms.mean.shape != policy.mean.shape:
        raise ValueError(f"policy: observation size {policy.mean.shape[0]}, the env's is {rms.mean.shape[0]}")
    # the running statistics weigh the loaded ones as many observations
    rms = rms.replace(
        mean=jnp.asarray(policy.mean, rms.mean.dtype), var=jnp.asarray(policy.var, rms.var.dtype), count=1e6
    )
    return ts.replace(actor_ts=actor_ts, obs_rms_state=rms)


def train(
    fenv: Any,
    out: str | Path,
    total_timesteps: int,
    max_steps: int,
    settings: PPOSettings | None = None,
    chunk_timesteps: int = 1_000_000,
    seed: int = 0,
    eval_envs: int = 64,
    time_budget_s: float | None = None,
    log: Callable[[str], None] = print,
    init_policy: str | Path | None = None,
    init_log_std: float = -1.0,
) -> tuple[Any, Any, list[dict[str, float]]]:
    """Train PPO on ``fenv`` for ``total_timesteps`` env steps in chunks of ``chunk_timesteps``,
        resuming from ``out`` (``checkpoint.msgpack``, ``curve.json``) if a run left them there; stops
        early when the next chunk would pass ``time_budget_s`` (s of wall time in this call). The
        state of the chunk with the highest evaluated success rate so far is kept as ``best.msgpack``
        (:func:`load_checkpoint`). A new run
    (nothing to resume) starts from the actor of ``init_policy`` (an exported ``.npz``) with
    ``init_log_std`` (:func:`load_policy`) if given. Returns
        (algo, train state, curve: one row per chunk with steps, wall time, success rate, mean return
        and length of the mean-action evaluation). Runs in 32-bit JAX (``jax_enable_x64`` off for the
        call: rejax's running statistics are float32)."""
    with jax.enable_x64(False):
        return _train(
            fenv,
            out,
            total_timesteps,
            max_steps,
            settings,
            chunk_timesteps,
            seed,
            eval_envs,
            time_budget_s,
            log,
            init_policy,
            init_log_std,
        )


def _train(
    fenv: Any,
    out: str | Path,
    total_timesteps: int,
    max_steps: int,
    settings: PPOSettings | None,
    chunk_timesteps: int,
    seed: int,
    eval_envs: int,
    time_budget_s: float | None,
    log: Callable[[str], None],
    init_policy: str | Path | None,
    init_log_std: float,
) -> tuple[Any, Any, list[dict[str, float]]]:
    if not (isinstance(init_log_std, int | float) and -5.0 <= init_log_std <= 1.0):
        raise ValueError(f"init_log_std must be a number in [-5, 1], got {init_log_std!r}")
    settings = settings or PPOSettings()
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    per_iteration = settings.num_envs * settings.num_steps
    chunk = max(1, -(-chunk_timesteps // per_iteration)) * per_iteration  # whole PPO iterations
    algo = make_ppo(fenv, max_steps, settings, chunk, eval_envs)
    ts = algo.init_state(jax.random.PRNGKey(seed))
    ckpt, curve_file = folder / "checkpoint.msgpack", folder / "curve.json"
    curve: list[dict[str, float]] = []
    if ckpt.exists() and curve_file.exists():
        ts = serialization.from_bytes(ts, ckpt.read_bytes())
        curve = json.loads(curve_file.read_text())
        log(f"resumed at {curve[-1]['steps'] if curve else 0:.0f} steps from {ckpt}")
    elif init_policy is not None:
        ts = load_policy(ts, MlpPolicy.load(init_policy), init_log_std)
        log(f"actor initialised from {init_policy}")
    train_fn = jax.jit(algo.train)
    start = time.perf_counter()
    last_chunk = 0.0
    while (done := int(curve[-1]["steps"]) if curve else 0) < total_timesteps:
        spent = time.perf_counter() - start
        if time_budget_s is not None and curve and spent + last_chunk > time_budget_s:
            log(f"time budget reached after {spent:.0f} s")
            break
        t0 = time.perf_counter()
        ts, evaluation = train_fn(train_state=ts)
        jax.block_until_ready(ts)
        last_chunk = time.perf_counter() - t0
        success, ret, length = (float(v) for v in np.asarray(evaluation).reshape(-1)[-3:])
        wall = (curve[-1]["wall_s"] if curve else 0.0) + last_chunk
        row = {"steps": float(done + chunk), "wall_s": wall, "success": success, "return": ret}
        row["length"] = length
        curve.append(row)
        ckpt.write_bytes(serialization.to_bytes(ts))
        if success > max((r["success"] for r in curve[:-1]), default=-1.0):
            (folder / "best.msgpack").write_bytes(serialization.to_bytes(ts))
        curve_file.write_text(json.dumps(curve, indent=1))
        log(
            f"{row['steps']:.3g} steps  {wall:7.1f} s  success {success:5.1%}  return {ret:8.2f}  "
            f"length {length:5.1f}"
        )
    return algo, ts, curve


def load_checkpoint(ts: Any, path: str | Path) -> Any:
    """``ts`` (a train state of the same algorithm and settings) with the values saved at ``path``
    (``checkpoint.msgpack`` or ``best.msgpack`` of a run folder)."""
    return serialization.from_bytes(ts, Path(path).read_bytes())


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m ihrcf_env.rl.jax_ppo``: train PPO on the JAX backend's landing env (float32,
    projected camera) and export the policy."""
    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--env-id", default="ihrcf_env/DeckLanding-v2")
    ap.add_argument("--level", default="moderate")
    ap.add_argument("--timesteps", type=float, default=1e7, help="env steps in all")
    ap.add_argument(
        "--chunk", type=float, default=5e5, help="env steps per compiled call (a checkpoint each)"
    )
    ap.add_argument("--time-budget", type=float, default=None, help="stop before this many s of wall time")
    ap.add_argument("--out", required=True, help="run folder (checkpoint, curve); resumes a run left there")
    ap.add_argument("--policy", default=None, help="write the trained policy here (.npz)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init-policy", default=None, help="start a new run from this exported policy (.npz)")
    ap.add_argument(
        "--init-log-std",
        type=float,
        default=-1.0,
        help="the Gaussian's log std when starting from --init-policy",
    )
    ap.add_argument("--num-envs", type=int, default=PPOSettings.num_envs)
    ap.add_argument("--num-steps", type=int, default=PPOSettings.num_steps)
    ap.add_argument("--learning-rate", type=float, default=PPOSettings.learning_rate)
    ap.add_argument("--eval-envs", type=int, default=64, help="episodes of each chunk's evaluation")
    ap.add_argument(
        "--export",
        choices=("last", "best"),
        default="last",
        help="write the last chunk's actor, or the one with the best evaluated success rate",
    )
    args = ap.parse_args(argv)
    if not (args.learning_rate > 0 and args.learning_rate < 1):
        ap.error(f"--learning-rate must be in (0, 1), got {args.learning_rate}")
    if args.eval_envs < 1:
        ap.error(f"--eval-envs must be a positive int, got {args.eval_envs}")
    from ihrcf_env.vector.checks import time_limit
    from ihrcf_env.vector.jax_make import make_functional

    max_steps = time_limit(args.env_id, None) or 600
    fenv = make_functional(args.env_id, "float32", max_steps=max_steps, level=args.level)
    settings = PPOSettings(num_envs=args.num_envs, num_steps=args.num_steps, learning_rate=args.learning_rate)
    algo, ts, curve = train(
        fenv, args.out, int(args.timesteps), max_steps, settings, int(args.chunk), args.seed,
        eval_envs=args.eval_envs, time_budget_s=args.time_budget, init_policy=args.init_policy,
        init_log_std=args.init_log_std,
    )  # fmt: skip
    if args.policy:
        last = curve[-1] if curve else {"steps": 0.0, "wall_s": 0.0}
        best = Path(args.out) / "best.msgpack"
        if args.export == "best" and curve and best.exists():
            ts = load_checkpoint(ts, best)
            last = max(curve, key=lambda r: r["success"])
        export_policy(
            algo, ts, args.policy, env_id=args.env_id, level=args.level, trainer="rejax PPO (JAX backend)",
            steps=int(last["steps"]), wall_s=float(last["wall_s"]),
            **({"init_policy": Path(args.init_policy).name} if args.init_policy else {}),
        )  # fmt: skip
        print(f"policy written to {args.policy}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
