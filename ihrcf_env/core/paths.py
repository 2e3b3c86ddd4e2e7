"""Where the shipped assets live (pure Python; no simulator import)."""

from __future__ import annotations

import importlib.resources
from pathlib import Path


def assets_dir() -> Path:
    """Directory of the shipped assets (URDF, meshes, calibration file).

    An installed package carries them as the ``ihrcf_env.assets`` package (mapped from the
    project's top-level ``assets/``); in a plain source checkout used without installing, the
    top-level ``assets/`` next to the ``ihrcf_env/`` folder is used.
    """
    try:
        d = Path(str(importlib.resources.files("ihrcf_env.assets")))
        if d.is_dir():
            return d
    except ModuleNotFoundError:
        pass
    d = Path(__file__).resolve().parents[2] / "assets"  # ihrcf_env/core/paths.py -> repo root
    if d.is_dir():
        return d
    raise FileNotFoundError("ihrcf_env assets not found: reinstall the package (pip install .)")


def asset_path(name: str) -> Path:
    """Absolute path of a shipped asset file; FileNotFoundError naming it if missing."""
    p = assets_dir() / name
    if not p.is_file():
        raise FileNotFoundError(f"asset {name!r} not found at {p}; is the package installed completely?")
    return p


__all__ = [
    "asset_path",
    "assets_dir",
]
