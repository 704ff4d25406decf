"""A batch on a Dask cluster, the client's side: the job list cut into chunks, one task each submitted, the
results gathered in job order, the workers and the clock watched, and what a lost cluster did not do reported
(see :mod:`pyramid_cli.run.cluster`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
import uuid
from collections import deque
from typing import TYPE_CHECKING

from pyramid_cli.core.errors import PyramidError, UsageError
from pyramid_cli.run import batch
from pyramid_cli.run.cluster.connection import TIMEOUT, connect, one_line, require, resolve
from pyramid_cli.run.cluster.logs import captured_output, summarise
from pyramid_cli.run.cluster.worker import (
    ChunkResult,
    NoBar,
    SessionPlugin,
    SessionSpec,
    line_from_disk,
    run_chunk,
    written_since,
)

if TYPE_CHECKING:  # distributed is an optional extra, imported when a cluster is used
    from distributed import Variable

MAX_CHUNK = 16
_POLL = 0.1  # seconds between looks at the futures, the worker events and the clock
_RECONCILE = 5.0  # seconds between counts of the scheduler's workers (events can be missed)


class ClusterError(PyramidError):
    """Frames the cluster could not run: the scheduler lost, no worker for the timeout, a chunk that killed its workers.

    Exit 6, as a backend that is unavailable: the frames are fine, the place they were to run is not.
    """

    kind = "backend"


def describe_jobs(jobs: list[batch.Job], most: int = 12) -> str:
    """Jobs as a person reads them: ``frames 1005-1012,1020`` (a range ``--frames`` takes), else their inputs."""
    frames = [f for f in (getattr(j, "frame", None) for j in jobs) if f is not None]
    if not jobs or len(frames) != len(jobs):
        names = [j.input for j in jobs]
        more = f" and {len(names) - 5} more" if len(names) > 5 else ""
        return ", ".join(names[:5]) + more
    from pyramid_cli.run.sequence import range_text

    runs = range_text(frames).split(",")
    text = ",".join(runs[:most]) + (f" and {len(runs) - most} more" if len(runs) > most else "")
    return ("frame " if len(frames) == 1 else "frames ") + text


def chunks(jobs: list, size: int) -> list[list]:
    """``jobs`` cut into contiguous chunks of ``size`` (the last one shorter)."""
    return [jobs[i:i + size] for i in range(0, len(jobs), size)]


def default_chunk(n_jobs: int, n_workers: int) -> int:
    """About four tasks per worker (load balance, retry granularity), at most :data:`MAX_CHUNK` jobs each."""
    return max(1, min(MAX_CHUNK, math.ceil(n_jobs / max(1, 4 * n_workers))))


def _session_spec(session) -> SessionSpec:
    if session is None:
        return SessionSpec()
    if isinstance(session, SessionSpec):
        return session
    return SessionSpec(session.backend, session.precision)


class _Run:
    """The client's side of one batch: chunk results in job order, worker events, the stop, the losses."""

    def __init__(self, client, label: str, parts: list[list[batch.Job]], reporter, *, work, mip_tile, keep_going: bool,
                 skip_existing: bool, timeout: float, started: float, executor: str, bar):
        self.client, self.label, self.parts, self.reporter = client, label, parts, reporter
        self.work, self.mip_tile, self.keep_going, self.skip_existing = work, mip_tile, keep_going, skip_existing
        self.timeout, self.started, self.executor, self.bar = timeout, started, executor, bar
        self.results: list[ChunkResult | None] = [None] * len(parts)
        self.printed = 0
        self.first_failed: int | None = None  # without --keep-going: chunks after it do not start
        self.stop: Variable | None = None  # the distributed.Variable the workers read it from
        self.events: deque = deque()
        self.workers: set[str] = set()
        self.deaths = [0] * len(parts)
        self.keys: dict[str, int] = {}
        import dask

        self.allowed_failures = int(dask.config.get("distributed.scheduler.allowed-failures", 3))

    # -------------------------------------------------------------- the loop
    def run(self, submit) -> batch.Report:
        from distributed import as_completed

        self.client.subscribe_topic("all", self.events.append)
        try:
            self.workers = set(self.client.nthreads())
            futures = [submit(i, part) for i, part in enumerate(self.parts)]
            self.keys = {f.key: i for i, f in enumerate(futures)}
            # results gathered in the background: a result lost with its worker is computed again, or waited
            # for, without holding up this loop (which watches the workers and the clock)
            pending = as_completed(futures, loop=self.client.loop, with_results=True, raise_errors=False)
            lost: str | None = None
            no_worker_since: float | None = None
            reconciled = time.monotonic()
            while not pending.is_empty():
                self._events()  # first: a worker's loss is reported before the chunk it rescheduled comes back
                finished = pending.next_batch(block=False)
                for future, value in finished:
                    lost = self._finish(self.keys[future.key], future, value) or lost
                self._release()
                now = time.monotonic()
                if lost is None and self.client.status != "running":
                    lost = "lost the scheduler"
                if lost is None and now - reconciled > _RECONCILE:
                    with contextlib.suppress(Exception):
                        self.workers = set(self.client.nthreads())
                    reconciled = now
                if lost is None and not self.workers:
                    if no_worker_since is None:
                        no_worker_since = now
                        self.reporter.detail(f"cluster {self.label}: no worker connected; waiting up to "
                                             f"{self.timeout:g} s (--cluster-timeout)")
                    elif now - no_worker_since >= self.timeout:
                        lost = f"no worker connected for {self.timeout:g} s (--cluster-timeout)"
                elif self.workers:
                    no_worker_since = None
                if lost is not None:
                    with contextlib.suppress(Exception):
                        self.client.cancel([f for f in futures if not f.done()], force=True)
                    self._lose(lost)
                    break
                if not finished:
                    time.sleep(_POLL)
        finally:
            with contextlib.suppress(Exception):
                self.client.unsubscribe_topic("all")
            if self.stop is not None:
                with contextlib.suppress(Exception):
                    self.stop.delete()
        self._release(everything=True)
        report = batch.Report()
        for result in self.results:
            if result is not None:
                report.extend(result.report)
        return report

    def stop_variable(self) -> str | None:
        """Set up the stop (without --keep-going) before the chunks are submitted; its name for the workers."""
        if self.keep_going:
            return None
        from distributed import Variable

        stop = self.stop = Variable(f"pyramid-stop-{uuid.uuid4().hex[:8]}", client=self.client)
        stop.set(len(self.parts))
        return stop.name

    # -------------------------------------------------------------- one chunk
    def _finish(self, i: int, future, value) -> str | None:
        """Take chunk ``i``'s ``value`` (as ``as_completed(with_results=True, raise_errors=False)`` gives it);
        a lost scheduler's reason when its future was cancelled under us."""
        from concurrent.futures import CancelledError

        from distributed.scheduler import KilledWorker

        if self.results[i] is not None:
            return None
        if isinstance(value, ChunkResult):
            self._take(i, value)
            return None
        if isinstance(value, CancelledError) or future.status == "cancelled":
            return "lost the scheduler"  # Dask cancels every future of a client that lost its scheduler
        error = value[1] if isinstance(value, tuple) and len(value) == 3 else value  # (type, exception, traceback)
        chunk = f"cluster {self.label}: chunk {i + 1} ({describe_jobs(self.parts[i])})"
        if isinstance(error, KilledWorker):
            self._take(i, self._from_disk(i, lambda jobs: ClusterError(
                f"{chunk}: its workers died running it more often than the scheduler allows "
                f"(distributed.scheduler.allowed-failures); {describe_jobs(jobs)} not done")))
        else:  # a task that raised: a bug, exit 1, in one line
            raised = one_line(error) if isinstance(error, BaseException) else repr(error)
            self._take(i, self._from_disk(i, lambda jobs: PyramidError(
                f"{chunk} raised {raised}; {describe_jobs(jobs)} not done")))
        return None

    def _take(self, i: int, result: ChunkResult) -> None:
        self.results[i] = result
        self.executor = result.executor or self.executor
        self.bar.update(len(self.parts[i]))
        if result.report.failed and not self.keep_going and (self.first_failed is None or i < self.first_failed):
            self.first_failed = i
            with contextlib.suppress(Exception):
                if self.stop is not None:  # set up by stop_variable without --keep-going
                    self.stop.set(i)

    def _from_disk(self, i: int, error) -> ChunkResult:
        """Chunk ``i`` as its outputs on disk tell: written since the start, up to date, or failed (``error(jobs)``)."""
        from pyramid_cli.run.shard import remove_stale_temps

        result = ChunkResult(executor=self.executor)
        missing = []
        for job in self.parts[i]:
            if written_since(job, self.started):
                result.report.done.append(job)
                if not self.bar_shown and not self.reporter.quiet:
                    result.messages.append(("out", line_from_disk(job, self.work, self.mip_tile, self.executor)))
            elif self.skip_existing and batch.is_fresh(job):
                result.report.skipped.append(job)
            else:
                missing.append(job)
        # what a dead worker left half-written (one cut off from the scheduler may still finish a frame: its
        # rename then fails, and the frame stays not done, as said)
        remove_stale_temps([job.output for job in missing])
        if missing and error is not None:
            e = error(missing)
            result.report.failed = [(job, e) for job in missing]
        return result

    @property
    def bar_shown(self) -> bool:
        return not isinstance(self.bar, NoBar)

    def _lose(self, reason: str) -> None:
        """Every chunk not back: outputs on disk counted, the frames not done failed by one error naming them."""
        undone = [i for i, r in enumerate(self.results) if r is None]
        partial = {i: self._from_disk(i, None) for i in undone}
        counted = [i for i in undone if self.first_failed is None or i < self.first_failed]  # the rest never ran
        missing = [j for i in counted for j in self.parts[i]
                   if j not in partial[i].report.done and j not in partial[i].report.skipped]
        if missing:
            error = ClusterError(f"cluster {self.label}: {reason}; {describe_jobs(missing)} not done")
            for i in counted:
                partial[i].report.failed = [(j, error) for j in self.parts[i] if j in missing]
        for i in undone:
            self.results[i] = partial[i]
            self.bar.update(len(self.parts[i]))

    # -------------------------------------------------------------- what is said
    def _release(self, everything: bool = False) -> None:
        """Print the lines of the finished chunks that no unfinished chunk precedes (all of them at the end)."""
        while self.printed < len(self.results) and (everything or self.results[self.printed] is not None):
            result = self.results[self.printed]
            for stream, line in result.messages if result is not None else []:
                (self.reporter.out if stream == "out" else self.reporter.err)(line)
            self.printed += 1

    def _events(self) -> None:
        """The scheduler's worker events: the worker count, and -v lines in this tool's words."""
        while self.events:
            _, msg = self.events.popleft()
            if not isinstance(msg, dict):
                continue
            worker, action = msg.get("worker"), msg.get("action")
            if action == "add-worker" and worker:
                self.workers.add(worker)
                self.reporter.detail(f"cluster: worker {worker} joined")
            elif action == "remove-worker" and worker:
                self.workers.discard(worker)
                what = []
                for key in msg.get("processing-tasks") or ():
                    i = self.keys.get(key)
                    if i is None:
                        continue
                    self.deaths[i] += 1
                    fate = "rescheduled" if self.deaths[i] <= self.allowed_failures else "given up"
                    what.append((i, f"chunk {i + 1} ({describe_jobs(self.parts[i])}) {fate}"))
                self.reporter.detail("; ".join([f"cluster: worker {worker} {'left' if msg.get('expected') else 'lost'}",
                                                *(text for _, text in sorted(what))]))


def run_cluster(job_list: list[batch.Job], work, cluster, *, session=None, read=None, write=None, reporter=None,
                keep_going: bool = False, skip_existing: bool = False, jobs: int = 2, mip_tile: int | None = None,
                chunk: int | None = None, many: bool = True, retries: int = 2,
                timeout: float | None = None) -> batch.Report:
    """Run ``job_list`` on a Dask cluster in chunks; the report of one process, in job order.

    Parameters
    ----------
    job_list : list of Job
        The planned jobs (after sequences and shards).
    work : Work
        What every job runs.
    cluster : str or distributed.Client
        A scheduler address (``tcp://host:8786``, ``host:8786``, ``tls://…``…), a scheduler
        file, ``local:N``, or a connected Client.
    session : Session or SessionSpec, optional
        The backend and precision the workers' sessions use (``Session()``'s defaults).
    chunk : int, optional
        Jobs per task (default :func:`default_chunk`).
    retries : int
        Dask retries of a task that raises (a worker's death is rescheduled by the scheduler).
    timeout : float, optional
        Seconds (default :data:`TIMEOUT`) to connect, and to wait with no worker connected
        before the frames not done fail.

    Returns
    -------
    batch.Report
        Failed frames carry their job's error, or one :class:`ClusterError` shared by the
        frames a lost cluster did not do.

    Raises
    ------
    UsageError
        The cluster cannot be reached or used (one line naming it).
    """
    from pyramid_cli.run.report import Reporter
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    read, write, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    timeout = TIMEOUT if timeout is None else float(timeout)
    if timeout <= 0:
        raise UsageError(f"--cluster-timeout {timeout:g}: a number of seconds > 0")
    spec = _session_spec(session)
    if not job_list:
        return batch.Report()
    require()
    if isinstance(cluster, (str, os.PathLike)):
        cluster = resolve(cluster, timeout)  # before Dask's import: a refused address fails at once
    # workers resolve paths themselves: relative ones would be relative to their own folders
    job_list = [dataclasses.replace(j, input=os.path.abspath(j.input), output=os.path.abspath(j.output))
                for j in job_list]
    import distributed  # noqa: F401 - its import sets up its loggers, which captured_output() then replaces

    with captured_output() as (captured, warned):
        try:
            with connect(cluster, timeout) as (client, label):
                client.register_plugin(SessionPlugin(spec), name=spec.plugin_name)
                n_workers = len(client.nthreads())
                size = chunk or default_chunk(len(job_list), n_workers)
                parts = chunks(job_list, size)
                reporter.detail(f"cluster {label}: {n_workers} worker(s), {len(parts)} task(s) of up to {size} "
                                f"job(s), executor {spec.backend}")
                show_bar = many and not reporter.quiet and reporter.progress is not None
                started = time.time()
                batch_id = uuid.uuid4().hex[:8]
                with (reporter.progress(len(job_list)) if show_bar else NoBar(len(job_list))) as bar:
                    run = _Run(client, label, parts, reporter, work=work, mip_tile=mip_tile, keep_going=keep_going,
                               skip_existing=skip_existing, timeout=timeout, started=started, executor=spec.backend,
                               bar=bar if show_bar else NoBar(0))
                    stop = run.stop_variable()

                    def submit(i: int, part: list[batch.Job]):
                        return client.submit(run_chunk, part, work, read, write, keep_going=keep_going,
                                             skip_existing=skip_existing, threads=jobs, mip_tile=mip_tile,
                                             started=started, quiet=reporter.quiet, verbose=reporter.verbose,
                                             bar=show_bar, plugin=spec.plugin_name, index=i, stop=stop,
                                             key=f"pyramid-{batch_id}-{i:05d}", retries=retries, pure=False)

                    return run.run(submit)
        finally:
            summarise(captured, warned, reporter)


__all__ = ["MAX_CHUNK", "ClusterError", "describe_jobs", "chunks", "default_chunk", "run_cluster"]
