"""Run a command module with Ctrl-C handled from its import on (standard library only).

A command module imports PyBullet, OpenCV, SciPy and Gymnasium: a second or more of start-up
before its ``main`` runs. :func:`run_command` imports it inside a ``try``, so a Ctrl-C at any
moment after the caller started, start-up included, ends the command with a one-line message and
exit status 130 (as a Ctrl-C during the run does, :func:`ihrcf_env.cmdline.common.command_main`),
never a traceback. The console scripts (:mod:`ihrcf_env.cli.launch`) and the ``python -m``
launchers call it with the module that holds the command.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

from ihrcf_env.cmdline.common import interrupted


def run_command(name: str, module: str, argv: Sequence[str] | None = None) -> int:
    """Import ``module`` and run its ``main(argv)`` as the command ``ihrcf-<name>`` (``argv``
    None: ``sys.argv[1:]``); its exit status, 130 on Ctrl-C."""
    try:
        return int(importlib.import_module(module).main(argv))
    except KeyboardInterrupt:
        return interrupted(name)


__all__ = ["run_command"]
