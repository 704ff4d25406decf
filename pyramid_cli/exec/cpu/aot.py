"""Ahead-of-time compiled kernels: a kernel's machine code as a small extension module, run without numba.

A fresh process that runs the CPU executor through numba first imports numba and llvmlite and loads each
kernel's machine code from numba's disk cache: about 0.2 s and 100 MiB before any pixel, the largest of its
fixed costs (docs/performance.md, "Fixed costs"). Once a kernel has run on a machine, this module has numba's
own ahead-of-time compiler (:mod:`numba.pycc`) build the same kernel text into an extension module, in a
process of its own after the run (:func:`spawn`), so that later processes import that module instead: a
fraction of a millisecond, numba and llvmlite never imported. The arithmetic is the same (the same text, the
same LLVM passes with the SLP vectoriser on, no fast-math), so the pixels are the same bits.

The modules live under ``aot/<machine key>/`` in the CPU cache folder (:func:`folder`): the key is the
processor's model and instruction-set flags (the code is compiled for this processor: a home folder shared by
the nodes of a farm keeps one set per kind of node) and numpy's version, and the Python ABI is in each module's
file name. A module
is written under a temporary name and renamed, so a process sees a whole module or none; one that cannot be
imported is left alone and the kernel runs through numba as before. Building needs a C compiler and Python's
headers (numba's builder compiles its runtime beside the kernel); where they are missing the builder leaves
its reason in the folder (``unavailable``) and is not tried again for a day, and the kernels run through numba.
``PYRAMID_AOT=0`` turns the modules off (neither loaded nor built).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from pyramid_cli.core import signals
from pyramid_cli.exec.cpu.codegen import source_digest

ENV = "PYRAMID_AOT"
UNAVAILABLE = "unavailable"   # the builder's reason it cannot build here (a C compiler or Python's headers missing)
RETRY_S = 24 * 3600           # a machine that could not build is tried again after this
STALE_S = 600                 # a build lock (or build folder) older than this is a builder that died
BUILDING = ".build-"          # the prefix of a builder's temporary folder beside the modules
SUFFIX = importlib.machinery.EXTENSION_SUFFIXES[0]


def enabled() -> bool:
    """Whether ahead-of-time kernels are used here: on Linux (the processor is read from /proc/cpuinfo), unless
    ``PYRAMID_AOT=0``."""
    return os.environ.get(ENV, "1") != "0" and sys.platform.startswith("linux")


def _cpu_text() -> str:
    """The first processor's model and flags from /proc/cpuinfo (every core of a machine has the same)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            block = f.read(1 << 16).split("\n\n", 1)[0]
    except OSError:
        return ""
    keep = ("vendor_id", "cpu family", "model", "model name", "flags", "Features", "CPU implementer", "CPU part")
    return "\n".join(ln for ln in block.splitlines() if ln.split(":", 1)[0].strip() in keep)


def machine_key(cpu: str | None = None) -> str | None:
    """The folder name of this machine's modules: a digest of the processor (model and instruction-set flags), the
    architecture and numpy's version (the modules convert arrays through numpy's C API; Python's ABI is in each
    module's file name); None where the processor cannot be read (then no modules are used)."""
    if cpu is None:
        return _this_machine()
    if not cpu:
        return None
    import numpy

    return hashlib.sha256(f"{platform.machine()}\nnumpy {numpy.__version__}\n{cpu}".encode()).hexdigest()[:16]


@functools.cache
def _this_machine() -> str | None:
    return machine_key(_cpu_text())


def folder(cache: Path) -> Path | None:
    """Where this machine's modules live under the CPU cache folder ``cache`` (None: not used here)."""
    if not enabled():
        return None
    key = machine_key()
    return None if key is None else Path(cache) / "aot" / key


def module_path(where: Path, digest: str) -> Path:
    """The module of the kernel whose source has ``digest``."""
    return where / f"k_{digest}{SUFFIX}"


def ready(cache: Path, digest: str) -> bool:
    """Whether the module of ``digest`` is built for this machine."""
    where = folder(cache)
    return where is not None and module_path(where, digest).exists()


def load(cache: Path, digest: str) -> Callable[..., None] | None:
    """The kernel of ``digest`` from its module, or None (not built, turned off, or not importable here)."""
    where = folder(cache)
    if where is None:
        return None
    path = module_path(where, digest)
    if not path.exists():
        return None
    try:
        spec = importlib.util.spec_from_file_location(f"k_{digest}", path)
        if spec is None or spec.loader is None:
            return None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.kernel
    except Exception:  # noqa: BLE001 - a module that does not load (cut short, another libc): numba runs it
        return None


# ------------------------------------------------------------------ building
def _lock(where: Path, digest: str) -> bool:
    """Take the build of ``digest`` (a lock file made exclusively); False when another builder has it."""
    lock = where / f"k_{digest}.lock"
    for _ in range(2):
        try:
            os.close(os.open(lock, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
            return True
        except FileExistsError:
            try:
                if time.time() - lock.stat().st_mtime < STALE_S:
                    return False
                lock.unlink()  # its builder died: take it over
            except OSError:
                return False
        except OSError:
            return False
    return False


def building(where: Path) -> list[str]:
    """The digests whose builders are at work in ``where`` now: their locks, less those older than
    :data:`STALE_S` (a builder that died, whose lock the next build takes over)."""
    now, live = time.time(), []
    for lock in where.glob("k_*.lock"):
        try:
            if now - lock.stat().st_mtime < STALE_S:
                live.append(lock.stem[2:])
        except OSError:
            continue  # its builder finished meanwhile
    return live


def blocked(where: Path) -> bool:
    """Whether the builder found, less than :data:`RETRY_S` ago, that it cannot build on this machine."""
    try:
        return time.time() - (where / UNAVAILABLE).stat().st_mtime < RETRY_S
    except OSError:
        return False


# the builder's process: this package (not whatever a ``pyramid_cli`` in its working folder would be), then main()
_BUILDER = "import sys; sys.path.insert(0, {root!r}); from pyramid_cli.exec.cpu.aot import main; sys.exit(main())"


def spawn(cache: Path, kernels: list[tuple[str, str, str]]) -> int:
    """Start a builder for ``kernels`` — (digest, source path, numba signature) of kernels that ran through numba
    and have no module yet — in a process of its own that outlives this one, at low priority, its output
    discarded. Returns how many kernels it was given (0: none started, for nothing to build, turned off, a machine
    that cannot build, a run interrupted by a signal, or an interpreter that is not a ``python`` executable)."""
    where = folder(cache)
    if where is None or not kernels or signals.interrupted():  # an interrupted run leaves nothing running behind
        return 0
    if not os.path.basename(sys.executable).startswith("python"):
        return 0  # inside an application's own interpreter (a DCC's), sys.executable is the application
    try:
        where.mkdir(parents=True, exist_ok=True)
    except OSError:
        return 0
    if blocked(where):
        return 0
    todo = [k for k in kernels if not module_path(where, k[0]).exists() and _lock(where, k[0])]
    if not todo:
        return 0
    try:
        proc = subprocess.Popen([sys.executable, "-c", _BUILDER.format(root=str(Path(__file__).parents[3]))],
                                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True, close_fds=True)
        assert proc.stdin is not None
        proc.stdin.write(json.dumps({"folder": str(where), "kernels": todo}).encode())
        proc.stdin.close()
    except OSError:
        for digest, _, _ in todo:
            (where / f"k_{digest}.lock").unlink(missing_ok=True)
        return 0
    return len(todo)


def build(where: Path, digest: str, source_path: str, sig: str) -> None:
    """Compile the kernel in ``source_path`` for ``sig`` into its module in ``where`` (numba's pycc: the same text
    and LLVM passes as the JIT's, the SLP vectoriser on, for this processor), written under a temporary name and
    renamed. The kernel's Python entry releases the GIL, as the JIT's ``nogil`` kernels do."""
    import tempfile
    import warnings

    text = Path(source_path).read_text(encoding="utf-8")
    if source_digest(text) != digest:
        raise ValueError(f"{source_path} is not the kernel {digest}")
    warnings.simplefilter("ignore")  # pycc's pending deprecation: this process prints nothing anyway
    from numba.core import compiler, config
    from numba.pycc import CC
    from numba.pycc import compiler as pycc_compiler

    class _NoGIL(compiler.Flags):  # pycc makes its flags itself: the entry it wraps keeps the GIL otherwise
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.release_gil = True

    pycc_compiler.Flags = _NoGIL  # type: ignore[misc]
    config.SLP_VECTORIZE = 1  # type: ignore[attr-defined]  # as compile.compile_vectorised
    namespace: dict = {"__name__": f"_pyramid_aot_{digest}"}
    exec(compile(text.replace("cache=True", "cache=False"), source_path, "exec"), namespace)  # noqa: S102 - ours
    with tempfile.TemporaryDirectory(dir=where, prefix=f"{BUILDING}{digest}-") as tmp:
        cc = CC(f"k_{digest}", source_module=__name__)
        cc.output_dir = tmp
        cc.target_cpu = "host"
        cc.export("kernel", sig)(namespace["kernel"].py_func)
        tempfile.tempdir = tmp  # pycc's own build folder, which it leaves behind when it fails: inside ours
        try:
            cc.compile()
        finally:
            tempfile.tempdir = None
        os.replace(os.path.join(tmp, cc.output_file), module_path(where, digest))


def _sweep(where: Path) -> None:
    """Remove the build folders of builders that died (older than :data:`STALE_S`)."""
    import shutil

    for old in where.glob(f"{BUILDING}*"):
        try:
            if time.time() - old.stat().st_mtime > STALE_S:
                shutil.rmtree(old, ignore_errors=True)
        except OSError:
            pass


def main() -> int:
    """The builder (:func:`spawn`): builds the kernels named on standard input, lowest priority; a failure to
    compile at all (no C compiler, no Python headers) is written to ``unavailable``."""
    job = json.loads(sys.stdin.buffer.read())
    where = Path(job["folder"])
    with contextlib.suppress(OSError):
        os.nice(19)
    with contextlib.suppress(OSError):  # the first process the kernel ends where memory runs out, never a user's run
        Path("/proc/self/oom_score_adj").write_text("1000", encoding="ascii")
    _sweep(where)
    built, failed = 0, ""
    for digest, source_path, sig in job["kernels"]:
        try:
            build(where, digest, source_path, sig)
            built += 1
        except Exception as e:  # noqa: BLE001 - said in the folder; the kernels keep running through numba
            failed = failed or f"{type(e).__name__}: {' '.join(str(e).split())}"
        finally:
            (where / f"k_{digest}.lock").unlink(missing_ok=True)
    if failed and not built:
        (where / UNAVAILABLE).write_text(failed + "\n", encoding="utf-8")
        return 1
    return 0


__all__ = ["ENV", "UNAVAILABLE", "blocked", "build", "building", "enabled", "folder", "load", "machine_key",
           "module_path", "ready", "spawn"]

