"""One executor for many jobs: which one runs, why, and nothing behind the user's back.

A :class:`Session` owns one executor (one GL context with its compiled programs and
pooled textures, or the CPU executor) for a whole command, batch or Python loop, and
runs :class:`~pyramid_cli.jobs.work.Work` values on it. Backend names mean one thing:

- ``gl``: OpenGL through headless EGL; if no context can be made, or a plan cannot
  run there, the error says so (exit 6 / 5) instead of running elsewhere;
- ``cpu``: the CPU executor of plans;
- ``reference``: the float64 oracle of the paper's formulas (:mod:`pyramid_cli.reference.filters`);
- ``auto``: the executor estimated to finish this job first (:mod:`pyramid_cli.exec.auto`),
  with one warning when it has to move an image to the CPU (no EGL, or an image GL cannot hold).

``auto`` decides once it knows the job: at :meth:`Session.decide` (the run layer calls it with
the first input's size and the batch's length), else at the first :meth:`~Session.plan`,
:meth:`~Session.run` or :meth:`~Session.prepare`. No GL context is opened to decide (the
machine's renderer is cached, :func:`pyramid_cli.exec.gl.context.machine_gl`); one is opened only
to run on GL. On the CPU executor, :meth:`Session.prepare_async` imports numba and loads the
plan's kernels in a background thread while the caller reads the input; the first run waits for it.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from pyramid_cli.core import errors, options
from pyramid_cli.core.errors import BackendError, DataError
from pyramid_cli.exec.base import Executor
from pyramid_cli.exec.emulate import Emulator, rounded
from pyramid_cli.exec.gl.context import is_software_renderer
from pyramid_cli.jobs.work import Blur, Work
from pyramid_cli.plan.model import Plan

if TYPE_CHECKING:  # importing the CPU executor imports numba: made on first use (LoadingCPU)
    from pyramid_cli.exec.cpu import CPUExecutor

# What auto estimates when asked before any job is known (the demo's and the API's first call decide better).
NOMINAL_JOB = (Blur(levels=4), (1080, 1920, 4))



def spare_core() -> bool:
    """Whether a core is idle for loading in the background: the last minute's load average below the cores
    this process may use, less a half. On a busy machine the thread only takes turns with the decoder (measured
    0.3–0.6 s slower than loading after the read on two loaded cores), so the executor is made when first used."""
    from pyramid_cli.exec.cpu.executor import default_threads

    try:
        return os.getloadavg()[0] < default_threads() - 0.5
    except OSError:  # no load average here
        return True


def _numba_installed() -> bool:
    """Whether numba can be found (not imported: that costs 0.2 s and happens when the CPU executor is made)."""
    return "numba" in sys.modules or importlib.util.find_spec("numba") is not None


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


class LoadingCPU:
    """The compiled CPU executor while it is made in a background thread (numba imported, a plan's
    kernels loaded or compiled): what a caller asks before running (its strategy, dtypes, texture
    needs, name) is answered at once; running, or anything else, waits for the thread.

    Parameters
    ----------
    threads : int, optional
        The executor's threads (:class:`~pyramid_cli.exec.cpu.CPUExecutor`).
    """

    backend = "cpu"
    strategy = "fused"
    work_dtype = np.dtype(np.float32)
    max_texture_size = None
    host_textures = False
    writes_into = True

    def __init__(self, threads: int | None = None):
        from pyramid_cli.exec.cpu.executor import default_threads

        self.threads = max(1, int(threads)) if threads else default_threads()
        self._ready: CPUExecutor | None = None
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        self.pending = 0  # kernels the background thread compiles (what announce_compiles would say)

    @staticmethod
    def texture_bytes(extent: tuple[int, int]) -> int:
        """No textures beside the pictures: 0."""
        return 0

    @property
    def name(self) -> str:
        """``cpu (numba X, N thread(s))``, numba's version read without importing it
        (:func:`~pyramid_cli.exec.cpu.executor.numba_version`)."""
        if self._ready is not None:
            return self._ready.name
        from pyramid_cli.exec.cpu.executor import numba_version

        version = numba_version()
        if version == "?":
            return self.result().name
        return f"cpu (numba {version}, {self.threads} thread(s))"

    @property
    def started(self) -> bool:
        """Whether the background thread was started (or the executor made)."""
        return self._thread is not None or self._ready is not None

    def start(self, plan: Plan | None = None, dtype=np.float32, compiles: int = 0) -> None:
        """Make the executor, and load ``plan``'s kernels for inputs of ``dtype``, in a background thread
        (``compiles``: how many of them are not on disk). Once only; the thread's errors come at :meth:`result`,
        except those of loading the plan's kernels, which the run reports itself."""
        if self.started:
            return
        self.pending = compiles

        def work() -> None:
            try:
                from pyramid_cli.exec.cpu import CPUExecutor

                executor = CPUExecutor(threads=self.threads)
            except BaseException as e:  # noqa: BLE001 - handed to the caller at result()
                self._error = e
                return
            try:
                if plan is not None:
                    executor.prepare(plan, dtype)
            except Exception:  # noqa: BLE001, S110 - the run compiles it again and reports the error
                pass
            self._ready = executor

        self._thread = threading.Thread(target=work, name="pyramid-cpu-load")
        self._thread.start()

    def result(self) -> CPUExecutor:
        """The executor: waits for the background thread (made here when none was started)."""
        if self._thread is not None:
            self._thread.join()
            self._thread = None
            self.pending = 0
        if self._error is not None:
            raise self._error
        if self._ready is None:
            from pyramid_cli.exec.cpu import CPUExecutor

            self._ready = CPUExecutor(threads=self.threads)
        return self._ready

    def run_outputs(self, plan: Plan, images, dtype=np.float32, codes=None, out=None) -> list[np.ndarray]:
        """:meth:`~pyramid_cli.exec.cpu.CPUExecutor.run_outputs`, once the executor is ready."""
        return self.result().run_outputs(plan, images, dtype, codes=codes, out=out)

    def run(self, plan: Plan, image) -> np.ndarray:
        """:meth:`~pyramid_cli.exec.cpu.CPUExecutor.run`, once the executor is ready."""
        return self.result().run(plan, image)

    def encode8(self):
        """:meth:`~pyramid_cli.exec.cpu.CPUExecutor.encode8`, once the executor is ready."""
        return self.result().encode8()

    def prepare(self, plan: Plan, dtype=np.float32) -> None:
        """:meth:`~pyramid_cli.exec.cpu.CPUExecutor.prepare`, once the executor is ready."""
        self.result().prepare(plan, dtype)

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """Kernels still to compile: while the background thread runs, those it is compiling."""
        if self._thread is not None and self._thread.is_alive():
            return self.pending
        return self.result().uncached(plan, dtype)

    def close(self) -> None:
        """Wait for the background thread, then close the executor."""
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self._ready is not None:
            self._ready.close()

    @property
    def building(self) -> int:
        """Kernels the executor handed to a builder process as it closed (0 when it was never made)."""
        return self._ready.building if self._ready is not None else 0

    def __getattr__(self, name: str):  # anything else the executor has (compiles, cache_loads, info, …)
        if name.startswith("__") or name in ("_ready", "_error", "_thread"):
            raise AttributeError(name)
        return getattr(self.result(), name)


class Session:
    """One executor for many jobs (one GL context, compiled programs, pooled memory).

    Parameters
    ----------
    backend : {"auto", "gl", "cpu", "reference"}
        Where plans run (see the module notes); ``auto`` picks the one estimated to finish first.
    precision : {"float", "half"}
        GL intermediate textures: RGBA32F (exact) or RGBA16F.
    threads : int, optional
        CPU executor threads (default: the machine's cores).
    warn : callable, optional
        Receives one-line warnings (default: a :class:`~pyramid_cli.core.errors.BackendWarning` through
        ``warnings``; the command line passes its own, which prints ``pyramid: warning: …``).
    note : callable, optional
        Receives one line when the executor is chosen: ``executor NAME (WHY)`` (``-v``).

    Examples
    --------
    >>> import numpy as np, pyramid_cli as pyr
    >>> with pyr.Session(backend="cpu") as s:
    ...     outs = [pyr.blur(np.ones((9, 7)), 2, session=s) for _ in range(3)]
    >>> float(outs[-1].mean())
    1.0
    """

    def __init__(self, backend: str = "auto", precision: str = "float", *, threads: int | None = None,
                 warn: Callable[[str], None] | None = None, note: Callable[[str], None] | None = None):
        options.check("backend", backend, options.BACKENDS)
        options.check("precision", precision, options.PRECISIONS)
        self.backend = backend
        self.precision = precision
        self.threads = threads
        self._warn = warn or (lambda msg: errors.warn(msg, errors.BackendWarning))
        self._note = note
        self._executor: Executor | None = None
        self._cpu: Executor | None = None
        self._why = ""
        self.ran = ""          # the executor that ran the last job
        self.estimates: dict = {}  # auto: each backend's Estimate of the job it decided on
        self._ahead: Plan | None = None  # auto chose GL for this CPU plan: its kernels are built ahead at close()
        self._decided = False
        if backend != "auto":
            self._choose_named()

    # ------------------------------------------------------------ choice
    def _choose_named(self) -> None:
        if self.backend == "reference":
            self._why = "asked for: the float64 oracle of the paper's formulas"
        elif self.backend == "cpu":
            if not _numba_installed():
                _cpu_executor(self.threads, required=True)  # raises with the reason and the fix
            self._executor = self._cpu = LoadingCPU(self.threads)
            self._why = "asked for"
        else:
            from pyramid_cli.exec import gl

            executor = gl.GLExecutor(precision=self.precision)
            executor.open()  # BackendError (exit 6) now, before any input is read
            self._executor = executor
            self._why = "asked for"
        self._chosen()

    def _chosen(self) -> None:
        self._decided = True
        if self._note is not None:
            self._note(f"executor {self.name} ({self._why})")

    @property
    def decided(self) -> bool:
        """Whether the executor is chosen (``auto`` chooses at the first job, see the module)."""
        return self._decided

    def decide(self, work: Work | None = None, sizes=(), count: int = 1, dtype=None) -> None:
        """Choose ``auto``'s executor for ``count`` jobs of ``work`` on inputs of ``sizes`` ((rows, columns) or
        (rows, columns, channels) each; 4 channels when not said) stored as ``dtype`` (float16, float32, or None
        when not known). Once per session: later calls do nothing. Without ``work``, a nominal job decides
        (:data:`NOMINAL_JOB`). Opens no GL context and imports no numba."""
        if self._decided:
            return
        from pyramid_cli.exec.gl import context

        key = context.driver_key()
        gl = context.machine_gl(key=key)
        if not gl["ok"]:
            self._use_cpu()
            self._why = f"auto: no GL here ({gl['reason']})"
            self._warn(f"{gl['reason']}; running on the CPU")
        elif not _numba_installed():
            self._use_gl(gl)
            self._why = f"auto: GL renderer {gl['renderer']} (the compiled CPU executor needs numba)"
        else:
            try:
                self._estimate(work, sizes, count, dtype, gl, key)
            except Exception as e:  # noqa: BLE001 - a broken calibration file must not stop the run
                software = is_software_renderer(gl["renderer"])
                if software:
                    self._use_cpu()
                else:
                    self._use_gl(gl)
                self._why = (f"auto: no estimate ({type(e).__name__}: {e}); "
                             + ("GL is a software renderer: the CPU executor" if software else "a GPU: GL"))
        self._chosen()

    def _estimate(self, work, sizes, count, dtype, gl: dict, key: str) -> None:
        from pyramid_cli.exec import auto
        from pyramid_cli.plan import backend_cost

        costs = backend_cost.load(key)
        renderer = gl["renderer"]
        if not auto.calibrated_for(costs, renderer):
            self._use_gl(gl)
            self._why = (f"auto: GL renderer {renderer}, not calibrated here (make calibrate measures it against "
                         "the CPU executor)")
            return
        nominal = work is None or not sizes
        if nominal:
            work, sizes = NOMINAL_JOB[0], [NOMINAL_JOB[1]]
        size = tuple(sizes[0])
        channels = size[2] if len(size) > 2 else 4
        rc = tuple(tuple(s[:2]) for s in sizes)
        try:
            cpu_plan, gl_plan = work.plan(rc, "fused"), work.plan(rc, "cost")
        except Exception:  # noqa: BLE001 - the run reports a job that cannot be planned
            cpu_plan = gl_plan = None
        if cpu_plan is None or gl_plan is None:  # nothing to compute (or the run will say why not)
            self._use_cpu()
            self._why = "auto: no plan to estimate; the CPU executor, which sets nothing up before it runs"
            return
        from pyramid_cli.exec.gl.textures import texture_bytes

        found = auto.estimates(cpu_plan, gl_plan, channels, jobs=max(1, count), threads=self.threads, costs=costs,
                               texture_bytes=texture_bytes)
        chosen = min(found, key=lambda b: found[b].seconds)
        self.estimates = found
        if chosen == "gl":
            self._use_gl(gl)
            self._ahead = cpu_plan  # its kernels built ahead of time once this session closes (close())
        else:
            self._use_cpu()
        self._why = auto.line(found, {"gl": f"gl ({renderer})"}, chosen)
        if nominal:
            self._why += f" for a nominal job ({NOMINAL_JOB[1][1]}×{NOMINAL_JOB[1][0]} blur)"

    def _use_gl(self, info: dict) -> None:
        from pyramid_cli.exec import gl

        self._executor = gl.GLExecutor(precision=self.precision, info=info)

    def _use_cpu(self) -> None:
        if _numba_installed():
            self._executor = self._cpu = LoadingCPU(self.threads)
        else:
            self._executor = self._cpu = _cpu_executor(self.threads, self._warn)

    def _ready(self) -> Executor | None:
        """The chosen executor (a nominal choice when none was made); auto's GL context opened, or the CPU
        executor instead, with a warning, when it cannot be (the cache said it could: it is forgotten)."""
        if not self._decided:
            self.decide()
        ex = self._executor
        if self.backend == "auto" and ex is not None and ex.backend == "gl":
            from pyramid_cli.exec.gl import GLExecutor  # imported already: _use_gl made the executor

            assert isinstance(ex, GLExecutor), "GLExecutor is the executor whose backend is gl"
            if not ex.opened:
                try:
                    ex.open()
                except BackendError as e:
                    from pyramid_cli.exec.gl import context

                    context.forget()
                    self._warn(f"{e.message}; running on the CPU")
                    self._why = f"auto: no GL here ({e.message})"
                    self._use_cpu()
        return self._executor

    @property
    def why(self) -> str:
        """Why this executor, in one line (for -v)."""
        if not self._decided:
            self.decide()
        return self._why

    @property
    def name(self) -> str:
        """The executor this session runs on, e.g. ``gl (llvmpipe …)`` or ``cpu (…)``."""
        if not self._decided:
            self.decide()
        return _name(self._executor)

    @property
    def on_gl(self) -> bool:
        """Whether this session runs on the GL executor."""
        if not self._decided:
            self.decide()
        return self._executor is not None and self._executor.backend == "gl"

    @property
    def executor(self) -> Executor | None:
        """The executor (GLExecutor, the CPU executor, the emulator, or None for the reference)."""
        return self._ready()

    # ------------------------------------------------------------ running
    def plan(self, work: Work, sizes, executor=None) -> Plan | None:
        """``work``'s plan for inputs of ``sizes``, as the executor wants it planned (its ``strategy``:
        the GL executor's calibrated cost model by default, one fused pass per filter on the CPU).
        ``auto`` decides here when it has not yet (for this one job)."""
        if not self._decided:
            self.decide(work, sizes)
        ex = executor or self._ready()
        if ex is None:
            raise BackendError("the reference backend runs jobs, not plans")
        strategy = ex.strategy
        return work.plan(tuple(tuple(s[:2]) for s in sizes), strategy)

    def run(self, work: Work, images, dtype=np.float32) -> list[np.ndarray]:
        """Every output of ``work`` on ``images`` (one array, or one per input), as ``dtype``.

        ``dtype`` is float32 or float16 (rounded to nearest even from the float32 result,
        as every executor rounds), or float64: computed in float64 throughout by the compiled CPU
        executor's float64 kernels for ``auto`` and ``cpu`` (by the numpy plan emulator,
        :class:`~pyramid_cli.exec.emulate.Emulator`, where numba is missing), by the float64 oracle
        (:meth:`~pyramid_cli.jobs.work.Work.reference`) for ``reference``, and in float32 then widened
        on ``gl``, which has no float64. A job that keeps its input returns it first, unchanged.
        """
        images = list(images) if isinstance(images, (list, tuple)) else [images]
        if len(images) != work.n_inputs:
            raise ValueError(f"{work.label} takes {work.n_inputs} image(s), got {len(images)}")
        work.check(tuple(im.shape[:2] for im in images))
        kept = [images[0]] if work.keeps_input else []
        if np.dtype(dtype) == np.float64:
            return kept + self._run_float64(work, images)
        if not self._decided:
            shapes = [np.shape(im) if np.ndim(im) > 2 else (*np.shape(im)[:2], 1) for im in images]
            self.decide(work, shapes, dtype=np.asarray(images[0]).dtype)
        if self._ready() is None:
            self.ran = "reference"
            return kept + [rounded(o, dtype) for o in work.reference(images)]
        p = self.plan(work, [im.shape for im in images])
        if p is None:
            self.ran = self.name
            return kept
        return kept + self.run_plan(p, images, dtype, work)

    def _run_float64(self, work: Work, images: list) -> list[np.ndarray]:
        """:meth:`run`'s float64 outputs (see there), without the kept input."""
        if self.backend == "reference":
            self.ran = "reference"
            return [np.asarray(o, dtype=np.float64) for o in work.reference(images)]
        if self.backend == "gl":
            return [o.astype(np.float64) for o in self.run(work, images)[1 if work.keeps_input else 0:]]
        if self._cpu is None and _numba_installed():  # auto on GL (or not decided yet): GL has no float64
            self._cpu = LoadingCPU(self.threads)
        executor = self._cpu if self._cpu is not None else Emulator()
        p = work.plan(tuple(tuple(np.shape(im)[:2]) for im in images), executor.strategy)
        outs = [] if p is None else executor.run_outputs(p, images, np.float64)
        self.ran = _name(executor)
        return outs

    def run_plan(self, p: Plan, images, dtype=np.float32, work: Work | None = None) -> list[np.ndarray]:
        """Every output of a plan, on this session's executor (the reference cannot run plans)."""
        executor = self._ready()
        if executor is None:
            raise BackendError("the reference backend runs jobs, not plans")
        images = list(images) if isinstance(images, (list, tuple)) else [images]
        try:
            outs = executor.run_outputs(p, images, dtype)
            self.ran = self.name
            return outs
        except DataError as e:  # GL cannot hold this image (texture limit, allocation failure)
            if self.backend != "auto" or not self.on_gl:
                raise
            self._warn(f"{e.message}; running this image on the CPU")
        if self._cpu is None:
            self._cpu = _cpu_executor(self.threads, self._warn)
        if self._cpu.strategy != executor.strategy and work is not None:
            replanned = self.plan(work, [im.shape for im in images], self._cpu)
            assert replanned is not None, "a job with a plan under one strategy has one under every strategy"
            p = replanned
        outs = self._cpu.run_outputs(p, images, dtype)
        self.ran = _name(self._cpu)
        return outs

    def uncached(self, work: Work, images, dtype=np.float32) -> int:
        """Kernels the CPU executor must compile before it can run ``work`` on ``images`` (0 elsewhere):
        a first run on a machine compiles them once, about a second each."""
        ex = self._ready()
        if ex is None:
            return 0
        p = self.plan(work, [im.shape for im in images])
        half = any(np.asarray(im).dtype == np.float16 for im in images)
        return ex.uncached(p, np.float16 if half else np.float32) if p is not None else 0

    def prepare(self, work: Work, sizes) -> None:
        """Get ready to run ``work`` on inputs of ``sizes`` (GL: compile, allocate; the CPU: load the kernels);
        never fails."""
        try:
            ex = self._ready()
            if ex is None:
                return
            p = self.plan(work, sizes)
            if p is not None:
                ex.prepare(p)
        except (BackendError, DataError):
            pass  # the run itself reports it, or falls back

    def prepare_async(self, work: Work, sizes, count: int = 1, dtype=None) -> None:
        """Decide (:meth:`decide`) and, on the CPU executor, import numba and load ``work``'s kernels for
        inputs of ``sizes`` in a background thread, so that it overlaps the caller's reading of the input
        where a core is idle for it (:func:`spare_core`); the first run waits for it. GL prepares nothing
        here (its context belongs to the calling thread: :meth:`prepare` compiles and allocates there).
        Never fails: the run reports what goes wrong."""
        try:
            self.decide(work, sizes, count, dtype)
            ex = self._executor
            if not isinstance(ex, LoadingCPU) or ex.started or not spare_core():
                return
            p = work.plan(tuple(tuple(s[:2]) for s in sizes), ex.strategy)
            half = dtype is not None and np.dtype(dtype) == np.float16
            compiles = 0
            if p is not None:
                from pyramid_cli.exec.auto import cpu_kernels

                compiles = cpu_kernels(p)[1]
            ex.start(p, np.float16 if half else np.float32, compiles)
        except Exception:  # noqa: BLE001 - an optimisation only: the run decides and reports
            pass

    def close(self) -> None:
        executors = {id(e): e for e in (self._executor, self._cpu) if e is not None}.values()
        for ex in executors:
            ex.close()
        building = sum(getattr(ex, "building", 0) for ex in executors)
        if self._ahead is not None:  # auto ran GL: the CPU executor's kernels built for the next process to weigh
            from pyramid_cli.exec.cpu.executor import build_ahead

            plan, self._ahead = self._ahead, None
            try:
                building += build_ahead(plan)
            except Exception:  # noqa: BLE001, S110 - a speed-up for later runs: never this run's failure
                pass
        if building and self._note is not None:  # nothing runs behind the user's back unsaid (-v)
            self._note(f"{building} CPU kernel(s) now build ahead of time in a process of its own, once per machine, "
                       "so that later runs load them without numba (PYRAMID_AOT=0 turns this off)")

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _name(executor: Executor | None) -> str:
    return "reference" if executor is None else executor.name


__all__ = ["LoadingCPU", "NOMINAL_JOB", "Session", "is_software_renderer"]
