"""Progress reporting for long runs: a tqdm bar on a terminal, plain lines in a log.

A bar redrawn in place is only readable on a terminal; written to a file or a pipe it is either
suppressed (tqdm's ``disable=None``: nothing for minutes) or a flood of carriage returns. A
:class:`Progress` draws the bar when its stream is a terminal and otherwise prints one plain line
(``label: done/total (pct %), elapsed s``) every ``every_s`` seconds of wall time, and at the end.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from tqdm import tqdm


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is an interactive terminal (False for files, pipes and captured streams)."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(isatty()) if callable(isatty) else False
    except (OSError, ValueError):  # a closed stream
        return False


class Progress:
    """Progress of ``total`` units of work (steps, frames, stages) labelled ``label``.

    Args:
        total: units of work (>= 0).
        label: what is counted, shown first on every line.
        stream: where to write (default ``sys.stderr``).
        every_s: wall seconds between two plain lines when ``stream`` is not a terminal (> 0).
        terminal: force the bar (True) or the plain lines (False); None: ask ``stream``.
        unit: the unit's name for the bar.
    """

    def __init__(
        self,
        total: int,
        label: str,
        stream: TextIO | None = None,
        every_s: float = 5.0,
        terminal: bool | None = None,
        unit: str = "it",
    ) -> None:
        if total < 0:
            raise ValueError(f"total must be >= 0, got {total!r}")
        if not every_s > 0:
            raise ValueError(f"every_s must be > 0 s, got {every_s!r}")
        self.total = int(total)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.every_s = float(every_s)
        self.n = 0
        self.note = ""
        self._t0 = time.perf_counter()
        self._last = self._t0
        self._closed = False
        tty = is_terminal(self.stream) if terminal is None else terminal
        self._bar: tqdm | None = (
            tqdm(total=self.total, desc=label, file=self.stream, unit=unit, dynamic_ncols=True)
            if tty
            else None
        )

    def update(self, done: int, note: str = "") -> None:
        """Set the units done so far (clipped to ``total``) and an optional short note."""
        done = max(0, min(int(done), self.total))
        self.note = note
        if self._bar is not None:
            if note:
                self._bar.set_postfix_str(note, refresh=False)
            self._bar.update(done - self.n)
            self.n = done
            return
        self.n = done
        now = time.perf_counter()
        if now - self._last >= self.every_s:
            self._last = now
            self._line()

    def advance(self, units: int = 1, note: str = "") -> None:
        """Add ``units`` done."""
        self.update(self.n + units, note)

    def _line(self) -> None:
        pct = 100.0 * self.n / self.total if self.total else 100.0
        elapsed = time.perf_counter() - self._t0
        note = f", {self.note}" if self.note else ""
        print(
            f"{self.label}: {self.n}/{self.total} ({pct:.0f} %), {elapsed:.0f} s{note}",
            file=self.stream,
            flush=True,
        )

    def close(self) -> None:
        """Finish: close the bar, or print the last plain line. Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.close()
        else:
            self._line()

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = [
    "Progress",
    "is_terminal",
]
