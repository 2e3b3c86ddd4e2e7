"""``python -m ihrcf_env.mavlink`` (the same command as ``ihrcf-mavlink``): see
:mod:`ihrcf_env.cli.mavlink`. A launcher, run only by ``python -m`` (importing the package
:mod:`ihrcf_env.mavlink` never loads it), as the ``python -m`` launchers at the package root are."""

from ihrcf_env.cli.launch import launch

if __name__ == "__main__":
    raise SystemExit(launch("mavlink"))
