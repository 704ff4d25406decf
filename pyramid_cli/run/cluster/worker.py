"""A cluster worker's side: one session for the worker's life (a worker plugin), and the chunk task that runs
its jobs on it, reporting what a chunk run again finds already written (see :mod:`pyramid_cli.run.cluster`).
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from itertools import groupby

from pyramid_cli.run import batch

try:  # the [cluster] extra
    from distributed import WorkerPlugin as _WorkerPlugin
except ImportError:  # pragma: no cover - exercised without the extra
    _WorkerPlugin = object  # type: ignore[assignment,misc]

PLUGIN_NAME = "pyramid-session"
#: Test hook: a path; the first chunk that can create this file writes half its jobs,
#: leaves a temporary file as a killed writer would, and kills its worker process.
CRASH_VARIABLE = "PYRAMID_TEST_CLUSTER_CRASH"
#: Test hook: seconds every chunk sleeps before it starts (a run long enough to kill things in).
SLOW_VARIABLE = "PYRAMID_TEST_CLUSTER_SLOW"


def _print_warning(message: str) -> None:
    """A worker session's warning, on the worker's standard error as the command line prints it."""
    import sys

    print(f"pyramid: warning: {message}", file=sys.stderr)


@dataclass(frozen=True)
class SessionSpec:
    """What a worker's session is made of: ``Session(backend, precision, threads=threads)``."""

    backend: str = "auto"
    precision: str = "float"
    threads: int | None = None

    def open(self):
        from pyramid_cli.exec.session import Session

        return Session(self.backend, self.precision, threads=self.threads, warn=_print_warning)

    @property
    def plugin_name(self) -> str:
        """The worker plugin's name: batches with other settings on the same cluster keep their own sessions."""
        return f"{PLUGIN_NAME}-{self.backend}-{self.precision}-{self.threads or 0}"


class SessionPlugin(_WorkerPlugin):
    """One :class:`~pyramid_cli.exec.session.Session` per Dask worker, for the worker's whole life.

    Parameters
    ----------
    spec : SessionSpec
        The backend and precision of the sessions.
    """

    name = PLUGIN_NAME

    def __init__(self, spec: SessionSpec):
        self.spec = spec
        self.name = spec.plugin_name
        self.session = None
        self.lock: threading.Lock | None = None

    def setup(self, worker) -> None:
        self.session = None
        self.lock = threading.Lock()

    def acquire(self):
        """The worker's session, opened at first use (in the thread that runs tasks: a GL context's thread)."""
        if self.session is None:
            self.session = self.spec.open()
        return self.session

    def teardown(self, worker) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None


@dataclass
class ChunkResult:
    """What one chunk task sends back: its report, its lines (``(stream, line)``, in job order), its executor.

    ``started`` is False for a chunk that did nothing because an earlier chunk failed
    (without ``--keep-going``): a local run would not have started its jobs either.
    """

    report: batch.Report = field(default_factory=batch.Report)
    messages: list[tuple[str, str]] = field(default_factory=list)
    executor: str = ""
    started: bool = True


class NoBar:
    """A progress bar that shows nothing (a chunk's, or a run without a bar)."""

    def __init__(self, total: int):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n: int) -> None:
        pass


def written_since(job: batch.Job, started: float) -> bool:
    """Was ``job``'s output written since ``started`` (a time.time()) and is it up to date?"""
    try:
        return os.path.getmtime(job.output) >= started and batch.is_fresh(job)
    except OSError:
        return False


def line_from_disk(job: batch.Job, work, mip_tile: int | None, executor: str) -> str:
    """The ``wrote`` line a local run prints for ``job``, for an output written by a run that could not say so."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.report import wrote_line

    shape = io.read_shape(job.output) or (0, 0, 0)
    levels = None
    if mip_tile:
        from pyramid_cli.core.geometry import mip_sizes

        levels = len(mip_sizes(shape[:2], getattr(work, "rounding", "down")))
    return wrote_line(job.output, shape[1], shape[0], levels, executor)


def _crash_hook(jobs: list[batch.Job]) -> bool:
    flag = os.environ.get(CRASH_VARIABLE)
    if not flag or len(jobs) < 2:
        return False
    try:
        os.close(os.open(flag, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def _stopped(stop: str | None, index: int) -> bool:
    """Has a chunk before ``index`` failed (without --keep-going)? The stop variable holds the first failed index."""
    if stop is None:
        return False
    from distributed import Variable

    try:
        return index > int(Variable(stop).get(timeout=10))
    except Exception:  # noqa: BLE001 - no answer: run the chunk; the client counts what it writes
        return False


def run_chunk(jobs: list[batch.Job], work, read, write, *, keep_going: bool, skip_existing: bool, threads: int,
              mip_tile: int | None, started: float, quiet: bool, verbose: bool, bar: bool,
              plugin: str = f"{PLUGIN_NAME}-auto-float", index: int = 0, stop: str | None = None) -> ChunkResult:
    """One cluster task: the chunk's jobs on this worker's session (see the module notes).

    ``index`` is the chunk's place in the job list; ``stop`` the name of the variable that
    holds the first failed chunk's index (None under ``--keep-going``).
    """
    from distributed import get_worker

    from pyramid_cli.run.local import run_in_budget, run_jobs
    from pyramid_cli.run.report import Reporter
    from pyramid_cli.run.shard import remove_stale_temps

    if os.environ.get(SLOW_VARIABLE):
        time.sleep(float(os.environ[SLOW_VARIABLE]))
    holder = get_worker().plugins[plugin]
    assert isinstance(holder, SessionPlugin) and holder.lock is not None, "registered by gather, set up by Dask"
    messages: list[tuple[str, str]] = []
    reporter = Reporter(quiet=quiet, verbose=verbose, out=lambda m: messages.append(("out", m)),
                        err=lambda m: messages.append(("err", m)), progress=NoBar if bar else None)
    remove_stale_temps([j.output for j in jobs])
    earlier = {k for k, j in enumerate(jobs) if written_since(j, started)}  # by a previous attempt of this chunk
    halted = _stopped(stop, index)
    if halted and not earlier:
        return ChunkResult(started=False)
    options = {"read": read, "write": write, "reporter": reporter, "keep_going": keep_going,
               "skip_existing": skip_existing, "jobs": threads, "mip_tile": mip_tile, "many": True}
    report = batch.Report()
    with holder.lock:
        session = holder.acquire()
        todo = [j for k, j in enumerate(jobs) if k not in earlier]
        if not halted and _crash_hook(todo):
            half = len(todo) // 2
            run_jobs(todo[:half], work, session, **options)
            victim = todo[half].output
            folder, base = os.path.split(os.path.abspath(victim))
            with open(os.path.join(folder, f".{base}.tmp-crashed{os.path.splitext(base)[1]}"), "wb") as f:
                f.write(b"half a file")
            os._exit(17)
        for done_before, group in groupby(enumerate(jobs), key=lambda kj: kj[0] in earlier):
            part = [j for _, j in group]
            if done_before:
                for j in part:
                    if not bar:
                        reporter.result(line_from_disk(j, work, mip_tile, session.ran or session.name))
                    report.done.append(j)
            elif not halted and (keep_going or not report.failed):  # within the worker's own limits, as locally
                report.extend(run_in_budget(part, work, session, memory=None, **options))
    return ChunkResult(report, messages, session.ran or session.name)


__all__ = ["PLUGIN_NAME", "CRASH_VARIABLE", "SLOW_VARIABLE", "SessionSpec", "SessionPlugin", "ChunkResult", "NoBar",
           "written_since", "line_from_disk", "run_chunk"]
