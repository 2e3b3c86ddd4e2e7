"""Train PPO with Ray RLlib (new API stack) on ``ihrcf_env/DeckLanding-v1``, on this machine or on
a multi-node Ray cluster.

The env is registered with Ray's registry (``ray.tune.registry.register_env``) as
``ihrcf_deck_landing``; ``--num-env-runners`` EnvRunner actors (one CPU each) step
``--num-envs-per-env-runner`` envs each with the fast projected camera (RLlib's SyncVectorEnv of single
envs, or with ``--vector-env`` the id's native vector env, ``gym.make_vec``'s vector_entry_point);
the learner runs in this process. Needs the ``[rl]`` extra on every node::

    pip install ".[rl]"
    # one machine: starts a local Ray instance with as many CPUs as the machine has
    python examples/train_rllib.py --iterations 50 --num-env-runners 2 --out out/rllib

    # a multi-node cluster: the same Python and `pip install ".[rl]"` on every node, then
    ray start --head --port=6379                 # on the head node
    ray start --address=HEAD_IP:6379             # on each worker node
    python examples/train_rllib.py --address auto --num-env-runners 32 --iterations 200 --out out/rllib

Each iteration samples ``--train-batch-size`` env steps across the runners, then runs
``--num-epochs`` passes of minibatch SGD. Written to ``--out``: ``progress.csv`` (one row per
iteration: steps, return, success rate over each runner's last 100 episodes) and ``checkpoint/``
(``Algorithm.save_to_path``, every ``--checkpoint-every`` iterations and at the end; continue with
``--restore OUT/checkpoint``).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--iterations", type=int, default=50, help="training iterations")
    ap.add_argument("--num-env-runners", type=int, default=2, help="EnvRunner actors (one CPU each)")
    ap.add_argument("--num-envs-per-env-runner", type=int, default=1)
    ap.add_argument(
        "--vector-env",
        action="store_true",
        help="each runner steps its envs as the id's native vector env (gym.make_vec's vector_entry_point) "
        "instead of RLlib's SyncVectorEnv of single envs",
    )
    ap.add_argument("--address", default=None, help="Ray cluster: 'auto' or HOST:PORT (default: local)")
    ap.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local Ray instance")
    ap.add_argument("--out", type=Path, default=Path("out/rllib"))
    ap.add_argument("--restore", type=Path, default=None, help="continue from a checkpoint directory")
    ap.add_argument("--checkpoint-every", type=int, default=10, help="iterations between checkpoints")
    ap.add_argument("--env-id", default=None, help="default: ihrcf_env/DeckLanding-v1")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    ap.add_argument("--max-episode-steps", type=int, default=None, help="default: the env's limit")
    ap.add_argument(
        "--deck-motion", action="store_true", help="v1 observation with the fused filter's deck motion"
    )
    ap.add_argument("--train-batch-size", type=int, default=4000, help="env steps per iteration")
    ap.add_argument("--minibatch-size", type=int, default=256)
    ap.add_argument("--num-epochs", type=int, default=10)
    ap.add_argument("--lr", type=float, default=3e-4)
    ap.add_argument("--gamma", type=float, default=0.99)
    ap.add_argument("--net-arch", type=int, nargs="+", default=[64, 64], help="hidden layer sizes")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    for name in ("iterations", "num_envs_per_env_runner", "train_batch_size", "minibatch_size", "num_epochs"):
        if getattr(args, name) < 1:
            ap.error(f"--{name.replace('_', '-')} must be >= 1")
    if args.num_env_runners < 0:
        ap.error("--num-env-runners must be >= 0 (0: sample in this process)")

    try:
        import gymnasium as gym
        import ray
        from ray.rllib.algorithms.ppo import PPOConfig
        from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

        from ihrcf_env.rl import rllib
        from ihrcf_env.rl.curves import CsvLog
    except ModuleNotFoundError as e:
        print(f'{e.name} is not installed: this example needs the [rl] extra (pip install ".[rl]")')
        return 2

    if args.address is None:
        ray.init(num_cpus=args.num_cpus or os.cpu_count(), include_dashboard=False)
    else:
        ray.init(address=args.address)
    env_config: dict[str, object] = {"env_id": args.env_id, "camera_model": args.camera_model}
    if args.max_episode_steps is not None:
        env_config["max_episode_steps"] = args.max_episode_steps
    if args.deck_motion:
        env_config["deck_motion"] = True
    vectorize_mode = gym.VectorizeMode.VECTOR_ENTRY_POINT if args.vector_env else gym.VectorizeMode.SYNC
    samplers = max(1, args.num_env_runners) * args.num_envs_per_env_runner  # 0 runners: this process samples
    frag = max(1, args.train_batch_size // samplers)
    config = (
        PPOConfig()
        .environment(rllib.register(), env_config=env_config)
        .env_runners(
            num_env_runners=args.num_env_runners,
            num_envs_per_env_runner=args.num_envs_per_env_runner,
            rollout_fragment_length=frag,
            gym_env_vectorize_mode=vectorize_mode,
        )
        .training(
            train_batch_size_per_learner=args.train_batch_size,
            minibatch_size=args.minibatch_size,
            num_epochs=args.num_epochs,
            lr=args.lr,
            gamma=args.gamma,
        )
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(args.net_arch), vf_share_layers=False))
        .callbacks(on_episode_end=rllib.log_success)
        .debugging(seed=args.seed)
    )
    algo = config.build_algo()
    if args.restore is not None:
        algo.restore_from_path(str(args.restore.resolve()))
    cpus = ray.cluster_resources().get("CPU", 0)
    kind = "native vector env" if args.vector_env else "SyncVectorEnv"
    print(
        f"Ray: {cpus:.0f} CPUs, {args.num_env_runners} env runners, "
        f"{args.num_envs_per_env_runner} envs each ({kind})",
        flush=True,
    )
    log = CsvLog(args.out / "progress.csv", rllib.PROGRESS_FIELDS)
    ckpt = (args.out / "checkpoint").resolve()
    t0 = time.time()
    try:
        for i in range(1, args.iterations + 1):
            it0 = time.time()
            row = rllib.progress_row(i, time.time() - t0, algo.train())
            row["wall_s"] = round(time.time() - t0, 1)
            log.write(row)
            print(
                f"iter {i}: {row['timesteps']} steps, {time.time() - it0:.1f} s, return "
                f"{row['episode_return_mean']:.1f}, success {row['success_rate']:.2f}",
                flush=True,
            )
            if i % args.checkpoint_every == 0 or i == args.iterations:
                algo.save_to_path(str(ckpt))
    finally:
        algo.stop()
        ray.shutdown()
    print(f"saved {ckpt} and {args.out / 'progress.csv'} ({time.time() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
