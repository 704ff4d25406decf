"""The GL executor: plans as hardware bilinear texture passes on a headless EGL context.

:mod:`.context` makes the context (and knows the software renderers), :mod:`.shaders`
writes the GLSL of each pass shape from the templates beside it, and :mod:`.executor`
runs plans (:class:`GLExecutor`). moderngl is imported only in this package, and only
when a context is made.
"""

from __future__ import annotations

from pyramid_cli.exec.gl.context import INSTALL_HINT, SOFTWARE_RENDERERS, available, is_software_renderer
from pyramid_cli.exec.gl.executor import GLExecutor, texture_size

__all__ = ["GLExecutor", "available", "texture_size", "INSTALL_HINT", "SOFTWARE_RENDERERS", "is_software_renderer"]
