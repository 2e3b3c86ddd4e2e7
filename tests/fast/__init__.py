"""The JAX kernels' golden tests (a package, so its conftest and modules do not shadow the others)."""
