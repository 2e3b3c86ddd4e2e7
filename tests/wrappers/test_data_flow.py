"""Data flows forward: the wrappers read sensor data from the observation only. From ``info`` they
read ground truth alone (the privileged block, the ground-truth pose), and they reach the base env
only for its declared configuration (``base_config``). Checked on the source, statically."""

from __future__ import annotations

import ast
from pathlib import Path

import ihrcf_env

WRAPPERS = Path(ihrcf_env.__file__).resolve().parent / "wrappers"
#: Ground truth the env always puts in ``info`` (see DeckLandingEnv).
GROUND_TRUTH_KEYS = {
    "deck_position_body",
    "deck_euler_body",
    "deck_rotation_body",
    "drone_quaternion_world",
    "relative_velocity",
    "wind_velocity",
}


def _reads(tree: ast.AST) -> list[tuple[str, int]]:
    """String keys read from a variable named ``info`` (``info["k"]``, ``info.get("k")``)."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "info":
            if isinstance(node.ctx, ast.Load) and isinstance(node.slice, ast.Constant):
                out.append((str(node.slice.value), node.lineno))
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "get"
            and isinstance(node.func.value, ast.Name)
            and node.func.value.id == "info"
        ):
            key = node.args[0].value if node.args and isinstance(node.args[0], ast.Constant) else "?"
            out.append((str(key), node.lineno))
    return out


def test_wrappers_read_only_ground_truth_from_info() -> None:
    for path in WRAPPERS.glob("*.py"):
        for key, line in _reads(ast.parse(path.read_text())):
            assert key in GROUND_TRUTH_KEYS, (
                f"{path.name}:{line} reads info[{key!r}]: sensor data belongs in obs"
            )


def test_wrappers_reach_the_base_env_only_for_its_config() -> None:
    for path in WRAPPERS.glob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and node.attr in ("world", "wind", "settings", "task"):
                owner = node.value
                is_env = (isinstance(owner, ast.Name) and owner.id in ("env", "base")) or (
                    isinstance(owner, ast.Attribute) and owner.attr in ("unwrapped", "env")
                )
                assert not is_env, f"{path.name}:{node.lineno} reads .{node.attr} of an env"
        uses = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "unwrapped"]
        if uses:
            # the observation wrappers read the task's config
            allowed = {"estimates.py": "base_config"}
            assert path.name in allowed, f"{path.name} uses env.unwrapped at lines {uses}"
            func = next(
                n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == allowed[path.name]
            )
            assert all(func.lineno <= u <= func.end_lineno for u in uses)  # type: ignore[operator]
