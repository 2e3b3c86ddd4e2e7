"""Command lines, one module each, installed as console scripts and runnable with ``python -m``:

* ``ihrcf-benchmark`` / ``python -m ihrcf_env.benchmark``: :mod:`ihrcf_env.cli.benchmark`;
* ``ihrcf-calibrate`` / ``python -m ihrcf_env.calibrate``: :mod:`ihrcf_env.cli.calibrate`;
* ``ihrcf-evaluate`` / ``python -m ihrcf_env.evaluate``: :mod:`ihrcf_env.cli.evaluate`;
* ``ihrcf-fit-detector`` / ``python -m ihrcf_env.fit_detector``: :mod:`ihrcf_env.cli.fit_detector`;
* ``ihrcf-mavlink`` / ``python -m ihrcf_env.mavlink``: :mod:`ihrcf_env.cli.mavlink`;
* ``ihrcf-record`` / ``python -m ihrcf_env.record``: :mod:`ihrcf_env.cli.record`.

What they share (parser, argument types, output checks): :mod:`ihrcf_env.cli.common`. The console
scripts and the ``python -m`` launchers start them through :mod:`ihrcf_env.cli.launch` (a Ctrl-C
during start-up exits 130). The command lines import the library, never the reverse.
"""

#: Command name -> module under ihrcf_env.cli (the console script is ``ihrcf-<name>``).
COMMANDS = {
    "benchmark": "benchmark",
    "calibrate": "calibrate",
    "evaluate": "evaluate",
    "fit-detector": "fit_detector",
    "mavlink": "mavlink",
    "record": "record",
}

__all__ = [
    "COMMANDS",
]
