"""``python -m ihrcf_env.fit_detector`` (the same command as ``ihrcf-fit-detector``): see
:mod:`ihrcf_env.cli.fit_detector`. A launcher (:func:`ihrcf_env.cli.launch.launch`): the command is
imported when it runs, so a Ctrl-C during its start-up exits with status 130."""

from ihrcf_env.cli.launch import launch

if __name__ == "__main__":
    raise SystemExit(launch("fit-detector"))
