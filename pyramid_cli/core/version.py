"""The package's version, in the lowest layer so that any module may name it (a file's provenance, say)
without importing the top package, which loads the API."""

from __future__ import annotations

__version__ = "0.1.0"  # the same as pyproject.toml's [project] version

__all__ = ["__version__"]
