"""The JAX kernels' tests run in float64: x64 is switched on when this package's tests are
collected (it stays on for the rest of the process, which the other tests never notice: they do
not use JAX). Compiled functions go to the package's persistent compilation cache
(:mod:`ihrcf_env.fast.cache`), so a later run loads what an earlier one compiled."""

from __future__ import annotations

import pytest

jax = pytest.importorskip("jax")
jax.config.update("jax_enable_x64", True)

from ihrcf_env.fast.cache import enable_compilation_cache  # noqa: E402

enable_compilation_cache()
