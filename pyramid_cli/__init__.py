"""Pyramid filters based on bilinear interpolation (Kraus & Strengert, GRAPP 2007).

``import pyramid_cli as pyr`` gives the Python API (:mod:`pyramid_cli.api`):
``pyr.apply``, ``pyr.reduce``, ``pyr.expand``, ``pyr.blur``, ``pyr.pyramid``, ``pyr.laplacian``,
``pyr.collapse``, ``pyr.mipmap``, ``pyr.tiles``, ``pyr.fill``, ``pyr.blend``, ``pyr.read_image``, ``pyr.write_image``,
``pyr.process_files``, ``pyr.Session``, the job values ``process_files`` takes (``pyr.Blur``, ``pyr.Fill``,
``pyr.TextureLevels``, …) and the warning categories (``pyr.PyramidWarning``, …). They load on first use,
so importing the core (parser, algebra, planner) pulls in no third-party module.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pyramid_cli.core.version import __version__ as __version__

if TYPE_CHECKING:  # what a type checker sees of the names loaded on first use
    from pyramid_cli.api import *  # noqa: F403

_API = ("apply", "reduce", "expand", "blur", "pyramid", "laplacian", "collapse", "mipmap", "read_image",
        "write_image", "process_files", "as_pixels", "Session", "Work", "Filter", "Blur", "SigmaBlur", "Levels",
        "Laplacian", "Collapse", "Fill", "Blend", "TextureLevels", "fill", "blend", "Bands", "Report",
        "PyramidWarning", "MixedLatticeWarning", "MaskWarning", "BackendWarning", "tiles")
__all__ = list(_API)


def __getattr__(name: str) -> object:
    if name in _API:
        from pyramid_cli import api

        return getattr(api, name)
    raise AttributeError(f"module 'pyramid_cli' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_API])
