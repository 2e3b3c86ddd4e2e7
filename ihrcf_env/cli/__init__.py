"""Command lines, installed as console scripts and runnable with ``python -m``:

* ``ihrcf-benchmark`` / ``python -m ihrcf_env.benchmark``: :mod:`ihrcf_env.cli.benchmark`;
* ``ihrcf-calibrate`` / ``python -m ihrcf_env.calibrate``: :mod:`ihrcf_env.cli.calibrate`;
* ``ihrcf-evaluate`` / ``python -m ihrcf_env.evaluate``: :mod:`ihrcf_env.cli.evaluate`;
* ``ihrcf-fit-detector`` / ``python -m ihrcf_env.fit_detector``: :mod:`ihrcf_env.cli.fit_detector`;
* ``ihrcf-mavlink`` / ``python -m ihrcf_env.mavlink``: :mod:`ihrcf_env.mavlink.command`;
* ``ihrcf-record`` / ``python -m ihrcf_env.record``: :mod:`ihrcf_env.record.command`.

The last two live in the package whose face they are, so that its ``python -m`` launcher needs
nothing from here. What the commands share (parser, argument types, the env and policy
arguments): :mod:`ihrcf_env.cmdline`. The console scripts start them through
:mod:`ihrcf_env.cli.launch` (a Ctrl-C during start-up exits 130). The command lines import the
library, never the reverse.
"""

#: Command name -> the module holding its ``main`` (the console script is ``ihrcf-<name>``).
COMMANDS = {
    "benchmark": "ihrcf_env.cli.benchmark",
    "calibrate": "ihrcf_env.cli.calibrate",
    "evaluate": "ihrcf_env.cli.evaluate",
    "fit-detector": "ihrcf_env.cli.fit_detector",
    "mavlink": "ihrcf_env.mavlink.command",
    "record": "ihrcf_env.record.command",
}

__all__ = [
    "COMMANDS",
]
