"""Train a recurrent (GRU) landing policy by DAgger on whole episodes (the ``[rl]`` extra, PyTorch).

The learner imitates the scripted landing, which runs alongside it on the same observations
(``ihrcf_env.rl.recurrent``); the policy is saved as a numpy ``.npz`` that the evaluate CLI runs
without PyTorch::

    python examples/train_recurrent.py --env-id ihrcf_env/DeckLanding-v2 --out out/gru-v2 \
        --deck-motion --drop-inputs ihrcf atda --rounds 12 --episodes 32 --val-episodes 100
    python -m ihrcf_env.evaluate --policy out/gru-v2/best.npz --level moderate --episodes 100 \
        --camera-model rendered

``--vector-envs 32`` flies the episodes in one native vector env of 32 envs (over
``--workers`` processes) instead of single envs.

Writes to ``--out``: ``best.npz`` (the best round on the validation seeds), ``final.npz``,
``round_R.npz``, ``dagger.csv`` and ``checkpoint.pt`` (run the same command again to continue a
stopped run). Seeds: DAgger round r flies 30_000 + 100 SEED + 1000 r and up; validation flies
20_000 + ``--val-offset`` and up; the evaluation protocol's test seeds (100_000 and up) and seeds
below 10_000 are never flown in training or selection.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    """Command line entry point; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env-id", default="ihrcf_env/DeckLanding-v2")
    ap.add_argument("--out", type=Path, default=Path("out/gru"))
    ap.add_argument("--deck-motion", action="store_true", help="the env's deck_motion=True observation")
    ap.add_argument("--level", default=None, help="the v2 level to train on (default: the env's)")
    ap.add_argument("--drop-inputs", nargs="*", default=[], help="observation fields the policy ignores")
    ap.add_argument("--rounds", type=int, default=12, help="learner rounds after the expert's (>= 0)")
    ap.add_argument("--episodes", type=int, default=32, help="episodes per round (>= 1)")
    ap.add_argument("--val-episodes", type=int, default=100, help="validation episodes per round (>= 0)")
    ap.add_argument("--val-offset", type=int, default=30, help="validation seeds: 20_000 + this and up")
    ap.add_argument("--noise", type=float, default=0.05, help="learner action noise (action units)")
    ap.add_argument("--epochs", type=int, default=20, help="fit epochs per learner round")
    ap.add_argument("--first-epochs", type=int, default=60, help="fit epochs after the expert's round")
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--polish-epochs", type=int, default=0, help="a final fit on all episodes (0: none)")
    ap.add_argument("--polish-lr", type=float, default=3e-4, help="its learning rate")
    ap.add_argument("--hidden", type=int, default=128, help="GRU state size")
    ap.add_argument("--workers", type=int, default=2, help="processes flying episodes")
    ap.add_argument(
        "--vector-envs",
        type=int,
        default=0,
        help="fly in one vector env of this many envs over --workers processes (0: single envs)",
    )
    ap.add_argument(
        "--fit-threads",
        type=int,
        default=None,
        help="torch threads of the fit (default: --workers; the same weights for any number)",
    )
    ap.add_argument("--max-wall-min", type=float, default=None, help="stop after the round that passes it")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    for name, least in (
        ("rounds", 0),
        ("episodes", 1),
        ("val_episodes", 0),
        ("epochs", 1),
        ("workers", 1),
        ("vector_envs", 0),
        ("polish_epochs", 0),
        ("fit_threads", 1),
    ):
        if getattr(args, name) is None:
            continue
        if getattr(args, name) < least:
            ap.error(f"--{name.replace('_', '-')} must be >= {least}")
    try:
        import torch as th

        from ihrcf_env.rl.ppo_args import DAGGER_SEED_BASE, EVAL_SEED_BASE
        from ihrcf_env.rl.recurrent import RunConfig, train
    except ModuleNotFoundError as e:
        print(f'{e.name} is not installed: this example needs the [rl] extra (pip install ".[rl]")')
        return 2
    th.set_num_threads(1)
    env_kw: dict[str, object] = {"deck_motion": True} if args.deck_motion else {}
    if args.level is not None:
        env_kw["level"] = args.level
    val0 = EVAL_SEED_BASE + args.val_offset
    cfg = RunConfig(
        args.env_id,
        args.out,
        env_kw,
        tuple(args.drop_inputs),
        args.rounds,
        args.episodes,
        tuple(range(val0, val0 + args.val_episodes)),
        DAGGER_SEED_BASE + 100 * args.seed,
        args.noise,
        args.epochs,
        args.first_epochs,
        args.lr,
        polish_epochs=args.polish_epochs,
        polish_lr=args.polish_lr,
        hidden=args.hidden,
        workers=args.workers,
        vector_envs=args.vector_envs,
        max_wall_min=args.max_wall_min,
        seed=args.seed,
        fit_threads=args.workers if args.fit_threads is None else args.fit_threads,
    )
    train(cfg, lambda s: print(s, flush=True))
    print(f"best policy: {args.out / 'best.npz'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
