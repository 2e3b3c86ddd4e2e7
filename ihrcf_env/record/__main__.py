"""``python -m ihrcf_env.record`` (the same command as ``ihrcf-record``): see :mod:`ihrcf_env.cli.record`."""

from ihrcf_env.cli.record import main

if __name__ == "__main__":
    raise SystemExit(main())
