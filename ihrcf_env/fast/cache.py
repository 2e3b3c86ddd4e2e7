"""JAX's persistent compilation cache for the package's compiled functions.

:func:`enable_compilation_cache` points JAX at a cache folder (``IHRCF_JAX_CACHE``, else
``~/.cache/ihrcf_env/jax``) unless the user configured one, so a configuration compiled once is
loaded from disk by later processes.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CACHE_ENV", "cache_dir", "enable_compilation_cache"]

#: Environment variable naming the cache folder ("" or "0": no persistent cache).
CACHE_ENV = "IHRCF_JAX_CACHE"


def cache_dir() -> Path | None:
    """The folder the cache uses (None: disabled by ``IHRCF_JAX_CACHE=0`` or empty)."""
    value = os.environ.get(CACHE_ENV)
    if value is not None:
        return None if value.strip() in ("", "0") else Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "ihrcf_env" / "jax"


def enable_compilation_cache() -> Path | None:
    """Turn the persistent cache on (once per process; a folder the user set through JAX's own
    ``jax_compilation_cache_dir`` is kept). Returns the folder in use (None: none)."""
    import jax

    current = getattr(jax.config, "jax_compilation_cache_dir", None)
    if current:
        return Path(current)
    folder = cache_dir()
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None  # a read-only home: compile every time rather than fail
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    return folder
