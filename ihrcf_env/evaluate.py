"""``python -m ihrcf_env.evaluate`` (the same command as ``ihrcf-evaluate``):
see :mod:`ihrcf_env.cli.evaluate`."""

from ihrcf_env.cli.evaluate import main

if __name__ == "__main__":
    raise SystemExit(main())
