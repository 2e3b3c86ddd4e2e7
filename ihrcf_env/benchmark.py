"""``python -m ihrcf_env.benchmark`` (the same command as ``ihrcf-benchmark``):
see :mod:`ihrcf_env.cli.benchmark`."""

from ihrcf_env.cli.benchmark import main

if __name__ == "__main__":
    raise SystemExit(main())
