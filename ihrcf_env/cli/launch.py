"""The console scripts' entry points (``ihrcf-<name>`` -> :func:`launch`), light to import.

A command module imports PyBullet, OpenCV, SciPy and Gymnasium: a second or more of start-up
before its ``main`` runs. Each entry point here imports only the standard library, then imports the
command inside a ``try``, so a Ctrl-C at any moment after the interpreter starts the entry point,
start-up included, ends the command with a one-line message and exit status 130 (as a Ctrl-C
during the run does, :func:`ihrcf_env.cli.common.command_main`), never a traceback. The
``python -m ihrcf_env.<name>`` launchers run the same :func:`launch`.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence

from ihrcf_env.cli import COMMANDS
from ihrcf_env.cli.common import interrupted

__all__ = [
    "benchmark",
    "calibrate",
    "evaluate",
    "fit_detector",
    "launch",
    "mavlink",
    "record",
]


def launch(name: str, argv: Sequence[str] | None = None) -> int:
    """Run the command ``ihrcf-<name>`` (a key of :data:`~ihrcf_env.cli.COMMANDS`) with ``argv``
    (None: ``sys.argv[1:]``); its exit status, 130 on Ctrl-C."""
    try:
        module = importlib.import_module(f"ihrcf_env.cli.{COMMANDS[name]}")
        return int(module.main(argv))
    except KeyboardInterrupt:
        return interrupted(name)


def benchmark() -> int:
    """``ihrcf-benchmark``."""
    return launch("benchmark")


def calibrate() -> int:
    """``ihrcf-calibrate``."""
    return launch("calibrate")


def evaluate() -> int:
    """``ihrcf-evaluate``."""
    return launch("evaluate")


def fit_detector() -> int:
    """``ihrcf-fit-detector``."""
    return launch("fit-detector")


def mavlink() -> int:
    """``ihrcf-mavlink``."""
    return launch("mavlink")


def record() -> int:
    """``ihrcf-record``."""
    return launch("record")
