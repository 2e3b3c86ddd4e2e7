"""``python -m ihrcf_env.benchmark`` (the same command as ``ihrcf-benchmark``): see
:mod:`ihrcf_env.cli.benchmark`. A launcher (:func:`ihrcf_env.cli.launch.launch`): the command is
imported when it runs, so a Ctrl-C during its start-up exits with status 130."""

from ihrcf_env.cli.launch import launch

if __name__ == "__main__":
    raise SystemExit(launch("benchmark"))
