"""``python -m ihrcf_env.mavlink`` (the same command as ``ihrcf-mavlink``): see
:mod:`ihrcf_env.cli.mavlink`."""

from ihrcf_env.cli.mavlink import main

if __name__ == "__main__":
    raise SystemExit(main())
