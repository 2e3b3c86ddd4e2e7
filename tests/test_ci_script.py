"""``.ci/run`` runs the default suite again on each newer Python the machine provides (pyenv's
versions or ``pythonX.Y`` on PATH) and skips, with a printed line, a version that is absent."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

CI = Path(__file__).resolve().parents[1] / ".ci" / "run"

pytestmark = pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")


def _newer_python(version: str, pyenv_root: Path, path: str) -> str:
    """What the script's ``newer_python`` function finds for ``version`` (``path``: the PATH)."""
    text = CI.read_text()
    function = re.search(r"^newer_python\(\) \{.*?^\}", text, re.S | re.M)
    assert function is not None
    script = f"set -euo pipefail\n{function.group(0)}\nnewer_python {version}\n"
    env = {"PYENV_ROOT": str(pyenv_root), "PATH": path, "HOME": str(pyenv_root)}
    bash = shutil.which("bash")
    assert bash is not None
    run = subprocess.run([bash, "-c", script], capture_output=True, text=True, env=env, check=True)
    return run.stdout.strip()


def test_the_newest_pyenv_interpreter_of_a_version_is_found(tmp_path: Path) -> None:
    for v in ("3.12.1", "3.12.10", "3.13.0"):
        exe = tmp_path / "versions" / v / "bin" / "python3"
        exe.parent.mkdir(parents=True)
        exe.write_text("")
    empty = tmp_path / "bin"  # the tools the function uses, and no python3.X
    empty.mkdir()
    for tool in ("ls", "sort", "tail"):
        found = shutil.which(tool)
        assert found is not None
        (empty / tool).symlink_to(found)
    assert _newer_python("3.12", tmp_path, str(empty)) == str(tmp_path / "versions/3.12.10/bin/python3")
    assert _newer_python("3.13", tmp_path, str(empty)) == str(tmp_path / "versions/3.13.0/bin/python3")
    assert _newer_python("3.14", tmp_path, str(empty)) == ""  # absent: nothing, and no failure


def test_every_newer_version_runs_the_suite_or_says_it_is_skipped() -> None:
    text = CI.read_text()
    loop = re.search(r"^for version in ([^\n]*); do$(.*?)^done$", text, re.S | re.M)
    assert loop is not None
    assert loop.group(1).split() == ["3.12", "3.13"]
    body = loop.group(2)
    assert "its suite is skipped" in body and "continue" in body
    assert "installs[$version]=$!" in body  # each version found is installed (in the background)
    run = re.search(r'^for version in "\$\{!installs\[@\]\}"; do$(.*?)^done$', text, re.S | re.M)
    assert run is not None  # then every installed version runs the default suite
    assert 'wait "${installs[$version]}"' in run.group(1)
    assert '.venv-py$version/bin/pytest"' in run.group(1)


def test_the_background_installs_build_from_their_own_copies() -> None:
    """Every install started in the background builds from its own copy of the tree: pip builds the
    package in its source folder, and two builds of one folder at once collide. Only the README's
    install (in the foreground) builds in the checkout itself."""
    text = CI.read_text()
    background = [line for line in text.splitlines() if "/bin/pip" in line and "install" in line]
    in_tree = [line for line in background if '".[' in line]
    assert len(in_tree) == 1 and "&&" in in_tree[0] and in_tree[0].startswith("python3 -m venv .venv &&")
    copied = [line for line in background if "_source" in line]
    assert len(copied) == 2 and all("[" in line for line in copied), copied  # newer Pythons, [rl]
    function = re.search(r"^private_source\(\) \{.*?^\}", text, re.S | re.M)
    assert function is not None and "mktemp -d" in function.group(0)


def test_a_copy_of_the_tree_leaves_out_environments_and_build_output(tmp_path: Path) -> None:
    """What ``private_source`` copies: the tree without .git, the virtual environments, build/ and
    egg-info, into a new folder each call."""
    text = CI.read_text()
    function = re.search(r"^private_source\(\) \{.*?^\}", text, re.S | re.M)
    assert function is not None
    tree = tmp_path / "tree"
    for rel in ("pyproject.toml", "ihrcf_env/__init__.py", ".venv/bin/python", ".venv-rl/x", "build/lib/y",
                "ihrcf_env.egg-info/PKG-INFO", ".git/HEAD"):  # fmt: skip
        (tree / rel).parent.mkdir(parents=True, exist_ok=True)
        (tree / rel).write_text("x")
    bash = shutil.which("bash")
    assert bash is not None
    script = f"set -euo pipefail\n{function.group(0)}\nprivate_source\nprivate_source\n"
    env = {"PATH": "/usr/bin:/bin", "TMPDIR": str(tmp_path)}
    run = subprocess.run([bash, "-c", script], cwd=tree, capture_output=True, text=True, env=env, check=True)
    first, second = (Path(line) for line in run.stdout.split())
    assert first != second
    copied = sorted(p.relative_to(first).as_posix() for p in first.rglob("*") if p.is_file())
    assert copied == ["ihrcf_env/__init__.py", "pyproject.toml"]
