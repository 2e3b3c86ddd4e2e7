"""``python -m ihrcf_env.calibrate`` (the same command as ``ihrcf-calibrate``):
see :mod:`ihrcf_env.cli.calibrate`."""

from ihrcf_env.cli.calibrate import main

if __name__ == "__main__":
    raise SystemExit(main())
