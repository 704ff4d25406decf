"""The GL executor: plans as hardware bilinear texture passes on a headless EGL context.

:mod:`.context` makes the context (and knows the software renderers), :mod:`.shaders`
writes the GLSL of each pass shape from the templates beside it, and :mod:`.executor`
runs plans (:class:`GLExecutor`). moderngl is imported only in this package, and only
when a context is made.
"""

from __future__ import annotations

from importlib import import_module

from pyramid_cli.exec.gl.context import INSTALL_HINT, SOFTWARE_RENDERERS, available, is_software_renderer
from pyramid_cli.exec.gl.textures import texture_size

_LAZY = {"GLExecutor": "pyramid_cli.exec.gl.executor"}


def __getattr__(name: str):
    """The executor's names, imported on first use: a run on the CPU executor asks this package whether the
    renderer is a software one (:mod:`.context`) and never loads the executor and its shader generator."""
    home = _LAZY.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(home), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})

__all__ = ["GLExecutor", "available", "texture_size", "INSTALL_HINT", "SOFTWARE_RENDERERS", "is_software_renderer"]
