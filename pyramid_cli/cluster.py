"""A batch on a Dask distributed cluster (``--cluster ADDRESS``; optional extra ``[cluster]``).

The client plans the job list (sequences, shards) as in one process, cuts it into
contiguous chunks and submits one task per chunk. Each worker holds one executor (a
:class:`~pyramid_cli.session.Session`) for its whole life through a worker plugin
(:class:`SessionPlugin`), opened at its first task in the thread that runs tasks and
closed when the worker stops. Workers read inputs and write outputs on the shared
storage themselves: only job lists, reports and messages travel through the scheduler.

A worker that dies mid-chunk is the scheduler's to retry (it reschedules the chunk
on another worker; ``retries=`` covers tasks that raise). Outputs are written
atomically (hidden temporary file, then rename), and a chunk that runs again first
removes the temporary files its dead predecessor left and skips the outputs already
written since the batch started, so a retry leaves neither half-written nor
duplicate files. ``--keep-going``, progress and the exit code are those of one process.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

from . import batch
from .errors import PyramidError, UsageError

try:  # the [cluster] extra
    from distributed import WorkerPlugin as _WorkerPlugin
except ImportError:  # pragma: no cover - exercised without the extra
    _WorkerPlugin = object  # type: ignore[assignment,misc]

PLUGIN_NAME = "pyramid-session"
INSTALL_HINT = "pip install 'bilinear-pyramid[cluster]'"
#: Test hook: a path; the first chunk that can create this file writes half its jobs,
#: leaves a temporary file as a killed writer would, and kills its worker process.
CRASH_VARIABLE = "PYRAMID_TEST_CLUSTER_CRASH"
MAX_CHUNK = 16
CONNECT_TIMEOUT = "20s"  # how long --cluster ADDRESS tries to reach the scheduler


class ClusterError(PyramidError):
    """A chunk that the cluster could not run (its worker died too often, the scheduler went away)."""

    kind = "internal"


@dataclass(frozen=True)
class SessionSpec:
    """What a worker's session is made of: ``Session(backend, precision, threads=threads)``."""

    backend: str = "auto"
    precision: str = "float"
    threads: int | None = None

    def open(self):
        from .session import Session

        return Session(self.backend, self.precision, threads=self.threads)

    @property
    def plugin_name(self) -> str:
        """The worker plugin's name: batches with other settings on the same cluster keep their own sessions."""
        return f"{PLUGIN_NAME}-{self.backend}-{self.precision}-{self.threads or 0}"


class SessionPlugin(_WorkerPlugin):
    """One :class:`~pyramid_cli.session.Session` per Dask worker, for the worker's whole life.

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


def require() -> None:
    """Raise a :class:`UsageError` (exit 2) naming the extra when Dask distributed is not installed."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(f"--cluster needs Dask distributed: {INSTALL_HINT}") from None


@contextlib.contextmanager
def connect(cluster) -> Iterator:
    """A ``distributed.Client`` for ``cluster``: a Client (used as is), ``local:N`` or a scheduler address.

    ``local:N`` starts ``LocalCluster(n_workers=N, processes=True, threads_per_worker=1)``
    on 127.0.0.1 without a dashboard, for the duration of the block.
    """
    require()
    from distributed import Client, LocalCluster

    if isinstance(cluster, Client):
        yield cluster
        return
    address = str(cluster)
    if address.startswith("local:"):
        try:
            n = int(address[len("local:"):])
        except ValueError:
            n = 0
        if n < 1:
            raise UsageError(f"--cluster {address!r}: expected local:N with N ≥ 1 worker processes")
        with LocalCluster(n_workers=n, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None, silence_logs=40) as local, Client(local) as client:
            yield client
        return
    try:
        client = Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as e:
        raise UsageError(f"--cluster {address}: cannot reach a Dask scheduler there ({e})") from None
    with client:
        yield client


def chunks(jobs: list, size: int) -> list[list]:
    """``jobs`` cut into contiguous chunks of ``size`` (the last one shorter)."""
    return [jobs[i:i + size] for i in range(0, len(jobs), size)]


def default_chunk(n_jobs: int, n_workers: int) -> int:
    """About four tasks per worker (load balance, retry granularity), at most :data:`MAX_CHUNK` jobs each."""
    return max(1, min(MAX_CHUNK, math.ceil(n_jobs / max(1, 4 * n_workers))))


class _NoBar:
    def __init__(self, total: int):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n: int) -> None:
        pass


def _written_since(job: batch.Job, started: float) -> bool:
    try:
        return os.path.getmtime(job.output) >= started and batch.is_fresh(job)
    except OSError:
        return False


def _crash_hook(jobs: list[batch.Job]) -> bool:
    flag = os.environ.get(CRASH_VARIABLE)
    if not flag or len(jobs) < 2:
        return False
    try:
        os.close(os.open(flag, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def run_chunk(jobs: list[batch.Job], work, read, write, *, keep_going: bool, skip_existing: bool, threads: int,
              mip_tile: int | None, started: float, quiet: bool, verbose: bool, bar: bool,
              plugin: str = f"{PLUGIN_NAME}-auto-float"):
    """One cluster task: the chunk's jobs on this worker's session (see the module notes).

    Returns ``(report, messages)``, messages being ``(stream, line)`` for the client to print.
    """
    from distributed import get_worker

    from .pipeline import Reporter, run_jobs
    from .shard import remove_stale_temps

    holder = get_worker().plugins[plugin]
    messages: list[tuple[str, str]] = []
    reporter = Reporter(quiet=quiet, verbose=verbose, out=lambda m: messages.append(("out", m)),
                        err=lambda m: messages.append(("err", m)), progress=_NoBar if bar else None)
    remove_stale_temps([j.output for j in jobs])
    earlier = [j for j in jobs if _written_since(j, started)]  # by a previous attempt of this chunk
    todo = [j for j in jobs if j not in earlier]
    options = {"read": read, "write": write, "reporter": reporter, "keep_going": keep_going,
               "skip_existing": skip_existing, "jobs": threads, "mip_tile": mip_tile, "many": True}
    with holder.lock:
        session = holder.acquire()
        if _crash_hook(todo):
            half = len(todo) // 2
            run_jobs(todo[:half], work, session, **options)
            victim = todo[half].output
            folder, base = os.path.split(os.path.abspath(victim))
            with open(os.path.join(folder, f".{base}.tmp-crashed{os.path.splitext(base)[1]}"), "wb") as f:
                f.write(b"half a file")
            os._exit(17)
        report = run_jobs(todo, work, session, **options)
    report.done = earlier + report.done
    return report, messages


def _session_spec(session) -> SessionSpec:
    if session is None:
        return SessionSpec()
    if isinstance(session, SessionSpec):
        return session
    return SessionSpec(session.backend, session.precision)


def run_cluster(job_list: list[batch.Job], work, cluster, *, session=None, read=None, write=None, reporter=None,
                keep_going: bool = False, skip_existing: bool = False, jobs: int = 2, mip_tile: int | None = None,
                chunk: int | None = None, many: bool = True, retries: int = 2) -> batch.Report:
    """Run ``job_list`` on a Dask cluster in chunks; the report of one process, in job order.

    Parameters
    ----------
    job_list : list of Job
        The planned jobs (after sequences and shards).
    work : Work
        What every job runs.
    cluster : str or distributed.Client
        A scheduler address (``tcp://host:8786``), ``local:N``, or a connected Client.
    session : Session or SessionSpec, optional
        The backend and precision the workers' sessions use (``Session()``'s defaults).
    chunk : int, optional
        Jobs per task (default :func:`default_chunk`).
    retries : int
        Dask retries of a task that raises (a worker's death is rescheduled by the scheduler).

    Returns
    -------
    batch.Report
    """
    from .pipeline import ReadOptions, Reporter, WriteOptions

    read, write, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    spec = _session_spec(session)
    report = batch.Report()
    if not job_list:
        return report
    # workers resolve paths themselves: relative ones would be relative to their own folders
    job_list = [dataclasses.replace(j, input=os.path.abspath(j.input), output=os.path.abspath(j.output))
                for j in job_list]
    with connect(cluster) as client:
        from distributed import as_completed

        client.register_plugin(SessionPlugin(spec), name=spec.plugin_name)
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        size = chunk or default_chunk(len(job_list), n_workers)
        parts = chunks(job_list, size)
        reporter.detail(f"cluster {client.scheduler.address}: {n_workers} worker(s), {len(parts)} task(s) of "
                        f"up to {size} job(s), executor {spec.backend}")
        show_bar = many and not reporter.quiet and reporter.progress is not None
        started = time.time()
        batch_id = uuid.uuid4().hex[:8]
        futures = {}
        for i, part in enumerate(parts):
            f = client.submit(run_chunk, part, work, read, write, keep_going=keep_going,
                              skip_existing=skip_existing, threads=jobs, mip_tile=mip_tile, started=started,
                              quiet=reporter.quiet, verbose=reporter.verbose, bar=show_bar, plugin=spec.plugin_name,
                              key=f"pyramid-{batch_id}-{i:05d}", retries=retries, pure=False)
            futures[f.key] = (i, f)
        results: dict[int, batch.Report] = {}
        bar_cm = reporter.progress(len(job_list)) if show_bar else _NoBar(len(job_list))
        with bar_cm as bar:
            pending = as_completed([f for _, f in futures.values()])
            for fut in pending:
                i, _ = futures[fut.key]
                try:
                    part_report, messages = fut.result()
                except Exception as e:  # the cluster's failure, not a job's
                    part_report = batch.Report(failed=[(j, ClusterError(
                        f"{j.input}: cluster task {fut.key} failed: {type(e).__name__}: {e}")) for j in parts[i]])
                    messages = []
                for stream, line in messages:
                    (reporter.out if stream == "out" else reporter.err)(line)
                results[i] = part_report
                bar.update(len(parts[i]))
                if part_report.failed and not keep_going:
                    for _, other in futures.values():
                        other.cancel()
                    break
    for i in sorted(results):
        r = results[i]
        report.done += r.done
        report.skipped += r.skipped
        report.failed += r.failed
    return report


__all__ = ["SessionSpec", "SessionPlugin", "ClusterError", "run_cluster", "run_chunk", "connect", "chunks",
           "default_chunk", "require", "PLUGIN_NAME", "CRASH_VARIABLE"]
