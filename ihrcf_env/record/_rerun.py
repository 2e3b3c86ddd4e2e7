"""The optional Rerun dependency, imported only when a recording is made."""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = ["INSTALL_HINT", "RerunMissingError", "import_rerun"]

#: The command that installs the viewer extra.
INSTALL_HINT = 'pip install "ihrcf-env[viewer]"'


class RerunMissingError(ImportError):
    """A recording was asked for but the Rerun SDK (``rerun-sdk``) is not installed."""


def import_rerun() -> ModuleType:
    """The ``rerun`` module, or :class:`RerunMissingError` saying how to install it."""
    try:
        return importlib.import_module("rerun")
    except ImportError as e:
        raise RerunMissingError(
            f"recording needs the Rerun SDK (rerun-sdk), which is not installed: {INSTALL_HINT}"
        ) from e
