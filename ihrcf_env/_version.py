"""The package version (a module of its own, so every layer can read it without importing the
package root)."""

__all__ = ["__version__"]

__version__ = "0.3.0"
