"""The persistent compilation cache's folder: from IHRCF_JAX_CACHE, off with "0"."""

from __future__ import annotations

from pathlib import Path

import pytest

from ihrcf_env.fast.cache import CACHE_ENV, cache_dir


def test_cache_dir_follows_the_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "c"))
    assert cache_dir() == tmp_path / "c"
    monkeypatch.setenv(CACHE_ENV, "0")
    assert cache_dir() is None
    monkeypatch.delenv(CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert cache_dir() == tmp_path / "ihrcf_env" / "jax"


def test_the_tests_use_a_persistent_cache() -> None:
    jax = pytest.importorskip("jax")
    assert jax.config.jax_compilation_cache_dir
