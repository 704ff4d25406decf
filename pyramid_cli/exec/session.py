"""One executor for many jobs: which one runs, why, and nothing behind the user's back.

A :class:`Session` owns one executor (one GL context with its compiled programs and
pooled textures, or the CPU executor) for a whole command, batch or Python loop, and
runs :class:`~pyramid_cli.jobs.work.Work` values on it. Backend names mean one thing:

- ``gl``: OpenGL through headless EGL; if no context can be made, or a plan cannot
  run there, the error says so (exit 6 / 5) instead of running elsewhere;
- ``cpu``: the CPU executor of plans;
- ``reference``: the float64 oracle of the paper's formulas (:mod:`pyramid_cli.reference.filters`);
- ``auto``: the fastest exact executor here (:func:`choose`), with one warning when it
  has to move an image to the CPU (no EGL, or an image GL cannot hold).
"""

from __future__ import annotations

import sys
from collections.abc import Callable

import numpy as np

from pyramid_cli.core import options
from pyramid_cli.core.errors import BackendError, DataError
from pyramid_cli.exec.base import Executor
from pyramid_cli.exec.emulate import Emulator, rounded
from pyramid_cli.exec.gl.context import is_software_renderer
from pyramid_cli.jobs.work import Work
from pyramid_cli.plan.model import Plan


def _compiled_cpu(threads: int | None) -> Executor | None:
    """The compiled CPU executor when numba is usable here, else None."""
    from pyramid_cli.exec import cpu

    return cpu.CPUExecutor(threads=threads) if cpu.available()[0] else None


def _cpu_executor(threads: int | None, warn=None, required: bool = False) -> Executor:
    """The compiled CPU executor; without numba, BackendError when ``required`` (``--backend cpu``), else the
    numpy plan emulator with a warning (``auto`` on a machine with neither GL nor numba)."""
    compiled = _compiled_cpu(threads)
    if compiled is not None:
        return compiled
    from pyramid_cli.exec import cpu

    why = cpu.available()[1]
    if required:
        raise BackendError(why)
    if warn is not None:
        warn(f"{why}; running the numpy plan emulator (slow, exact)")
    return Emulator()


class Session:
    """One executor for many jobs (one GL context, compiled programs, pooled memory).

    Parameters
    ----------
    backend : {"auto", "gl", "cpu", "reference"}
        Where plans run (see the module notes); ``auto`` picks the fastest exact one.
    precision : {"float", "half"}
        GL intermediate textures: RGBA32F (exact) or RGBA16F.
    threads : int, optional
        CPU executor threads (default: the machine's cores).
    warn : callable, optional
        Receives one-line warnings (default: printed to standard error).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> with pyr.Session(backend="cpu") as s:
    ...     outs = [pyr.blur(np.ones((9, 7)), 2, session=s) for _ in range(3)]
    >>> float(outs[-1].mean())
    1.0
    """

    def __init__(self, backend: str = "auto", precision: str = "float", *, threads: int | None = None,
                 warn: Callable[[str], None] | None = None):
        options.check("backend", backend, options.BACKENDS)
        options.check("precision", precision, options.PRECISIONS)
        self.backend = backend
        self.precision = precision
        self.threads = threads
        self._warn = warn or (lambda msg: print(f"pyramid: warning: {msg}", file=sys.stderr))
        self._executor: Executor | None = None
        self._cpu: Executor | None = None
        self.why = ""          # why this executor, in one line (for -v)
        self.ran = ""          # the executor that ran the last job
        self._choose()

    # ------------------------------------------------------------ choice
    def _choose(self) -> None:
        if self.backend == "reference":
            self.why = "asked for: the float64 oracle of the paper's formulas"
            return
        if self.backend == "cpu":
            self._executor = self._cpu = _cpu_executor(self.threads, required=True)
            self.why = "asked for"
            return
        from pyramid_cli.exec import gl

        executor = gl.GLExecutor(precision=self.precision)
        try:
            executor.open()
        except BackendError as e:
            if self.backend == "gl":
                raise
            self._executor = self._cpu = _cpu_executor(self.threads, self._warn)
            self.why = f"auto: no GL here ({e.message})"
            self._warn(f"{e.message}; running on the CPU")
            return
        renderer = executor.renderer
        if self.backend == "auto" and is_software_renderer(renderer):
            compiled = _compiled_cpu(self.threads)
            if compiled is not None:
                executor.close()
                self._executor = self._cpu = compiled
                self.why = f"auto: GL is a software renderer ({renderer}); the compiled CPU executor is faster"
                return
        self._executor = executor
        self.why = "asked for" if self.backend == "gl" else f"auto: GL renderer {renderer}"

    @property
    def name(self) -> str:
        """The executor this session runs on, e.g. ``gl (llvmpipe …)`` or ``cpu (…)``."""
        return _name(self._executor)

    @property
    def on_gl(self) -> bool:
        """Whether this session runs on the GL executor."""
        return self._executor is not None and self._executor.backend == "gl"

    @property
    def executor(self) -> Executor | None:
        """The executor (GLExecutor, the CPU executor, the emulator, or None for the reference)."""
        return self._executor

    # ------------------------------------------------------------ running
    def plan(self, work: Work, sizes, executor=None) -> Plan | None:
        """``work``'s plan for inputs of ``sizes``, as the executor wants it planned (its ``strategy``:
        the GL executor's calibrated cost model by default, one fused pass per filter on the CPU)."""
        strategy = (executor or self._executor).strategy
        return work.plan(tuple(tuple(s[:2]) for s in sizes), strategy)

    def run(self, work: Work, images, dtype=np.float32) -> list[np.ndarray]:
        """Every output of ``work`` on ``images`` (one array, or one per input), as ``dtype``.

        ``dtype`` is float32 or float16 (rounded to nearest even from the float32 result,
        as every executor rounds). A job that keeps its input returns it first, unchanged.
        """
        images = list(images) if isinstance(images, (list, tuple)) else [images]
        if len(images) != work.n_inputs:
            raise ValueError(f"{work.label} takes {work.n_inputs} image(s), got {len(images)}")
        work.check(tuple(im.shape[:2] for im in images))
        kept = [images[0]] if work.keeps_input else []
        if self._executor is None:
            self.ran = "reference"
            return kept + [rounded(o, dtype) for o in work.reference(images)]
        p = self.plan(work, [im.shape for im in images])
        if p is None:
            self.ran = self.name
            return kept
        return kept + self.run_plan(p, images, dtype, work)

    def run_plan(self, p: Plan, images, dtype=np.float32, work: Work | None = None) -> list[np.ndarray]:
        """Every output of a plan, on this session's executor (the reference cannot run plans)."""
        if self._executor is None:
            raise BackendError("the reference backend runs jobs, not plans")
        images = list(images) if isinstance(images, (list, tuple)) else [images]
        try:
            outs = self._executor.run_outputs(p, images, dtype)
            self.ran = self.name
            return outs
        except DataError as e:  # GL cannot hold this image (texture limit, allocation failure)
            if self.backend != "auto" or not self.on_gl:
                raise
            self._warn(f"{e.message}; running this image on the CPU")
        if self._cpu is None:
            self._cpu = _cpu_executor(self.threads, self._warn)
        if self._cpu.strategy != self._executor.strategy and work is not None:
            p = self.plan(work, [im.shape for im in images], self._cpu)
        outs = self._cpu.run_outputs(p, images, dtype)
        self.ran = _name(self._cpu)
        return outs

    def uncached(self, work: Work, images, dtype=np.float32) -> int:
        """Kernels the CPU executor must compile before it can run ``work`` on ``images`` (0 elsewhere):
        a first run on a machine compiles them once, about a second each."""
        if self._executor is None:
            return 0
        p = self.plan(work, [im.shape for im in images])
        half = any(np.asarray(im).dtype == np.float16 for im in images)
        return self._executor.uncached(p, np.float16 if half else np.float32) if p is not None else 0

    def prepare(self, work: Work, sizes) -> None:
        """Get ready to run ``work`` on inputs of ``sizes`` (GL: compile, allocate); never fails."""
        if self._executor is None:
            return
        try:
            p = self.plan(work, sizes)
            if p is not None:
                self._executor.prepare(p)
        except (BackendError, DataError):
            pass  # the run itself reports it, or falls back

    def close(self) -> None:
        for ex in {id(e): e for e in (self._executor, self._cpu) if e is not None}.values():
            ex.close()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _name(executor: Executor | None) -> str:
    return "reference" if executor is None else executor.name


__all__ = ["Session", "is_software_renderer"]
