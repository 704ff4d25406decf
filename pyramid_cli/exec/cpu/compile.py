"""Compilation for the CPU executor: generated kernel sources as numba dispatchers, cached on disk.

Compiled once per kernel text per machine: a source (:mod:`pyramid_cli.exec.cpu.codegen`) is
written to the cache directory (:func:`cache_dir`) under the digest of its text and compiled
with ``cache=True``, so a later process loads the machine code from numba's cache beside it
instead of compiling again. numba is imported only inside these functions (and by the
generated modules), so importing the executor does not load it.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from pyramid_cli.core import cache, signals
from pyramid_cli.core.errors import BackendError
from pyramid_cli.exec.cpu import aot
from pyramid_cli.exec.cpu.codegen import source_digest

if TYPE_CHECKING:
    from numba.core.dispatcher import Dispatcher

INSTALL_HINT = "install numba: pip install numba (or pip install -e . in a checkout)"
CACHE_ENV = "PYRAMID_CACHE_DIR"


def available() -> tuple[bool, str]:
    """Can the CPU executor run here? ``(True, "numba X.Y")`` or ``(False, reason with the fix)`` (imports numba)."""
    try:
        import numba
    except Exception as e:  # noqa: BLE001 - ImportError, or a broken llvmlite
        return False, _not_imported(e)
    return True, f"numba {numba.__version__}"


def installed() -> tuple[bool, str]:
    """:func:`available` without importing numba (found on the path, or imported already): ahead-of-time kernels
    (:mod:`pyramid_cli.exec.cpu.aot`) run without it, and a numba that fails to import is reported where a kernel
    first needs it (:func:`load`)."""
    if "numba" in sys.modules or importlib.util.find_spec("numba") is not None:
        return True, "numba"
    return False, f"numba is not installed; {INSTALL_HINT}"


def _not_imported(e: BaseException) -> str:
    reason = " ".join(str(e).split()) or type(e).__name__
    return f"numba cannot be imported ({reason}); {INSTALL_HINT}"


def cache_dir() -> Path:
    """Where generated kernel sources and numba's compiled code live.

    ``$PYRAMID_CACHE_DIR`` if set, else the ``cpu`` folder of the cache
    (:func:`pyramid_cli.core.cache.folder`: ``~/.cache/bilinear-pyramid/cpu`` by default).
    """
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    return cache.folder("cpu")


_LOCK = threading.Lock()
_MODULES: dict[str, Dispatcher | Callable[..., None]] = {}   # file digest → its kernel, shared by executors
_SOURCES: dict[str, str] = {}   # file digest → source path, of the kernels loaded as numba dispatchers
BLAS_PROBE = "scipy.linalg.cython_blas"


def compile_vectorised(fn, sig: str) -> None:
    """``fn.compile(sig)`` with LLVM's SLP vectoriser on (numba leaves it off by default).

    The unrolled channel loops are straight-line code that only the SLP vectoriser packs
    into SIMD registers: measured 3× faster on the RGBA synthesis loop. numba reads the
    flag when it builds the pass managers of each compile, so it is set for this compile
    only (under the module lock) and restored; a kernel loaded from the disk cache keeps
    the machine code it was compiled to.
    """
    from numba.core import config

    # numba's config sets its flags from the environment in a loop: no declared attribute to type
    saved = config.SLP_VECTORIZE  # type: ignore[attr-defined]
    config.SLP_VECTORIZE = 1  # type: ignore[attr-defined]
    try:
        compile_plain(fn, sig)
    finally:
        config.SLP_VECTORIZE = saved  # type: ignore[attr-defined]


def compile_plain(fn, sig: str) -> None:
    """``fn.compile(sig)``; a disk cache that cannot be written (a full disk, a file-size limit) costs the
    cache, not the run: the retry runs without the caches of ``fn`` and of the functions of its module that it
    calls (``half_row``, compiled for each type of row it is given, each saved as it is compiled)."""
    try:
        fn.compile(sig)
    except OSError:
        from numba.core.caching import NullCache

        for d in (fn, *fn.py_func.__globals__.values()):
            if hasattr(d, "_cache") and hasattr(d, "py_func"):  # numba's dispatchers
                d._cache = NullCache()
        fn.compile(sig)


def _skip_blas_probe() -> None:
    """Import numba's array math without its BLAS probe, which imports SciPy's linalg (~0.2 s).

    numba checks for BLAS once per process, when its array-math registry loads at the first
    compile or cache load; with SciPy installed that import costs more than loading every
    kernel of a plan. The kernels use no BLAS. The probe is skipped only while nothing has
    imported SciPy's linalg or numba's array math yet; afterwards SciPy imports as usual (and
    numba's ``np.dot`` family still finds it when first typed).
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules or BLAS_PROBE in sys.modules:
        return
    sys.modules[BLAS_PROBE] = None  # type: ignore[assignment]  # makes the probe's import fail fast
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        if BLAS_PROBE in sys.modules and sys.modules[BLAS_PROBE] is None:
            del sys.modules[BLAS_PROBE]


def write_source(folder: Path, digest: str, source: str) -> Path:
    """``source`` as ``k_<digest>.py`` in ``folder``, written once, atomically; its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"k_{digest}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
        tmp.write_text(source, encoding="utf-8")
        os.replace(tmp, path)  # never a half-written file, even with processes racing
    return path


def fallback_cache() -> Path:
    """A per-user folder under the temporary directory, for when the cache folder cannot be written."""
    import tempfile

    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return Path(tempfile.gettempdir()) / f"bilinear-pyramid-cpu-{uid}"


def load(source: str, folder: Path) -> Dispatcher | Callable[..., None]:
    """The ``kernel`` of ``source``: its ahead-of-time module where one is built for this machine
    (:func:`pyramid_cli.exec.cpu.aot.load`: numba is not imported), else the source written once to ``folder``
    (atomically) and imported from there as a numba dispatcher (:func:`jit_kernels` lists those). A numba that
    cannot be imported is a BackendError naming the fix."""
    digest = source_digest(source)
    with _LOCK:
        hit = _MODULES.get(digest)
        if hit is not None:
            return hit
        fn = aot.load(folder, digest)
        if fn is not None:
            _MODULES[digest] = fn
            return fn
        try:
            path = write_source(folder, digest, source)
        except OSError:  # a read-only or broken cache folder: compile from a private one
            path = write_source(fallback_cache(), digest, source)
        name = f"_pyramid_cpu_k_{digest}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"cannot import the kernel source {path}", path=str(path))
        module = importlib.util.module_from_spec(spec)
        try:
            import numba  # noqa: F401 - the kernel's own import, reported here as the others are
        except Exception as e:  # noqa: BLE001 - ImportError, or a broken llvmlite
            raise BackendError(_not_imported(e)) from None
        sys.modules[name] = module
        spec.loader.exec_module(module)
        _MODULES[digest] = module.kernel
        _SOURCES[digest] = str(path)
        return module.kernel


def jit_kernels() -> dict[str, str]:
    """The kernels this process runs through numba: digest → the path of its source (what
    :func:`pyramid_cli.exec.cpu.aot.spawn` builds ahead of time for the next process)."""
    with _LOCK:
        return dict(_SOURCES)


def loaded(digest: str) -> bool:
    """Whether this process has compiled (or loaded) the kernel of ``digest`` already."""
    fn = _MODULES.get(digest)
    return fn is not None and bool(getattr(fn, "signatures", True))  # an ahead-of-time kernel is always compiled


def on_disk(folder: Path, digest: str) -> bool:
    """Whether numba's cache in ``folder`` holds machine code of the kernel of ``digest``."""
    return any((folder / "__pycache__").glob(f"k_{digest}.kernel-*.nbi"))


def ensure_compiled(fn, sig: str, compile_: Callable[[object, str], None] = compile_plain) -> str | None:
    """Compile ``fn`` for ``sig`` once (or load it from the disk cache): ``"compiled"``, ``"loaded"``, or None
    when it already was.

    A signal waits for the compile to end (:func:`signals.deferred`): raised inside numba's
    compiler it would leave it broken, and its clean-up would print tracebacks.
    """
    if not hasattr(fn, "signatures"):  # an ahead-of-time kernel: machine code already
        return None
    with _LOCK, signals.deferred():
        if fn.signatures:
            return None
        hits = sum(fn.stats.cache_hits.values())
        with light_cache_load(fn):
            compile_(fn, sig)
        return "loaded" if sum(fn.stats.cache_hits.values()) > hits else "compiled"


@contextmanager
def light_cache_load(fn) -> Iterator[None]:
    """Within this block, ``fn`` loads its machine code from numba's disk cache without numba's full set-up.

    numba's cache load first "refreshes" its target: it imports and registers every implementation
    it could ever compile (lists, dicts, random, linalg, jitclass, …), about 0.15 s in a fresh
    process, for a kernel that is already machine code. A load needs only numba's runtime (the
    memory allocator of the kernels' scratch rows), so this loads with that alone. On a miss the
    compile that follows does numba's full set-up itself (every compile refreshes its target), after
    :func:`_skip_blas_probe`. Where numba's cache object lacks the internals this relies on (another
    numba, a cache disabled by a full disk), it changes nothing.
    """
    cache = getattr(fn, "_cache", None)
    load = getattr(cache, "_load_overload", None)
    guard = getattr(cache, "_guard_against_spurious_io_errors", None)
    try:
        from numba.core.runtime import rtsys
    except ImportError:
        cache = None
    if cache is None or load is None or guard is None:
        _skip_blas_probe()
        yield
        return

    def load_overload(sig, target_context):
        rtsys.initialize(target_context)
        cres = None
        with guard():  # as numba's own: an unreadable cache entry is a miss
            cres = load(sig, target_context)
        if cres is None:
            _skip_blas_probe()  # a compile follows
        return cres

    cache.load_overload = load_overload
    try:
        yield
    finally:
        del cache.load_overload


__all__ = ["BLAS_PROBE", "CACHE_ENV", "INSTALL_HINT", "available", "cache_dir", "compile_plain", "compile_vectorised",
           "ensure_compiled", "fallback_cache", "installed", "jit_kernels", "light_cache_load", "load", "loaded",
           "on_disk", "source_digest", "write_source"]
