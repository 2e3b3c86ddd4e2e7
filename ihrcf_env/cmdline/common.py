"""What every command line shares: the parser, argument types, output checks, Ctrl-C, writing a
file whole (standard library only).

Every command is installed as a console script (``ihrcf-<name>``, :mod:`ihrcf_env.cli.launch`) and
runs as ``python -m ihrcf_env.<name>``; its ``--help`` is plain text that states every default.
Arguments are checked before any simulation starts: seeds, counts and output files (the folder
exists and is writable, the path is not a folder), so a bad argument fails at once with a message
naming it (argparse's exit status 2), not after a long run.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import functools
import math
import os
import stat
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

#: Exit status of a command stopped by Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 130

#: Largest seed NumPy's and Gymnasium's seeding accept (2**32 - 1 for a reset seed).
MAX_SEED = 2**32 - 1


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """The description and epilog as written; each option's help ends with its default
    (``(default: X)``) unless the help already states it or there is nothing to state."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text.lower() or action.default is argparse.SUPPRESS:
            return text
        if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
            return f"{text} (default: off)" if action.default is False else f"{text} (default: on)"
        if action.option_strings and action.default is not None and not action.required:
            return f"{text} (default: %(default)s)"
        return text


def make_parser(name: str, description: str, epilog: str | None = None) -> argparse.ArgumentParser:
    """The parser of the command ``ihrcf-<name>`` (also ``python -m ihrcf_env.<name>``)."""
    return argparse.ArgumentParser(
        prog=f"ihrcf-{name}",
        description=description,
        epilog=epilog,
        formatter_class=HelpFormatter,
    )


def int_in(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse ``type``: an integer in [low, high] (high None: no upper bound)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < low or (high is not None and value > high):
            span = f">= {low}" if high is None else f"in [{low}, {high}]"
            raise argparse.ArgumentTypeError(f"must be an integer {span}, got {value}")
        return value

    parse.__name__ = "integer"
    return parse


def real_in(low: float, high: float, *, low_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in [low, high] (``low_open``: in (low, high])."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not (math.isfinite(value) and (value > low if low_open else value >= low) and value <= high):
            span = f"({low:g}, {high:g}]" if low_open else f"[{low:g}, {high:g}]"
            raise argparse.ArgumentTypeError(f"must be a number in {span}, got {text}")
        return value

    parse.__name__ = "number"
    return parse


#: An argparse ``type`` for seeds: an integer in [0, MAX_SEED].
seed_type = int_in(0, MAX_SEED)


def special_file(path: str | Path) -> bool:
    """Whether ``path`` exists and is neither a regular file nor a folder (a device, a FIFO, a
    socket, or a symbolic link to one): writing a file whole would replace it."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def check_output(ap: argparse.ArgumentParser, option: str, path: str | Path) -> Path:
    """``path`` as a file the command may write, or ``ap.error`` naming ``option``: not a folder
    nor an existing special file (device, FIFO, socket), and a file can be created (tried, then
    removed) in its folder or, where that folder does not exist yet, in its nearest existing
    ancestor (the missing folders are made when writing)."""
    if not str(path).strip():
        ap.error(f"argument {option}: an empty file name")
    out = Path(path)
    if out.is_dir():
        ap.error(f"argument {option}: {str(out)!r} is a folder; give a file name")
    if special_file(out):
        ap.error(
            f"argument {option}: {str(out)!r} exists and is not a regular file (a device, FIFO or socket)"
        )
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        ap.error(f"argument {option}: cannot write {str(out)!r}: {str(parent)!r} is not a folder")
    try:
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{out.name}.", suffix=".probe"):
            pass
    except OSError as e:
        ap.error(f"argument {option}: cannot write in {str(parent)!r} ({e.strerror or e})")
    return out


def interrupted(name: str) -> int:
    """Report a Ctrl-C of ``ihrcf-<name>`` with one line on stderr; :data:`EXIT_INTERRUPTED`."""
    print(f"\nihrcf-{name}: interrupted", file=sys.stderr, flush=True)
    return EXIT_INTERRUPTED


def command_main(name: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate the ``main(argv)`` of the command ``ihrcf-<name>``: Ctrl-C (KeyboardInterrupt)
    ends it with a one-line message on stderr and the exit status :data:`EXIT_INTERRUPTED`, no
    traceback."""

    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(argv: Sequence[str] | None = None) -> int:
            try:
                return main(argv)
            except KeyboardInterrupt:
                return interrupted(name)

        return run

    return wrap


def file_mode(path: str | Path) -> int:
    """The permission bits a file written at ``path`` gets: an existing file's own, else what
    ``open(path, "w")`` gives a new file (0o666 less the process's umask)."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def write_whole(path: str | Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` whole or not at all: through a temporary file beside it,
    renamed onto ``path`` (missing folders are made; an existing special file is refused with
    FileExistsError, never replaced); the temporary file is removed if anything
    fails. The file gets the mode a plain ``open`` would give it (:func:`file_mode`: an existing
    file keeps its own). Returns the path."""
    out = Path(path)
    if special_file(out):  # appeared since the check: never replaced by a file
        raise FileExistsError(
            errno.EEXIST, "exists and is not a regular file (a device, FIFO or socket)", str(out)
        )
    out.parent.mkdir(parents=True, exist_ok=True)
    mode = file_mode(out)
    fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            os.fchmod(f.fileno(), mode)
        os.replace(tmp, out)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return out


__all__ = [
    "MAX_SEED",
    "HelpFormatter",
    "check_output",
    "int_in",
    "interrupted",
    "make_parser",
    "seed_type",
    "special_file",
    "write_whole",
]
