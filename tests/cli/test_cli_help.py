"""Every command line: a console script on ``ihrcf_env.cli.launch`` (which runs
``ihrcf_env.cli.<name>.main``), a ``python -m`` launcher, and a plain ``--help`` that names the
program and states every default."""

from __future__ import annotations

import argparse
import importlib
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from ihrcf_env.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[2]


def _parser(module: str) -> argparse.ArgumentParser:
    return importlib.import_module(module).build_parser()


def test_every_command_is_a_console_script_on_cli() -> None:
    from ihrcf_env.cli import launch
    from ihrcf_env.cmdline.launch import run_command

    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    funcs = {name: name.replace("-", "_") for name in COMMANDS}
    assert scripts == {f"ihrcf-{name}": f"ihrcf_env.cli.launch:{f}" for name, f in funcs.items()}
    for name, module in COMMANDS.items():
        assert callable(importlib.import_module(module).main)
        assert callable(getattr(launch, funcs[name]))
        if module.startswith("ihrcf_env.cli."):  # python -m ihrcf_env.<name>: the root's launcher
            assert importlib.import_module(f"ihrcf_env.{funcs[name]}").launch is launch.launch
        else:  # python -m ihrcf_env.<package>: the package's own launcher, beside its command
            package = module.removesuffix(".command")
            assert importlib.import_module(f"{package}.__main__").run_command is run_command


@pytest.mark.parametrize(("name", "module"), sorted(COMMANDS.items()))
def test_help_is_plain_names_the_program_and_states_every_default(name: str, module: str) -> None:
    ap = _parser(module)
    text = ap.format_help()
    assert text.startswith(f"usage: ihrcf-{name} "), text[:80]
    for markup in ("``", ":class:", ":func:", ":mod:", ":meth:", ":data:", ":attr:"):
        assert markup not in text, markup
    assert not re.search(r":[a-z]+:`", text)
    formatter = ap.formatter_class(prog=ap.prog)
    for action in ap._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        shown = formatter._get_help_string(action) % {"default": action.default}
        assert "default" in shown or action.required, (action.dest, shown)


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_python_m_help_runs(name: str) -> None:
    run = subprocess.run(
        [sys.executable, "-m", f"ihrcf_env.{name.replace('-', '_')}", "--help"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("usage: ihrcf-"), run.stdout[:80]
    assert "``" not in run.stdout
