"""Progress output: a bar only on a terminal; plain lines in a log instead of nothing."""

from __future__ import annotations

import io

from ihrcf_env.experiments.progress import Progress, is_terminal


def test_plain_lines_when_not_a_terminal() -> None:
    log = io.StringIO()
    assert not is_terminal(log)
    with Progress(10, "frames", stream=log, every_s=1e-9) as bar:
        for k in range(10):
            bar.update(k + 1, "x")
    lines = log.getvalue().splitlines()
    assert lines[0].startswith("frames: 1/10 (10 %), ") and lines[-1].startswith("frames: 10/10 (100 %), ")
    assert "\r" not in log.getvalue() and all(line.endswith(", x") for line in lines)


def test_lines_are_spaced_in_time_and_the_end_is_printed() -> None:
    log = io.StringIO()
    bar = Progress(1000, "steps", stream=log, every_s=3600.0)
    for _ in range(1000):
        bar.advance()
    bar.close()
    bar.close()
    assert log.getvalue().splitlines() == [log.getvalue().splitlines()[0]]
    assert log.getvalue().startswith("steps: 1000/1000 (100 %)")


def test_a_bar_on_a_terminal() -> None:
    tty = io.StringIO()
    with Progress(5, "views", stream=tty, terminal=True) as bar:
        bar.update(5)
    assert "\r" in tty.getvalue() and "5/5" in tty.getvalue()
