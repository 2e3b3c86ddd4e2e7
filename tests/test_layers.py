"""The layer contract: what each folder of the package may import.

core/ and control/ are pure (numpy, scipy, OpenCV): usable on real drone logs, so no PyBullet and no
Gymnasium. config/ (the backend-neutral configuration) imports only core/ and numpy/scipy/the
standard library. sim/ is PyBullet without Gymnasium. Only envs/ and the layers above it (wrappers/,
experiments/, cli/) know Gymnasium. The array layers, when present, stay off the simulator: tasks/
(pure task rules) imports core/ and config/; fast/ (the compiled backend) imports core/, config/
and tasks/. Checked twice: statically on every import statement of every module (lazy imports
inside functions included), and dynamically by importing the pure layers in a fresh interpreter.
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
#: The command lines and the pieces they share.
_COMMANDS = ("ihrcf_env.cmdline", "ihrcf_env.cli")
#: Layers above the configuration: nothing below them may import these.
_ABOVE_CONFIG = (
    "ihrcf_env.sim",
    "ihrcf_env.envs",
    "ihrcf_env.wrappers",
    "ihrcf_env.vector",
    "ihrcf_env.record",
    "ihrcf_env.mavlink",
    "ihrcf_env.control",
    "ihrcf_env.experiments",
    "ihrcf_env.cmdline",
    "ihrcf_env.cli",
)
FORBIDDEN: dict[str, tuple[str, ...]] = {
    "core": (
        "pybullet",
        "gymnasium",
        "ihrcf_env.config",
        "ihrcf_env.tasks",
        "ihrcf_env.fast",
        *_ABOVE_CONFIG,
        *_LEARNING,
    ),
    "config": ("pybullet", "gymnasium", "ihrcf_env.tasks", "ihrcf_env.fast", *_ABOVE_CONFIG, *_LEARNING),
    "control": (
        "pybullet",
        "gymnasium",
        "ihrcf_env.sim",
        "ihrcf_env.envs",
        "ihrcf_env.wrappers",
        "ihrcf_env.experiments",
        "ihrcf_env.cmdline",
        "ihrcf_env.cli",
        "ihrcf_env.mavlink",
        *_LEARNING,
    ),
    # the task rules: arrays in, arrays out (numpy or jax.numpy), shared by every backend
    "sim": (
        "gymnasium",
        "ihrcf_env.envs",
        "ihrcf_env.wrappers",
        "ihrcf_env.experiments",
        "ihrcf_env.cmdline",
        "ihrcf_env.cli",
        *_LEARNING,
    ),
    "envs": ("ihrcf_env.wrappers", "ihrcf_env.experiments", *_COMMANDS, "ihrcf_env.mavlink", *_LEARNING),
    "wrappers": ("ihrcf_env.experiments", *_COMMANDS, "ihrcf_env.mavlink", *_LEARNING),
    # the vector envs sit at the wrappers' level: envs by id, stepped together
    "vector": ("ihrcf_env.experiments", *_COMMANDS, "ihrcf_env.mavlink", *_LEARNING),
    "experiments": (*_COMMANDS, "ihrcf_env.mavlink", *_LEARNING),
    # the pieces the command lines share (parser, env and policy arguments, the launcher): below
    # record/ and mavlink/, whose commands build on them, and below cli/
    "cmdline": (
        "pybullet",
        "ihrcf_env.sim",
        "ihrcf_env.cli",
        "ihrcf_env.record",
        "ihrcf_env.mavlink",
        *_LEARNING,
    ),
    # recordings sit on the Gymnasium API and the wrappers' public accessors, never the simulator;
    # its command (record/command.py) builds on cmdline/, never on cli/
    "record": ("pybullet", "ihrcf_env.sim", "ihrcf_env.mavlink", "ihrcf_env.cli", *_LEARNING),
    # the MAVLink vehicle (a face that runs an env, beside record/): envs, wrappers and core; its
    # command (mavlink/command.py) builds on cmdline/'s env arguments, never on cli/
    "mavlink": (
        "pybullet",
        "ihrcf_env.sim",
        "ihrcf_env.experiments",
        "ihrcf_env.record",
        "ihrcf_env.cmdline.episode_args",
        "ihrcf_env.cli",
        *_LEARNING,
    ),
    # learning glue (SB3 / RLlib) sits on the Gymnasium API: envs by id, never the simulator
    "rl": ("pybullet", "ihrcf_env.sim", "ihrcf_env.experiments", *_COMMANDS, "ihrcf_env.mavlink"),
    # the array layers (checked when their folders exist): pure rules, and the compiled backend
    "tasks": ("pybullet", "gymnasium", "ihrcf_env.fast", *_ABOVE_CONFIG, *_LEARNING),
    "fast": ("pybullet", "gymnasium", *_ABOVE_CONFIG, *_LEARNING),
}
#: Layers checked only when their folder exists.
OPTIONAL_LAYERS = ("tasks", "fast")
#: What the pure layers may import at all: the standard library, these packages, and these
#: ihrcf_env modules (the package root is above every layer: its version is ``ihrcf_env._version``).
#: ``ihrcf_env._components`` is the slot where the package root registers the simulator's checks of
#: the options naming user components (sensors, noise models, faults); like ``_version`` it imports
#: nothing of the package (:func:`test_leaf_modules_import_nothing_of_the_package`).
ALLOWED: dict[str, tuple[str, ...]] = {
    "core": ("numpy", "scipy", "cv2", "threadpoolctl", "ihrcf_env.core", "ihrcf_env._version"),
    "config": (
        "numpy",
        "scipy",
        "ihrcf_env.core",
        "ihrcf_env.config",
        "ihrcf_env._version",
        "ihrcf_env._components",
    ),
}
#: Modules at the package root that every layer may import: they import nothing of the package.
LEAF_MODULES = ("_version", "_components")
#: Lazy imports (inside functions) a layer may make of a layer above it: none. core/ and config/
#: import nothing upward, at the top of a module or inside a function.
LAZY_EXCEPTIONS: dict[str, tuple[str, ...]] = {}


def _layers() -> list[str]:
    return sorted(k for k in FORBIDDEN if k not in OPTIONAL_LAYERS or (PKG / k).is_dir())


def _imports(path: Path, top_level_only: bool = False) -> set[str]:
    """The module names ``path`` imports (``from m import a`` gives ``m`` and ``m.a``); with
    ``top_level_only``, those of the module's own statements, not inside functions or classes."""
    tree = ast.parse(path.read_text(), str(path))
    nodes = ast.iter_child_nodes(tree) if top_level_only else ast.walk(tree)
    names: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.If):  # ``if TYPE_CHECKING:`` blocks at the top level
            for child in ast.walk(node):
                names |= _import_names(child)
        names |= _import_names(node)
    return names


def _import_names(node: ast.AST) -> set[str]:
    if isinstance(node, ast.Import):
        return {a.name for a in node.names}
    if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
        return {node.module, *(f"{node.module}.{a.name}" for a in node.names)}
    return set()


def _matches(name: str, prefixes: tuple[str, ...]) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _violations(layer: str) -> list[str]:
    bad = []
    lazy_ok = LAZY_EXCEPTIONS.get(layer, ())
    for f in sorted((PKG / layer).rglob("*.py")):
        top = _imports(f, top_level_only=True)
        for name in _imports(f):
            if _matches(name, lazy_ok) and name not in top:
                continue
            if _matches(name, FORBIDDEN[layer]):
                bad.append(f"{f.relative_to(PKG)} imports {name}")
    return bad


@pytest.mark.parametrize("layer", _layers())
def test_layer_imports(layer: str) -> None:
    assert (PKG / layer).is_dir(), f"layer folder {layer}/ is missing"
    assert _violations(layer) == []


def _modules(*layers: str) -> list[str]:
    return sorted(
        "ihrcf_env." + ".".join(f.relative_to(PKG).with_suffix("").parts).removesuffix(".__init__")
        for layer in layers
        for f in (PKG / layer).rglob("*.py")
    )


@pytest.mark.parametrize("layer", sorted(ALLOWED))
def test_pure_layers_import_only_what_is_below_them(layer: str) -> None:
    """core/ and config/ import the standard library, their allowed packages and the layers below
    them, nothing else (the package root included: it registers the Gymnasium envs)."""
    bad = []
    lazy_ok = LAZY_EXCEPTIONS.get(layer, ())
    for f in sorted((PKG / layer).rglob("*.py")):
        top = _imports(f, top_level_only=True)
        for name in _imports(f):
            root = name.split(".")[0]
            if root == "__future__" or (root in sys.stdlib_module_names and root != "ihrcf_env"):
                continue
            if _matches(name, ALLOWED[layer]) or (_matches(name, lazy_ok) and name not in top):
                continue
            bad.append(f"{f.relative_to(PKG)} imports {name}")
    assert bad == []


_DYNAMIC = ("import_module", "__import__")


def _dynamic_imports(path: Path) -> set[str]:
    """Names given as constants to ``importlib.import_module`` / ``__import__`` in ``path``."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if called in _DYNAMIC and isinstance(node.args[0].value, str):
                out.add(node.args[0].value)
    return out


@pytest.mark.parametrize("module", _modules("core", "config"))
def test_each_pure_module_imports_neither_pybullet_nor_gymnasium(module: str) -> None:
    """Each of core's and config's own modules: no import of PyBullet or Gymnasium anywhere in it
    (inside functions too, nor by name through importlib)."""
    path = PKG.joinpath(*module.split(".")[1:])
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    names = _imports(path) | _dynamic_imports(path)
    assert [n for n in names if _matches(n, ("pybullet", "gymnasium"))] == []


def test_contract_catches_a_violation(tmp_path: Path) -> None:
    f = tmp_path / "m.py"
    f.write_text("def g():\n    import pybullet as p\n    from gymnasium import spaces\n")
    assert {"pybullet", "gymnasium", "gymnasium.spaces"} <= _imports(f)


def test_pure_layers_do_not_load_pybullet_or_gymnasium_at_run_time() -> None:
    """Importing every module of core/, control/ and config/ in a fresh interpreter loads no
    PyBullet, and no Gymnasium module beyond those the package root loads to register its ids."""
    mods = _modules("core", "control", "config", "tasks")
    code = (
        "import sys, importlib\n"
        "def loaded(): return {k for k in sys.modules if k.split('.')[0] in ('pybullet', 'gymnasium')}\n"
        "import ihrcf_env\n"
        "before = loaded()\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        "print(sorted(loaded() - before))\n"
        "print('pybullet' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    added, pybullet = out.stdout.splitlines()
    assert added == "[]", added
    assert pybullet == "False"


def test_the_layer_contract_has_no_import_of_the_package_root() -> None:
    """core/ and config/ never import the package root (``from ihrcf_env import ...``): it registers
    the Gymnasium envs. The version is ``ihrcf_env._version``."""
    bad = [
        f"{f.relative_to(PKG)}"
        for layer in ("core", "config")
        for f in (PKG / layer).rglob("*.py")
        for node in ast.walk(ast.parse(f.read_text()))
        if isinstance(node, ast.ImportFrom)
        and node.module == "ihrcf_env"
        or isinstance(node, ast.Import)
        and any(a.name == "ihrcf_env" for a in node.names)
    ]
    assert bad == []


def test_every_package_is_installed() -> None:
    """pyproject.toml lists its packages one by one: a new sub-package missing there would work in
    an editable install and be absent from a real one."""
    import tomllib

    root = Path(__file__).resolve().parents[1]
    listed = set(tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(root).parts) for p in (root / "ihrcf_env").rglob("__init__.py")}
    assert found - listed == set()


def test_leaf_modules_import_nothing_of_the_package() -> None:
    """``ihrcf_env._version`` and ``ihrcf_env._components`` sit below every layer."""
    for name in LEAF_MODULES:
        names = _imports(PKG / f"{name}.py") | _dynamic_imports(PKG / f"{name}.py")
        assert [n for n in names if _matches(n, ("ihrcf_env",))] == [], name


#: The package root's ``python -m`` launchers (``python -m ihrcf_env.evaluate``, ...): the
#: ``python -m`` names of the commands in cli/, at the root (above every layer). Each runs
#: :func:`ihrcf_env.cli.launch.launch` under ``if __name__ == "__main__"`` and nothing else; no module
#: imports them. They are the only modules outside cli/ that import it.
ROOT_LAUNCHERS = ("benchmark.py", "calibrate.py", "evaluate.py", "fit_detector.py")
#: Packages whose command lives in the package (``<pkg>/command.py``), run by ``python -m
#: ihrcf_env.<pkg>`` through ``<pkg>/__main__.py`` without cli/.
PACKAGE_COMMANDS = ("mavlink", "record")


def _library_files() -> list[Path]:
    return sorted(
        f
        for f in PKG.rglob("*.py")
        if f.relative_to(PKG).parts[0] != "cli" and f.relative_to(PKG).as_posix() not in ROOT_LAUNCHERS
    )


def test_no_library_module_imports_the_command_lines() -> None:
    """The command lines import the library, never the reverse: no module outside cli/ imports
    ``ihrcf_env.cli`` (at the top, lazily, or by name through importlib), but the package root's
    ``python -m`` launchers; the ``python -m`` launchers of record/ and mavlink/ included."""
    bad = []
    for f in _library_files():
        rel = f.relative_to(PKG).as_posix()
        names = _imports(f) | _dynamic_imports(f)
        bad += [f"{rel} imports {n}" for n in sorted(names) if _matches(n, ("ihrcf_env.cli",))]
    assert bad == []
    assert {f"{p}/__main__.py" for p in PACKAGE_COMMANDS} <= {
        f.relative_to(PKG).as_posix() for f in _library_files()
    }


def test_the_check_sees_an_import_of_the_command_lines(tmp_path: Path) -> None:
    """What :func:`test_no_library_module_imports_the_command_lines` reads: a launcher of the old
    form (``from ihrcf_env.cli.launch import launch``) and a lazy import by name are both seen."""
    f = tmp_path / "__main__.py"
    f.write_text(
        "from ihrcf_env.cli.launch import launch\n"
        "def g():\n    import importlib\n    return importlib.import_module('ihrcf_env.cli.record')\n"
    )
    names = _imports(f) | _dynamic_imports(f)
    assert {"ihrcf_env.cli.launch", "ihrcf_env.cli.record"} <= names


def _launcher_body(path: Path) -> list[ast.stmt]:
    tree = ast.parse(path.read_text())
    return [n for n in tree.body if not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))]


def _importers(module: str) -> list[str]:
    return [
        f.relative_to(PKG).as_posix()
        for f in PKG.rglob("*.py")
        if module in _imports(f) or (module.endswith(".__main__") and module in _dynamic_imports(f))
    ]


@pytest.mark.parametrize("launcher", ROOT_LAUNCHERS)
def test_root_launchers_are_only_launchers(launcher: str) -> None:
    """A root launcher imports only :mod:`ihrcf_env.cli.launch` and calls it under ``__main__``; no
    module imports a launcher."""
    body = _launcher_body(PKG / launcher)
    assert [ast.unparse(n) for n in body[:-1]] == ["from ihrcf_env.cli.launch import launch"]
    assert isinstance(body[-1], ast.If) and ast.unparse(body[-1].test) == "__name__ == '__main__'"
    assert _importers("ihrcf_env." + launcher.removesuffix(".py")) == []


@pytest.mark.parametrize("package", PACKAGE_COMMANDS)
def test_package_launchers_run_their_own_command(package: str) -> None:
    """``<pkg>/__main__.py`` imports only :func:`ihrcf_env.cmdline.launch.run_command` and runs
    ``ihrcf_env.<pkg>.command`` with it under ``__main__``; the console script runs the same module;
    nothing imports the launcher, and the package does not import its command."""
    from ihrcf_env.cli import COMMANDS

    body = _launcher_body(PKG / package / "__main__.py")
    assert [ast.unparse(n) for n in body[:-1]] == ["from ihrcf_env.cmdline.launch import run_command"]
    assert isinstance(body[-1], ast.If) and ast.unparse(body[-1].test) == "__name__ == '__main__'"
    call = ast.unparse(body[-1].body[0])
    assert call == f"raise SystemExit(run_command({package!r}, 'ihrcf_env.{package}.command'))"
    assert COMMANDS[package] == f"ihrcf_env.{package}.command"
    assert _importers(f"ihrcf_env.{package}.__main__") == []
    assert not any(
        _matches(n, (f"ihrcf_env.{package}.command",)) for n in _imports(PKG / package / "__init__.py")
    )


def test_command_modules_form_no_cycle() -> None:
    """record's command builds on the shared episode arguments (:mod:`ihrcf_env.cmdline`);
    cli/evaluate does not import it (its ``--record`` uses :func:`ihrcf_env.record.record_failures`),
    and cmdline/ imports no command."""
    assert not any(_matches(n, ("ihrcf_env.record.command",)) for n in _imports(PKG / "cli" / "evaluate.py"))


def test_contract_catches_a_lazy_upward_import_of_config(tmp_path: Path) -> None:
    """The check of config/ reads imports inside functions (the registry was once imported so)."""
    f = tmp_path / "m.py"
    f.write_text("def g():\n    import ihrcf_env.sim.registry as registry\n    return registry\n")
    names = _imports(f)
    assert "ihrcf_env.sim.registry" in names and _matches("ihrcf_env.sim.registry", FORBIDDEN["config"])


def test_config_checks_components_through_the_slot_the_root_fills() -> None:
    """config/ reaches the simulator's registries only through ``ihrcf_env._components``, which the
    package root fills: a level's faults resolve from config alone, in a fresh interpreter."""
    code = (
        "import sys\n"
        "from ihrcf_env.config.make import make_config\n"
        "print('ihrcf_env.sim.registry' in sys.modules)\n"
        "c = make_config(task='landing-v2', level='rough', raw=True, camera_model='projected',"
        " camera_output='corners')\n"
        "print(sorted(name for name, _ in c.world.faults))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, faults = out.stdout.splitlines()
    assert before == "False"  # importing config loads no simulator
    assert "camera_dropout" in faults
