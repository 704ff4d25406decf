"""The GL executor's EGL context: making one, saying why not, and what its renderer is.

moderngl is imported only inside these functions (and :mod:`pyramid_cli.exec.gl.executor`),
so :mod:`pyramid_cli.exec.session` can ask :func:`is_software_renderer` without loading GL.
"""

from __future__ import annotations

from pyramid_cli.core.errors import BackendError

INSTALL_HINT = ("install the drivers: sudo apt-get install -y libegl1 libgl1 libgl1-mesa-dri libegl-mesa0, "
                "or use --backend cpu")

# GL_RENDERERs of software rasterisers (lower case, matched as substrings): their textures are host memory,
# and the compiled CPU executor is faster than they are (pyramid_cli.exec.session's ``auto``).
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "software rasterizer", "lavapipe")


def is_software_renderer(renderer: str) -> bool:
    """Whether GL_RENDERER ``renderer`` names a software rasteriser (:data:`SOFTWARE_RENDERERS`)."""
    low = renderer.lower()
    return any(name in low for name in SOFTWARE_RENDERERS)


def create_context():
    """A standalone OpenGL 3.3 core context through EGL, or BackendError saying why and how to fix it."""
    try:
        import moderngl
    except ImportError as e:  # pragma: no cover - moderngl is a dependency
        raise BackendError(f"moderngl cannot be imported ({e}); pip install moderngl, or use --backend cpu") from e
    try:
        ctx = moderngl.create_standalone_context(require=330, backend="egl")
    except Exception as e:  # moderngl/glcontext raise plain Exceptions for missing EGL, display, driver
        reason = " ".join(str(e).split()) or type(e).__name__
        raise BackendError(f"no OpenGL context through EGL ({reason}); {INSTALL_HINT}") from e
    return ctx


def available() -> tuple[bool, str]:
    """Can an EGL context be made here? ``(True, renderer)`` or ``(False, reason with the fix)``."""
    try:
        ctx = create_context()
    except BackendError as e:
        return False, e.message
    try:
        with ctx:
            return True, ctx.info["GL_RENDERER"]
    finally:
        ctx.release()


def context_info(ctx) -> dict:
    """What a (current) context says of itself: vendor, renderer, version and GL_MAX_TEXTURE_SIZE."""
    return {
        "vendor": ctx.info["GL_VENDOR"],
        "renderer": ctx.info["GL_RENDERER"],
        "version": ctx.info["GL_VERSION"],
        "version_code": ctx.version_code,
        "max_texture_size": int(ctx.info["GL_MAX_TEXTURE_SIZE"]),
    }


__all__ = ["INSTALL_HINT", "SOFTWARE_RENDERERS", "available", "context_info", "create_context",
           "is_software_renderer"]
