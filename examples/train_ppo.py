"""Train a PPO landing policy (stable-baselines3, the ``[rl]`` extra) on ``ihrcf_env/DeckLanding-v1``.

Trains on the projected camera (evaluate on the rendered one with the evaluate CLI). The shipped recipe
(README) warm-starts the policy by DAgger from the scripted landing, then fine-tunes it with PPO::

    python examples/train_ppo.py --out out/ppo --total-steps 400000 --deck-motion --drop-inputs ihrcf \
        atda --dagger-rounds 6 --dagger-episodes 24 --log-std-init -2.3 --learning-rate 3e-5 --gamma 0.998
``--vector`` steps the ``--n-envs`` training envs as the id's native vector env in this process
(``ihrcf_env.rl.vec.make_sb3_vec_env``) instead of one process per env (SubprocVecEnv).
Writes to ``--out``: ``final.zip``, ``best.zip`` (best evaluation), CSV logs, ``curves.png``,
``checkpoints/`` (``steps_N.zip`` every ``--checkpoint-every`` steps, ``latest.zip`` for ``--resume``).
Seeds: training env k starts from ``reset(seed=10_000 + 100 SEED + k)``, DAgger round r from
30_000 + 100 SEED + 1000 r (+ k), evaluations from 20_000; seeds below 10_000 are never trained on.
"""

from __future__ import annotations

import functools
import time

from ihrcf_env.core.threads import one_blas_thread
from ihrcf_env.rl.curriculum import curriculum_env
from ihrcf_env.rl.curves import EVAL_FIELDS, TRAIN_FIELDS, CsvLog, plot_curves, summary
from ihrcf_env.rl.envs import make_env, policy_inputs
from ihrcf_env.rl.ppo_args import DAGGER_SEED_BASE, EVAL_SEED_BASE, TRAIN_SEED_BASE, parse_args


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap, args = parse_args(argv, __doc__)
    try:
        import torch as th
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import CallbackList
        from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor, VecNormalize

        from ihrcf_env.rl import sb3
        from ihrcf_env.rl.imitation import warm_start
        from ihrcf_env.rl.vec import make_sb3_vec_env
    except ModuleNotFoundError as e:
        print(f'{e.name} is not installed: this example needs the [rl] extra (pip install ".[rl]")')
        return 2
    th.set_num_threads(1)  # the env processes need the cores; a 64x64 MLP gains nothing from threads
    env_id = args.env_id
    env_kw: dict[str, object] = {"deck_motion": True} if args.deck_motion else {}
    if args.reward_weights:  # shapes the training signal only: success is the task's
        env_kw["reward_weights"] = dict(args.reward_weights)
    if args.max_episode_steps is not None:
        env_kw["max_episode_steps"] = args.max_episode_steps
    thunk = functools.partial(make_env, env_id, args.camera_model, args.frame_stack, **env_kw)
    try:
        inputs = policy_inputs(thunk, args.drop_inputs)  # None: all
    except ValueError as e:
        ap.error(f"--drop-inputs: {e}")
    train_thunk = functools.partial(curriculum_env, thunk) if args.curriculum_steps else thunk
    if args.vector:  # one process: N envs stepped by the vector env (SB3's autoreset convention)
        if args.workers > 1:
            env_kw["workers"] = args.workers
        base = make_sb3_vec_env(env_id, args.n_envs, None, camera_model=args.camera_model, **env_kw)
    else:
        with one_blas_thread():  # the env processes: one BLAS thread each
            base = (SubprocVecEnv if args.n_envs > 1 else DummyVecEnv)([train_thunk] * args.n_envs)
    venv = VecMonitor(base, info_keywords=("is_success",))
    out, ckpt = args.out, sb3.ResumableCheckpointCallback(args.out / "checkpoints", args.checkpoint_every)
    resume = args.resume and ckpt.model_path.exists()
    if resume:
        venv = sb3.load_vecnormalize(ckpt.vecnormalize_path, venv)
        lr = {} if args.learning_rate is None else {"learning_rate": args.learning_rate}
        model = PPO.load(ckpt.model_path, env=venv, device="cpu", **lr)
        print(f"resuming from {ckpt.model_path} at {model.num_timesteps} steps", flush=True)
    else:
        venv = VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=args.gamma)
        kw = {k: getattr(args, k) for k in ("n_steps", "batch_size", "n_epochs", "gamma", "ent_coef", "seed")}
        net = {"net_arch": list(args.net_arch), "log_std_init": args.log_std_init}
        net["features_extractor_class"] = sb3.RunningNormExtractor
        net["features_extractor_kwargs"] = {"inputs": inputs}
        model = PPO("MlpPolicy", venv, args.learning_rate or 3e-4, device="cpu", policy_kwargs=net, **kw)
        if args.init_action_mean is not None:  # an untrained policy that already does this on average
            sb3.set_initial_action_mean(model, args.init_action_mean)
    done, keep = model.num_timesteps, (model.num_timesteps if resume else None)
    train_log = CsvLog(out / "train.csv", TRAIN_FIELDS, keep_until=keep)
    eval_log = CsvLog(out / "eval.csv", EVAL_FIELDS, keep_until=keep)
    seeds = range(EVAL_SEED_BASE, EVAL_SEED_BASE + args.eval_episodes)
    evaluator = sb3.HeldOutEvalCallback(thunk, seeds, args.eval_every, eval_log, out / "best.zip")
    callbacks = [sb3.EpisodeCsvCallback(train_log), ckpt, evaluator]
    if args.dagger_rounds:  # the normaliser keeps the DAgger data's statistics; the critic learns first
        callbacks.append(sb3.CriticWarmupCallback(args.critic_warmup_steps))
        if not resume:  # DAgger, then the warm-started policy's evaluation (at 0 PPO steps)
            seed0 = DAGGER_SEED_BASE + 100 * args.seed
            warm_start(
                model, venv, thunk, args.dagger_rounds, args.dagger_episodes, seed0, out / "dagger.csv"
            )
            evaluator.init_callback(model)
            evaluator.evaluate()
    else:
        callbacks.append(sb3.NormUpdateCallback())
    venv.seed(TRAIN_SEED_BASE + 100 * args.seed + done)  # first reset of each env process (+ its index)
    if args.curriculum_steps:
        callbacks.append(sb3.CurriculumCallback(args.curriculum_steps))
    if args.max_wall_min is not None:  # evaluator.start_time already counts earlier segments
        callbacks.append(sb3.WallClockBudgetCallback(evaluator.start_time + 60.0 * args.max_wall_min))
    kind = ", vector env" if args.vector else ""
    print(
        f"training PPO on {env_id} (camera_model={args.camera_model}, {args.n_envs} envs{kind})", flush=True
    )
    t0 = time.time()
    try:
        if args.total_steps > done:
            model.learn(args.total_steps - done, callback=CallbackList(callbacks), reset_num_timesteps=False)
    finally:
        venv.close()
    model.save(out / "final.zip")
    steps, wall = model.num_timesteps - done, time.time() - t0
    plot_curves(out / "train.csv", out / "eval.csv", out / "curves.png", title=f"PPO on {env_id}")
    s = summary(out / "eval.csv")
    print(f"{steps} steps in {wall:.0f} s ({steps / max(wall, 1e-9):.0f} steps/s incl. evaluations)")
    print(f"held-out success: last {s['last_success_rate']:.0%}, best {s['best_success_rate']:.0%} ({out})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
