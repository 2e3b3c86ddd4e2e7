"""The console scripts' entry points (``ihrcf-<name>`` -> :func:`launch`), light to import.

Each entry point imports only the standard library and :mod:`ihrcf_env.cmdline.launch`, then
imports its command inside a ``try`` (:func:`~ihrcf_env.cmdline.launch.run_command`), so a Ctrl-C
at any moment after the interpreter starts the entry point, start-up included, ends the command
with a one-line message and exit status 130, never a traceback. The package root's ``python -m
ihrcf_env.<name>`` launchers run the same :func:`launch`.
"""

from __future__ import annotations

from collections.abc import Sequence

from ihrcf_env.cli import COMMANDS
from ihrcf_env.cmdline.launch import run_command

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
    return run_command(name, COMMANDS[name], argv)


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
