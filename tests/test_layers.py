"""The layer contract: what each folder of the package may import.

core/ and control/ are pure (numpy, scipy, OpenCV): usable on real drone logs, so no PyBullet and no
Gymnasium. sim/ is PyBullet without Gymnasium. Only envs/ and the layers above it (wrappers/,
experiments/, cli/) know Gymnasium. Checked twice: statically on every import statement of every
module (lazy imports inside functions included), and dynamically by importing the pure layers in a
fresh interpreter.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import ihrcf_env

PKG = Path(ihrcf_env.__file__).resolve().parent

# layer -> top-level modules / ihrcf_env sub-packages it must not import
_LEARNING = ("ihrcf_env.rl", "torch", "stable_baselines3", "ray")
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "core": (
        "pybullet",
        "gymnasium",
        "ihrcf_env.sim",
        "ihrcf_env.envs",
        "ihrcf_env.wrappers",
        "ihrcf_env.control",
        "ihrcf_env.experiments",
        "ihrcf_env.cli",
        *_LEARNING,
    ),
    "control": (
        "pybullet",
        "gymnasium",
        "ihrcf_env.sim",
        "ihrcf_env.envs",
        "ihrcf_env.wrappers",
        "ihrcf_env.experiments",
        "ihrcf_env.cli",
        *_LEARNING,
    ),
    "sim": (
        "gymnasium",
        "ihrcf_env.envs",
        "ihrcf_env.wrappers",
        "ihrcf_env.experiments",
        "ihrcf_env.cli",
        *_LEARNING,
    ),
    "envs": ("ihrcf_env.wrappers", "ihrcf_env.experiments", "ihrcf_env.cli", *_LEARNING),
    "wrappers": ("ihrcf_env.experiments", "ihrcf_env.cli", *_LEARNING),
    "experiments": ("ihrcf_env.cli", *_LEARNING),
    # recordings sit on the Gymnasium API and the wrappers' public accessors, never the simulator
    "record": ("pybullet", "ihrcf_env.sim", *_LEARNING),
    # learning glue (SB3 / RLlib) sits on the Gymnasium API: envs by id, never the simulator
    "rl": ("pybullet", "ihrcf_env.sim", "ihrcf_env.experiments", "ihrcf_env.cli"),
}


def _imports(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def _violations(layer: str) -> list[str]:
    bad = []
    for f in sorted((PKG / layer).rglob("*.py")):
        for name in _imports(f):
            for forbidden in FORBIDDEN[layer]:
                if name == forbidden or name.startswith(forbidden + "."):
                    bad.append(f"{f.relative_to(PKG)} imports {name}")
    return bad


@pytest.mark.parametrize("layer", sorted(FORBIDDEN))
def test_layer_imports(layer: str) -> None:
    assert (PKG / layer).is_dir(), f"layer folder {layer}/ is missing"
    assert _violations(layer) == []


def test_contract_catches_a_violation(tmp_path: Path) -> None:
    f = tmp_path / "m.py"
    f.write_text("def g():\n    import pybullet as p\n    from gymnasium import spaces\n")
    assert {"pybullet", "gymnasium", "gymnasium.spaces"} <= _imports(f)


def test_pure_layers_do_not_load_pybullet_or_gymnasium_at_run_time() -> None:
    mods = sorted(
        "ihrcf_env." + ".".join(f.relative_to(PKG).with_suffix("").parts).removesuffix(".__init__")
        for layer in ("core", "control")
        for f in (PKG / layer).rglob("*.py")
    )
    code = (
        "import sys, importlib\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        "print(sorted(k for k in ('pybullet', 'gymnasium') if k in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    # importing the package root registers the envs with gymnasium; the pure modules add nothing more
    assert "pybullet" not in out.stdout, out.stdout


def test_every_package_is_installed() -> None:
    """pyproject.toml lists its packages one by one: a new sub-package missing there would work in
    an editable install and be absent from a real one."""
    import tomllib

    root = Path(__file__).resolve().parents[1]
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(root).parts) for p in (root / "ihrcf_env").rglob("__init__.py")}
    assert found - listed == set()
