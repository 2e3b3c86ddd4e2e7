"""The PPO learner of :mod:`ihrcf_env.rl.jax_ppo`: networks, train state, the clipped-surrogate
update and generalised advantage estimation, as pure JAX functions.

The actor is rejax's Gaussian MLP policy (so an exported actor is an
:class:`~ihrcf_env.control.mlp_policy.MlpPolicy`), the critic rejax's value MLP. The critic may
read more than the actor (an *asymmetric* actor-critic): each row of ``obs`` holds the actor's
observation in its first ``actor_inputs`` entries and the critic's privileged inputs after them;
the actor never sees the privileged part, so the exported policy runs on the env's observation
alone. Observations are normalised by running statistics (mean and variance over every row seen)
and clipped to +-:data:`CLIP_OBS`, as :class:`~ihrcf_env.control.mlp_policy.MlpPolicy` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import jax
import jax.numpy as jnp
import optax
from flax import linen as nn
from flax import struct
from flax.training.train_state import TrainState as NetState
from rejax.networks import GaussianPolicy, VNetwork

__all__ = [
    "CLIP_OBS",
    "Learner",
    "RunningStats",
    "TrainState",
    "Trajectory",
    "gae",
    "normalise",
    "update_stats",
]

#: Normalised observations are clipped to this magnitude (as ``MlpPolicy.clip_obs``).
CLIP_OBS = 10.0


class RunningStats(struct.PyTreeNode):
    """Running mean and variance of the observation rows (``count`` rows seen)."""

    mean: Any
    var: Any
    count: Any


class TrainState(struct.PyTreeNode):
    """The learner's state: the actor's and the critic's parameters and optimisers, the
    observation statistics, a key and the env steps trained on."""

    actor_ts: NetState
    critic_ts: NetState
    obs_rms_state: RunningStats
    rng: Any
    global_step: Any


class Trajectory(struct.PyTreeNode):
    """One rollout, each field (T, N, ...): normalised observations (actor's and privileged),
    the sampled (unclipped) actions, their log-probabilities, rewards, values and episode ends."""

    obs: Any
    action: Any
    log_prob: Any
    reward: Any
    value: Any
    done: Any


def update_stats(stats: RunningStats, x: Any) -> RunningStats:
    """``stats`` with the rows of ``x`` (B, D) added (Chan's parallel update)."""
    n = x.shape[0]
    mean, var = x.mean(axis=0), x.var(axis=0)
    delta = mean - stats.mean
    total = stats.count + n
    new_mean = stats.mean + delta * n / total
    m2 = stats.var * stats.count + var * n + delta**2 * stats.count * n / total
    return RunningStats(new_mean, m2 / total, total)


def normalise(stats: RunningStats, x: Any) -> Any:
    """``x`` normalised by ``stats`` and clipped to +-:data:`CLIP_OBS`."""
    return jnp.clip((x - stats.mean) / jnp.sqrt(stats.var + 1e-8), -CLIP_OBS, CLIP_OBS)


def gae(traj: Trajectory, last_value: Any, gamma: float, lam: float) -> tuple[Any, Any]:
    """Generalised advantage estimates and value targets of ``traj`` (T, N), bootstrapped from
    ``last_value`` (N,) (0 where the last step ended an episode); an episode's end (termination or
    the step limit) is not bootstrapped."""

    def back(carry: tuple[Any, Any], t: Trajectory) -> tuple[tuple[Any, Any], Any]:
        adv, next_value = carry
        live = 1.0 - t.done.astype(adv.dtype)
        delta = t.reward + gamma * next_value * live - t.value
        adv = delta + gamma * lam * live * adv
        return (adv, t.value), adv

    _, adv = jax.lax.scan(back, (jnp.zeros_like(last_value), last_value), traj, reverse=True)
    return adv, adv + traj.value


@dataclass(frozen=True, eq=False)
class Learner:
    """PPO's networks and hyperparameters (static: closed over by the compiled functions).

    ``actor_inputs``: the actor's share of an observation row; ``inputs``: the row's length
    (more with privileged critic inputs); ``action_dim``, ``low`` / ``high`` the action bounds;
    ``reward_scale``: the critic learns the returns of the rewards times this (the advantages are
    normalised per minibatch, so it sets the critic's target scale only); ``clip_value``: the value
    loss is clipped to ``clip_eps`` around the rollout's values, as the original PPO does."""

    actor_inputs: int
    inputs: int
    action_dim: int
    hidden: tuple[int, ...]
    activation: str
    learning_rate: float
    max_grad_norm: float
    gamma: float
    gae_lambda: float
    clip_eps: float
    ent_coef: float
    vf_coef: float
    num_epochs: int
    num_minibatches: int
    low: float = -1.0
    high: float = 1.0
    reward_scale: float = 1.0
    clip_value: bool = True

    @property
    def actor(self) -> GaussianPolicy:
        return GaussianPolicy(
            self.action_dim, (self.low, self.high), self.hidden, getattr(nn, self.activation)
        )

    @property
    def critic(self) -> VNetwork:
        return VNetwork(self.hidden, getattr(nn, self.activation))

    @cached_property
    def tx(self) -> Any:
        """The optimiser (one object per learner: the train state's static part)."""
        return optax.chain(optax.clip_by_global_norm(self.max_grad_norm), optax.adam(self.learning_rate))

    def init(self, key: Any) -> TrainState:
        """A new train state: random networks, empty statistics."""
        k_actor, k_critic, key = jax.random.split(key, 3)
        actor_params = self.actor.init(k_actor, jnp.zeros((1, self.actor_inputs)), k_actor)
        critic_params = self.critic.init(k_critic, jnp.zeros((1, self.inputs)))
        tx = self.tx
        stats = RunningStats(jnp.zeros(self.inputs), jnp.ones(self.inputs), jnp.asarray(1e-4))
        return TrainState(
            NetState.create(apply_fn=(), params=actor_params, tx=tx),
            NetState.create(apply_fn=(), params=critic_params, tx=tx),
            stats,
            key,
            jnp.asarray(0, jnp.int32),
        )

    def act(
        self, actor: Any, critic: Any, obs: Any, keys: Any, deterministic: Any
    ) -> tuple[Any, Any, Any, Any]:
        """For normalised rows ``obs`` (N, inputs) and one key per row: (action clipped to the
        bounds, the action taken, its log-probability, the critic's value). ``deterministic`` (a
        traced bool) takes the Gaussian's mean instead of a sample. Row by row: a row's result
        depends on its own inputs and key only."""
        x = obs[:, : self.actor_inputs]

        def one(xi: Any, k: Any) -> tuple[Any, Any]:
            sample, log_prob = self.actor.apply(actor, xi[None], k, method="action_log_prob")
            return sample[0], log_prob[0]

        sample, log_prob = jax.vmap(one)(x, keys)
        mean = self.mean_action(actor, x)
        taken = jnp.where(deterministic, mean, sample)
        value = self.critic.apply(critic, obs)
        return jnp.clip(taken, self.low, self.high), taken, log_prob, value

    def mean_action(self, actor_params: Any, x: Any) -> Any:
        """The actor's Gaussian mean for normalised actor inputs ``x`` (N, actor_inputs)."""
        features = self.actor.apply(actor_params, x, method=lambda m, o: m.features(o))
        return self.actor.apply(actor_params, features, method=lambda m, f: m.action_mean(f))

    def update(self, ts: TrainState, traj: Trajectory, last_obs: Any, last_done: Any) -> TrainState:
        """PPO's update on one rollout: advantages, then ``num_epochs`` passes over shuffled
        minibatches of the clipped surrogate (actor) and the clipped value loss (critic)."""
        last_value = self.critic.apply(ts.critic_ts.params, last_obs)
        last_value = jnp.where(last_done, 0.0, last_value)
        traj = traj.replace(reward=traj.reward * self.reward_scale)
        adv, targets = gae(traj, last_value, self.gamma, self.gae_lambda)
        size = adv.shape[0] * adv.shape[1]
        flat = jax.tree_util.tree_map(lambda a: a.reshape((size,) + a.shape[2:]), (traj, adv, targets))

        def epoch(ts: TrainState, _: Any) -> tuple[TrainState, None]:
            key, k = jax.random.split(ts.rng)
            perm = jax.random.permutation(k, size)
            batches = jax.tree_util.tree_map(
                lambda a: jnp.take(a, perm, axis=0).reshape((self.num_minibatches, -1) + a.shape[1:]), flat
            )
            ts, _ = jax.lax.scan(lambda s, b: (self._minibatch(s, *b), None), ts.replace(rng=key), batches)
            return ts, None

        ts, _ = jax.lax.scan(epoch, ts, None, self.num_epochs)
        return ts

    def _minibatch(self, ts: TrainState, t: Trajectory, adv: Any, targets: Any) -> TrainState:
        def actor_loss(params: Any) -> Any:
            log_prob, entropy = self.actor.apply(
                params, t.obs[:, : self.actor_inputs], t.action, method="log_prob_entropy"
            )
            ratio = jnp.exp(log_prob - t.log_prob)
            a = (adv - adv.mean()) / (adv.std() + 1e-8)
            clipped = jnp.clip(ratio, 1.0 - self.clip_eps, 1.0 + self.clip_eps)
            return -jnp.minimum(ratio * a, clipped * a).mean() - self.ent_coef * entropy.mean()

        def critic_loss(params: Any) -> Any:
            value = self.critic.apply(params, t.obs)
            loss = jnp.square(value - targets)
            if self.clip_value:
                clipped = t.value + jnp.clip(value - t.value, -self.clip_eps, self.clip_eps)
                loss = jnp.maximum(loss, jnp.square(clipped - targets))
            return self.vf_coef * 0.5 * loss.mean()

        actor_ts = ts.actor_ts.apply_gradients(grads=jax.grad(actor_loss)(ts.actor_ts.params))
        critic_ts = ts.critic_ts.apply_gradients(grads=jax.grad(critic_loss)(ts.critic_ts.params))
        return ts.replace(actor_ts=actor_ts, critic_ts=critic_ts)
