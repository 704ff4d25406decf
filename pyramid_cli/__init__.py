"""Pyramid filters based on bilinear interpolation (Kraus & Strengert, GRAPP 2007).

``import pyramid_cli as pyr`` gives the Python API (:mod:`pyramid_cli.api`):
``pyr.apply``, ``pyr.blur``, ``pyr.pyramid``, ``pyr.laplacian``, ``pyr.collapse``,
``pyr.mipmap``, ``pyr.fill``, ``pyr.blend``, ``pyr.read_image``, ``pyr.write_image``, ``pyr.process_files`` and
``pyr.Session``. They load on first use, so importing the core (parser, algebra,
planner) pulls in no third-party module.
"""

from __future__ import annotations

from pyramid_cli.core.version import __version__ as __version__

_API = ("apply", "blur", "pyramid", "laplacian", "collapse", "mipmap", "read_image", "write_image",
        "process_files", "as_pixels", "Session", "Work", "Filter", "Blur", "SigmaBlur", "Levels", "Laplacian",
        "Collapse", "fill", "blend", "Bands")
__all__ = list(_API)


def __getattr__(name: str):
    if name in _API:
        from pyramid_cli import api

        return getattr(api, name)
    raise AttributeError(f"module 'pyramid_cli' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
