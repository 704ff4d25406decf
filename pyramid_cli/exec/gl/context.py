"""The GL executor's EGL context: making one, saying why not, and what its renderer is.

moderngl is imported only inside these functions (and :mod:`pyramid_cli.exec.gl.executor`),
so :mod:`pyramid_cli.exec.session` can ask :func:`is_software_renderer` without loading GL.

What a context says of itself (or why none can be made) is the same in every process
until the driver changes, so :func:`machine_gl` keeps it in the cache folder
(:func:`pyramid_cli.core.cache.folder` ``gl``) under :func:`driver_key`: a digest of what
picks and implements EGL here (glvnd's vendor files, the libraries they name, Mesa's
drivers, the environment variables EGL and Mesa read, the GPU device nodes and the host).
``auto`` then decides without opening a context; one is opened only to run on GL.
"""

from __future__ import annotations

import glob
import json
import os
import sysconfig

from pyramid_cli.core import cache
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


# ------------------------------------------------------------ the machine's GL, cached
CACHE_FOLDER = "gl"
CACHE_ENTRY = "machine-{key}.json"  # one entry per driver setting: switching back and forth probes nothing
VENDOR_DIRS = ("/etc/glvnd/egl_vendor.d", "/usr/share/glvnd/egl_vendor.d")
# Environment variables that change which EGL driver loads or how it renders (prefixes).
ENV_PREFIXES = ("__EGL_", "EGL_", "MESA_", "LIBGL_", "GALLIUM_", "LP_", "__GLX_", "NVIDIA_", "CUDA_VISIBLE_DEVICES",
                "LD_LIBRARY_PATH")


def _lib_dirs() -> list[str]:
    """Where the dynamic loader looks for EGL's libraries (LD_LIBRARY_PATH, then the usual system folders)."""
    arch = sysconfig.get_config_var("MULTIARCH") or ""
    dirs = [d for d in os.environ.get("LD_LIBRARY_PATH", "").split(":") if d]
    for base in ("/usr/local/lib", "/usr/lib", "/lib"):
        if arch:
            dirs.append(f"{base}/{arch}")
    return dirs + ["/usr/lib64", "/lib64", "/usr/lib", "/lib"]


def _stat(path: str) -> tuple | None:
    """(real path, size, mtime in ns) of ``path`` (symbolic links followed), or None when it does not exist."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return os.path.realpath(path), st.st_size, st.st_mtime_ns


def _library(name: str, dirs: list[str]) -> tuple | None:
    """The file the loader would open for library ``name`` (absolute, or found in ``dirs``): :func:`_stat`."""
    if os.path.isabs(name):
        return _stat(name)
    for d in dirs:
        hit = _stat(os.path.join(d, name))
        if hit is not None:
            return hit
    return None


def driver_key() -> str:
    """A digest of what decides which EGL driver a context gets here and what it does (see the module).

    Cheap (a few dozen ``stat`` calls, no library loaded): glvnd's vendor files and the libraries they
    name, libEGL itself, Mesa's driver folders and ``libgallium``, the environment variables of
    :data:`ENV_PREFIXES`, the GPU device nodes, the host name (``os.uname``, which ``socket.gethostname`` reads
    too, without importing ``socket``) and the cores. A driver update, a new vendor file or another
    ``MESA_``/``EGL_`` setting gives another key, and the renderer is probed again.
    """
    dirs = _lib_dirs()
    env = sorted((k, v) for k, v in os.environ.items() if k.startswith(ENV_PREFIXES))
    vendor_dirs = [d for d in os.environ.get("__EGL_VENDOR_LIBRARY_DIRS", "").split(":") if d] or list(VENDOR_DIRS)
    vendor_files = [f for f in os.environ.get("__EGL_VENDOR_LIBRARY_FILENAMES", "").split(":") if f]
    for d in vendor_dirs:
        vendor_files += sorted(glob.glob(os.path.join(d, "*.json")))
    vendors = []
    for f in vendor_files:
        try:
            with open(f, encoding="utf-8") as fh:
                lib = json.load(fh).get("ICD", {}).get("library_path", "")
        except (OSError, ValueError, AttributeError):
            lib = ""
        vendors.append((f, _stat(f), lib, _library(lib, dirs) if isinstance(lib, str) and lib else None))
    drivers = []
    for d in dict.fromkeys(dirs):
        if os.path.isdir(d):
            drivers.append((d, _stat(os.path.join(d, "dri")), [_stat(g) for g in sorted(glob.glob(
                os.path.join(d, "libgallium*.so*")))]))
    devices = sorted(glob.glob("/dev/dri/*") + glob.glob("/dev/nvidia*"))
    return cache.key("egl", env, vendors, _library("libEGL.so.1", dirs), drivers, devices, os.uname().nodename,
                     os.cpu_count())


def probe() -> dict:
    """Open a context and say what it is: ``{"ok": True, **context_info}``, or ``{"ok": False, "reason": …}``
    (the :class:`BackendError` message, fix included) where none can be made."""
    try:
        ctx = create_context()
    except BackendError as e:
        return {"ok": False, "reason": e.message}
    try:
        with ctx:
            return {"ok": True, **context_info(ctx)}
    finally:
        ctx.release()


def machine_gl(refresh: bool = False, key: str | None = None) -> dict:
    """What :func:`probe` says on this machine, from the cache when its :func:`driver_key` still holds.

    A missing, unreadable or corrupt entry, or one of another key, is probed again (one context opened,
    about 40 ms on llvmpipe) and stored; ``refresh`` always probes. "No GL here" is stored too, with its
    reason, so a machine without EGL pays no probe per process. ``key``: :func:`driver_key`, when the
    caller has it already.
    """
    key = key or driver_key()
    entry_name = CACHE_ENTRY.format(key=key)
    if not refresh:
        raw = cache.read(CACHE_FOLDER, entry_name)
        if raw is not None:
            try:
                entry = json.loads(raw)
                if entry["key"] == key and _valid(entry["gl"]):
                    return entry["gl"]
            except (ValueError, TypeError, KeyError):
                pass  # corrupt: probed again
    info = probe()
    cache.write(CACHE_FOLDER, entry_name, json.dumps({"key": key, "gl": info}).encode("utf-8"))
    return info


def forget(key: str | None = None) -> None:
    """Drop the cached entry of ``key`` (default: :func:`driver_key`), as when a context failed where the cache
    said one opens: the next process probes again."""
    try:
        (cache.folder(CACHE_FOLDER) / CACHE_ENTRY.format(key=key or driver_key())).unlink()
    except OSError:
        pass


def _valid(info) -> bool:
    if not isinstance(info, dict) or not isinstance(info.get("ok"), bool):
        return False
    if not info["ok"]:
        return isinstance(info.get("reason"), str)
    return (all(isinstance(info.get(k), str) for k in ("vendor", "renderer", "version"))
            and isinstance(info.get("max_texture_size"), int) and info["max_texture_size"] > 0)


__all__ = ["CACHE_ENTRY", "CACHE_FOLDER", "INSTALL_HINT", "SOFTWARE_RENDERERS", "available", "context_info",
           "create_context", "driver_key", "forget", "is_software_renderer", "machine_gl", "probe"]
