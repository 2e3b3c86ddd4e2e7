"""``python -m ihrcf_env.record`` (the same command as ``ihrcf-record``): see
:mod:`ihrcf_env.cli.record`. A launcher, run only by ``python -m`` (importing the package
:mod:`ihrcf_env.record` never loads it): the one file under ``record/`` that reaches the command
lines, as the ``python -m`` launchers at the package root do."""

from ihrcf_env.cli.launch import launch

if __name__ == "__main__":
    raise SystemExit(launch("record"))
