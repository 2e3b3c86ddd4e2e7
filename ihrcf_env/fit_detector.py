"""``python -m ihrcf_env.fit_detector`` (the same command as ``ihrcf-fit-detector``):
see :mod:`ihrcf_env.cli.fit_detector`."""

from ihrcf_env.cli.fit_detector import main

if __name__ == "__main__":
    raise SystemExit(main())
