"""Train a PPO landing policy (stable-baselines3) on ``ihrcf_env/DeckLanding-v1``.

Training uses the fast projected camera (``camera_model="projected"``: no rendering); evaluate the
result on the rendered camera with the evaluate CLI. Needs the ``[rl]`` extra::

    python examples/train_ppo.py --out out/ppo --total-steps 3000000 --max-wall-min 60 --deck-motion \
        --curriculum-steps 500000 --init-action-mean 0 0 -0.3 0 --log-std-init -1 --gamma 0.998 \
        --reward-weights time=2          # 2 env processes; --resume continues (earlier wall counted)
    python -m ihrcf_env.evaluate --env-id ihrcf_env/DeckLanding-v1 --policy out/ppo/final.zip \\
        --episodes 50 --seed 0 --camera-model rendered

Writes to ``--out``: ``final.zip`` (last update), ``best.zip`` (best periodic evaluation),
``train.csv`` / ``eval.csv`` (one row per training episode / evaluation), ``curves.png``,
``checkpoints/`` (every ``--checkpoint-every`` steps; ``--resume`` continues from them). The policy
normalises its observation itself (``ihrcf_env.rl.sb3.RunningNormExtractor``): the ``.zip`` is all
an evaluation needs.

Seeds: training env k starts from ``reset(seed=10_000 + 100 * SEED + k)`` and runs on from there;
the periodic evaluations use seeds 20_000 .. 20_000 + EVAL_EPISODES - 1; seeds below 10_000 (e.g.
the CLI's ``--seed 0 --episodes 50``) are never seen in training or model selection.
``--curriculum-steps N``: training starts low near the tag, widening to the task's starts over N steps
(``ihrcf_env.rl.curriculum``); the evaluations always use the task's starts.
"""

from __future__ import annotations

import argparse
import functools
import time
from pathlib import Path

from ihrcf_env.rl.curriculum import curriculum_env
from ihrcf_env.rl.curves import EVAL_FIELDS, TRAIN_FIELDS, CsvLog, plot_curves, summary
from ihrcf_env.rl.envs import default_env_id, make_env, name_value

TRAIN_SEED_BASE, EVAL_SEED_BASE = 10_000, 20_000


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--total-steps", type=int, default=1_000_000, help="environment steps in all")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("out/ppo"))
    ap.add_argument("--n-envs", type=int, default=2, help="env processes (SubprocVecEnv if > 1)")
    ap.add_argument("--resume", action="store_true", help="continue from OUT/checkpoints/latest.zip")
    ap.add_argument("--env-id", default=None, help="default: ihrcf_env/DeckLanding-v1 (v0 if v1 is absent)")
    ap.add_argument("--camera-model", default="projected", choices=("projected", "rendered"))
    ap.add_argument("--max-episode-steps", type=int, default=None, help="default: the env's limit")
    ap.add_argument("--deck-motion", action="store_true", help="v1 deck_motion=True (CLI detects it)")
    ap.add_argument("--curriculum-steps", type=int, default=0, help="start curriculum length (0: off)")
    ap.add_argument("--ent-coef", type=float, default=0.0, help="PPO entropy bonus")
    ap.add_argument("--init-action-mean", type=float, nargs="+", default=None, help="e.g. 0 0 -0.3 0")
    ap.add_argument("--log-std-init", type=float, default=0.0, help="initial log std of the actions")
    ap.add_argument("--reward-weights", nargs="*", type=name_value, default=[], metavar="NAME=W")
    ap.add_argument("--n-steps", type=int, default=1024, help="rollout length per env")
    ap.add_argument("--batch-size", type=int, default=256)
    ap.add_argument("--n-epochs", type=int, default=10)
    ap.add_argument("--learning-rate", type=float, default=None, help="3e-4; with --resume: replaces it")
    ap.add_argument("--gamma", type=float, default=0.99)
    ap.add_argument("--net-arch", type=int, nargs="+", default=[64, 64], help="hidden layer sizes")
    ap.add_argument("--eval-every", type=int, default=50_000, help="steps between evaluations")
    ap.add_argument("--eval-episodes", type=int, default=20)
    ap.add_argument("--checkpoint-every", type=int, default=50_000)
    ap.add_argument("--max-wall-min", type=float, default=None, help="wall budget (min), resumes counted")
    args = ap.parse_args(argv)
    positive = ("total_steps", "n_envs", "n_steps", "batch_size", "eval_every", "eval_episodes")
    for name in ("curriculum_steps", *positive):
        if getattr(args, name) < (name in positive):
            ap.error(f"--{name.replace('_', '-')} must be >= {int(name in positive)}")
    if args.max_wall_min is not None and not args.max_wall_min > 0:
        ap.error("--max-wall-min must be > 0 (minutes)")

    import torch as th
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

    from ihrcf_env.rl import sb3

    th.set_num_threads(1)  # the env processes need the cores; a 64x64 MLP gains nothing from threads
    env_id = args.env_id or default_env_id()
    env_kw: dict[str, object] = {"deck_motion": True} if args.deck_motion else {}
    if args.reward_weights:  # shapes the training signal only: success is the task's
        env_kw["reward_weights"] = dict(args.reward_weights)
    if args.max_episode_steps is not None:
        env_kw["max_episode_steps"] = args.max_episode_steps
    thunk = functools.partial(make_env, env_id, args.camera_model, **env_kw)
    train_thunk = functools.partial(curriculum_env, thunk) if args.curriculum_steps else thunk
    vec_cls = SubprocVecEnv if args.n_envs > 1 else DummyVecEnv
    venv = VecMonitor(vec_cls([train_thunk] * args.n_envs), info_keywords=("is_success",))
    out, ckpt = args.out, sb3.ResumableCheckpointCallback(args.out / "checkpoints", args.checkpoint_every)
    resume = args.resume and ckpt.model_path.exists()
    if resume:
        venv = sb3.load_vecnormalize(ckpt.vecnormalize_path, venv)
        lr = {} if args.learning_rate is None else {"learning_rate": args.learning_rate}
        model = PPO.load(ckpt.model_path, env=venv, device="cpu", **lr)
        print(f"resuming from {ckpt.model_path} at {model.num_timesteps} steps", flush=True)
    else:
        venv = VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=args.gamma)
        model = PPO(
            "MlpPolicy",
            venv,
            n_steps=args.n_steps,
            batch_size=args.batch_size,
            n_epochs=args.n_epochs,
            learning_rate=args.learning_rate or 3e-4,
            gamma=args.gamma,
            ent_coef=args.ent_coef,
            seed=args.seed,
            device="cpu",
            policy_kwargs={
                "net_arch": list(args.net_arch),
                "features_extractor_class": sb3.RunningNormExtractor,
                "log_std_init": args.log_std_init,
            },
        )
        if args.init_action_mean is not None:  # an untrained policy that already does this on average
            sb3.set_initial_action_mean(model, args.init_action_mean)
    done = model.num_timesteps
    venv.seed(TRAIN_SEED_BASE + 100 * args.seed + done)  # first reset of each env process (+ its index)
    keep = done if resume else None
    train_log = CsvLog(out / "train.csv", TRAIN_FIELDS, keep_until=keep)
    eval_log = CsvLog(out / "eval.csv", EVAL_FIELDS, keep_until=keep)
    seeds = range(EVAL_SEED_BASE, EVAL_SEED_BASE + args.eval_episodes)
    evaluator = sb3.HeldOutEvalCallback(thunk, seeds, args.eval_every, eval_log, out / "best.zip")
    callbacks = [sb3.EpisodeCsvCallback(train_log), ckpt, evaluator, sb3.NormUpdateCallback()]
    if args.curriculum_steps:
        callbacks.append(sb3.CurriculumCallback(args.curriculum_steps))
    if args.max_wall_min is not None:  # evaluator.start_time already counts earlier segments
        callbacks.append(sb3.WallClockBudgetCallback(evaluator.start_time + 60.0 * args.max_wall_min))
    print(f"training PPO on {env_id} (camera_model={args.camera_model}, {args.n_envs} envs)", flush=True)
    t0 = time.time()
    try:
        if args.total_steps > done:
            model.learn(args.total_steps - done, callback=CallbackList(callbacks), reset_num_timesteps=False)
    finally:
        venv.close()
    model.save(out / "final.zip")
    steps = model.num_timesteps - done
    plot_curves(out / "train.csv", out / "eval.csv", out / "curves.png", title=f"PPO on {env_id}")
    s = summary(out / "eval.csv")
    wall = time.time() - t0
    print(f"{steps} steps in {wall:.0f} s ({steps / max(wall, 1e-9):.0f} steps/s incl. evaluations)")
    print(f"held-out success: last {s['last_success_rate']:.0%}, best {s['best_success_rate']:.0%} ({out})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
