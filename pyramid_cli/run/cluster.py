"""A batch on a Dask distributed cluster (``--cluster ADDRESS``; optional extra ``[cluster]``).

The client plans the job list (sequences, shards) as in one process, cuts it into
contiguous chunks and submits one task per chunk. Each worker holds one executor (a
:class:`~pyramid_cli.exec.session.Session`) for its whole life through a worker plugin
(:class:`SessionPlugin`), opened at its first task in the thread that runs tasks and
closed when the worker stops. Workers read inputs and write outputs on the shared
storage themselves: only job lists, reports and messages travel through the scheduler.

What the run says is one process's: chunks' lines are printed in job order (a chunk
that finishes early waits for those before it), and the report counts what happened on
disk however chunks failed or ran again.

- A worker that dies mid-chunk is the scheduler's to retry (it reschedules the chunk on
  another worker; ``retries=`` covers tasks that raise). Outputs are written atomically
  (hidden temporary file, then rename), and a chunk that runs again first removes the
  temporary files its dead predecessor left and reports the outputs written since the
  batch started as written (the line a local run prints, from the file's header) without
  writing them again: neither half-written nor duplicate files, nor missing lines.
- Without ``--keep-going`` the first failed chunk sets a stop (a ``distributed.Variable``
  holding its index): chunks after it that have not started do nothing, as a local run
  never starts the jobs after a failure; chunks already running finish and are counted.
- A chunk the cluster cannot run, the scheduler lost, or no worker connected for
  ``timeout`` seconds fail the frames not done with one :class:`ClusterError` naming them;
  outputs already on disk count as written.
- Dask's own log lines and warnings never reach the terminal: they are captured for the
  run, and ``-v`` says what happened in this tool's words (a worker lost, a chunk
  rescheduled).

Addresses are whatever ``distributed.Client`` accepts (``tcp://``, ``HOST:PORT``,
``tls://``, ``ws://``, ``wss://``, ``inproc://``, ``ucx://``), a scheduler file, or
``local:N``; anything that cannot be used is refused in one line (exit 2), a refused TCP
connection at once (a plain socket connect first, before Dask is imported).
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import importlib.util
import json
import logging
import math
import os
import re
import socket
import threading
import time
import uuid
import warnings
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import groupby

from pyramid_cli.core.errors import PyramidError, UsageError
from pyramid_cli.run import batch

try:  # the [cluster] extra
    from distributed import WorkerPlugin as _WorkerPlugin
except ImportError:  # pragma: no cover - exercised without the extra
    _WorkerPlugin = object  # type: ignore[assignment,misc]

PLUGIN_NAME = "pyramid-session"
INSTALL_HINT = "pip install 'bilinear-pyramid[cluster]'"
#: Test hook: a path; the first chunk that can create this file writes half its jobs,
#: leaves a temporary file as a killed writer would, and kills its worker process.
CRASH_VARIABLE = "PYRAMID_TEST_CLUSTER_CRASH"
#: Test hook: seconds every chunk sleeps before it starts (a run long enough to kill things in).
SLOW_VARIABLE = "PYRAMID_TEST_CLUSTER_SLOW"
MAX_CHUNK = 16
#: ``--cluster-timeout``'s default, in seconds: connecting, a scheduler file to appear, no worker connected.
TIMEOUT = 30.0
DEFAULT_PORT = 8786  # Dask's, for an address without one
#: Logger families whose records are captured for a run (Dask's, and the libraries it logs through).
DASK_LOGGERS = ("distributed", "dask", "tornado", "asyncio", "bokeh")
_POLL = 0.1  # seconds between looks at the futures, the worker events and the clock
_RECONCILE = 5.0  # seconds between counts of the scheduler's workers (events can be missed)


class ClusterError(PyramidError):
    """Frames the cluster could not run: the scheduler lost, no worker for the timeout, a chunk that killed its workers.

    Exit 6, as a backend that is unavailable: the frames are fine, the place they were to run is not.
    """

    kind = "backend"


@dataclass(frozen=True)
class SessionSpec:
    """What a worker's session is made of: ``Session(backend, precision, threads=threads)``."""

    backend: str = "auto"
    precision: str = "float"
    threads: int | None = None

    def open(self):
        from pyramid_cli.exec.session import Session

        return Session(self.backend, self.precision, threads=self.threads)

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


def require() -> None:
    """Raise a :class:`UsageError` (exit 2) naming the extra when Dask distributed is not installed."""
    try:
        found = importlib.util.find_spec("distributed") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise UsageError(f"--cluster needs Dask distributed: {INSTALL_HINT}")


# ------------------------------------------------------------------ addresses
def describe_jobs(jobs: list[batch.Job], most: int = 12) -> str:
    """Jobs as a person reads them: ``frames 1005-1012,1020`` (a range ``--frames`` takes), else their inputs."""
    frames = [getattr(j, "frame", None) for j in jobs]
    if not jobs or any(f is None for f in frames):
        names = [j.input for j in jobs]
        more = f" and {len(names) - 5} more" if len(names) > 5 else ""
        return ", ".join(names[:5]) + more
    from pyramid_cli.run.sequence import range_text

    runs = range_text(frames).split(",")
    text = ",".join(runs[:most]) + (f" and {len(runs) - most} more" if len(runs) > most else "")
    return ("frame " if len(frames) == 1 else "frames ") + text


def _one_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


@dataclass(frozen=True)
class Target:
    """Where ``--cluster`` points, checked as far as it can be without Dask: ``local:N`` or a scheduler address.

    ``label`` names it in messages (the scheduler file it came from, if any).
    """

    address: str
    label: str
    local: int = 0
    scheme: str = "tcp"


def _host_port(location: str, label: str) -> tuple[str, int]:
    m = re.fullmatch(r"\[([0-9A-Fa-f:.%\w]+)\](?::(\d+))?|([^\s:/\[\]@]+)(?::(\d+))?", location)
    if not m:
        raise UsageError(f"--cluster {label}: expected HOST:PORT after the scheme (e.g. tcp://scheduler:8786)")
    host = m.group(1) or m.group(3)
    port = int(m.group(2) or m.group(4) or DEFAULT_PORT)
    if not 0 < port < 65536:
        raise UsageError(f"--cluster {label}: port {port} is not a TCP port (1–65535)")
    return host, port


def _probe(host: str, port: int, label: str, timeout: float) -> None:
    """A plain TCP connect, so a refused or unknown address is reported at once (Dask retries until its timeout)."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except ConnectionRefusedError:
        raise UsageError(f"--cluster {label}: connection refused: no Dask scheduler listens on {host}:{port}") from None
    except socket.gaierror as e:
        raise UsageError(f"--cluster {label}: unknown host {host} ({e.strerror})") from None
    except TimeoutError:
        raise UsageError(f"--cluster {label}: no answer from {host}:{port} in {timeout:g} s "
                         "(--cluster-timeout)") from None
    except OSError as e:
        raise UsageError(f"--cluster {label}: cannot connect to {host}:{port} ({e.strerror or e})") from None


def _scheduler_file(path: str, timeout: float) -> str:
    """The address in a ``dask scheduler --scheduler-file`` file, waiting up to ``timeout`` for it as Dask does."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            with open(path, encoding="utf-8") as f:
                address = json.load(f).get("address")
            if isinstance(address, str) and address:
                return address
            problem = "no scheduler address in the file"
        except FileNotFoundError:
            problem = "no such scheduler file"
        except (OSError, ValueError, AttributeError) as e:  # half written, or not a scheduler file
            problem = f"not a Dask scheduler file ({e.strerror if isinstance(e, OSError) else 'not JSON'})"
        if time.monotonic() >= deadline:
            raise UsageError(f"--cluster {path}: {problem} after {timeout:g} s (--cluster-timeout; "
                             "dask scheduler --scheduler-file writes the file)")
        time.sleep(0.1)


def resolve(cluster: str | os.PathLike, timeout: float = TIMEOUT) -> Target:
    """Check ``--cluster``'s value without importing Dask: a refused or malformed TCP address fails here, fast.

    Raises
    ------
    UsageError
        ``local:N`` with N < 1, a scheduler file that does not appear in ``timeout``, an address
        that is not one, a host that does not resolve, a refused connection, no answer in ``timeout``.
    """
    text = os.fspath(cluster).strip()
    if text.startswith("local:"):
        n = int(text[6:]) if text[6:].isdigit() else 0
        if n < 1:
            raise UsageError(f"--cluster {text!r}: expected local:N with N ≥ 1 worker processes")
        return Target(text, text, local=n, scheme="local")
    label = text
    if "://" not in text and (text.lower().endswith(".json") or os.sep in text or os.path.isfile(text)):
        text = _scheduler_file(text, timeout)
        label = f"{text} (from {label})"
    scheme, sep, location = text.partition("://")
    if not sep:
        scheme, location = "tcp", text
    scheme = scheme.lower()
    if scheme in ("tcp", "tls", "ws", "wss"):
        host, port = _host_port(location, label)
        _probe(host, port, label, timeout)
        text = f"{scheme}://{f'[{host}]' if ':' in host else host}:{port}"
    return Target(text, label, scheme=scheme)


def _security(target: Target):
    """The Dask configuration's TLS settings (``distributed.comm.tls.*``) for tls:// and wss://, or a refusal."""
    from distributed import Security

    try:
        security = Security()
        context = security.get_connection_args("client").get("ssl_context")
    except Exception as e:  # noqa: BLE001 - a missing or bad certificate file, whatever the library raises
        raise UsageError(f"--cluster {target.label}: the Dask TLS configuration cannot be used "
                         f"({_one_line(e)})") from None
    if context is None:
        raise UsageError(f"--cluster {target.label}: {target.scheme}:// needs certificates: set "
                         "distributed.comm.tls.ca-file, distributed.comm.tls.client.cert and .client.key in the Dask "
                         "configuration (~/.config/dask/distributed.yaml or DASK_DISTRIBUTED__COMM__TLS__… variables)")
    return security


def _check_scheme(target: Target) -> None:
    """Refuse in one line what Dask cannot connect to from here (unknown schemes, UCX missing, inproc elsewhere)."""
    from distributed.comm import registry

    if target.scheme == "inproc":
        from distributed.comm.inproc import global_manager

        try:
            listener = global_manager.get_listener_for(target.address.partition("://")[2])
        except ValueError:  # another process's, or not an inproc address at all
            listener = None
        if listener is None:
            raise UsageError(f"--cluster {target.label}: no scheduler in this process listens there (an inproc:// "
                             "address reaches a scheduler in the same Python process)")
        return
    try:
        registry.get_backend(target.scheme).get_connector()
    except ValueError:
        raise UsageError(f"--cluster {target.label}: unknown address scheme {target.scheme}:// (Dask's: "
                         f"{', '.join(s + '://' for s in sorted(registry.backends))}; or HOST:PORT, local:N, "
                         "a scheduler file)") from None
    except Exception as e:  # noqa: BLE001 - a backend whose library is missing (ucx) fails in its own way
        extra = " (install distributed-ucxx)" if target.scheme == "ucx" else ""
        raise UsageError(f"--cluster {target.label}: {target.scheme}:// cannot be used on this machine{extra}: "
                         f"{_one_line(e)}") from None


def _identify(target: Target, security, timeout: float) -> None:
    """Ask the address who it is, within ``timeout``: a listener that is not a Dask scheduler, or one that
    never answers, makes ``distributed.Client`` wait forever."""
    from distributed.comm import connect as dask_connect

    args = security.get_connection_args("client") if security is not None else {}
    answer: list = []

    async def ask():
        comm = await dask_connect(target.address, timeout=timeout, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def run() -> None:  # a thread of its own: the caller may be inside an event loop (Jupyter)
        try:
            answer.append(asyncio.run(asyncio.wait_for(ask(), timeout)))
        except BaseException as e:  # noqa: BLE001 - reported below in one line
            answer.append(e)

    thread = threading.Thread(target=run, name="pyramid-cluster-identify", daemon=True)
    thread.start()
    thread.join(timeout + 1)
    reply = answer[0] if answer else TimeoutError()
    if isinstance(reply, TimeoutError):
        raise UsageError(f"--cluster {target.label}: no Dask scheduler answered in {timeout:g} s (--cluster-timeout)")
    if isinstance(reply, BaseException):
        raise UsageError(f"--cluster {target.label}: cannot talk to a Dask scheduler there ({_one_line(reply)})")
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        kind = reply.get("type") if isinstance(reply, dict) else type(reply).__name__
        raise UsageError(f"--cluster {target.label}: answered, but is not a Dask scheduler ({kind})")


@contextlib.contextmanager
def connect(cluster, timeout: float = TIMEOUT) -> Iterator[tuple[object, str]]:
    """``(distributed.Client, label)`` for ``cluster``: a Client (used as is), ``local:N``, a scheduler file or address.

    ``local:N`` starts ``LocalCluster(n_workers=N, processes=True, threads_per_worker=1)``
    on 127.0.0.1 without a dashboard, for the duration of the block. A client this opens
    is closed at the end of the block. Anything that cannot be connected to raises a one-line
    :class:`UsageError` within about ``timeout`` seconds.
    """
    require()
    from distributed import Client, LocalCluster

    if isinstance(cluster, Client):
        yield cluster, str(cluster.scheduler.address)
        return
    target = cluster if isinstance(cluster, Target) else resolve(cluster, timeout)
    if target.local:
        with LocalCluster(n_workers=target.local, processes=True, threads_per_worker=1, host="127.0.0.1",
                          dashboard_address=None, silence_logs=logging.CRITICAL) as local, \
                Client(local, set_as_default=False) as client:
            yield client, target.label
        return
    _check_scheme(target)
    security = _security(target) if target.scheme in ("tls", "wss") else None
    if target.scheme != "inproc":
        _identify(target, security, timeout)
    try:
        client = Client(target.address, timeout=timeout, security=security, set_as_default=False)
    except Exception as e:  # noqa: BLE001 - whatever Dask raises, one line with the address
        raise UsageError(f"--cluster {target.label}: cannot connect ({_one_line(e)})") from None
    try:
        yield client, target.label
    finally:
        with contextlib.suppress(Exception):
            client.close(timeout=min(timeout, 10))


# ------------------------------------------------------------------ Dask's output
class _Captured(logging.Handler):
    """Keeps the records of Dask's loggers (warnings and worse) instead of printing them."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def captured_output() -> Iterator[tuple[_Captured, list]]:
    """Dask's log records and Python warnings kept, not printed, for the block: ``(handler, warnings)``.

    Import ``distributed`` first: its import installs its own handlers, which this replaces
    for the block and puts back after.
    """
    handler = _Captured()
    family = {n for n in logging.root.manager.loggerDict if n.split(".")[0] in DASK_LOGGERS} | set(DASK_LOGGERS)
    saved = []
    for name in sorted(family):
        logger = logging.getLogger(name)
        if logger.handlers or name in DASK_LOGGERS:
            saved.append((logger, logger.handlers[:], logger.propagate))
            logger.handlers[:] = [handler]
            logger.propagate = False
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            yield handler, warned
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers[:] = handlers
            logger.propagate = propagate


def _summarise(handler: _Captured, warned: list, reporter) -> None:
    """Under -v, one line for what Dask logged or warned during the run (its own lines never reach the terminal)."""
    def first_line(text: str) -> str:
        line = next((t.strip() for t in text.splitlines() if t.strip()), "")
        return line[:160] + ("…" if len(line) > 160 else "")

    texts = [f"{r.levelname.lower()} from {r.name}: {first_line(r.getMessage())}" for r in handler.records]
    texts += [f"{w.category.__name__}: {first_line(str(w.message))}" for w in warned]
    if texts:
        reporter.detail(f"cluster: Dask logged {len(texts)} message(s) during the run; the first: {texts[0]}")


# ------------------------------------------------------------------ chunks
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


def _line_from_disk(job: batch.Job, work, mip_tile: int | None, executor: str) -> str:
    """The ``wrote`` line a local run prints for ``job``, for an output written by a run that could not say so."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.pipeline import wrote_line

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

    from pyramid_cli.run.pipeline import Reporter, run_jobs
    from pyramid_cli.run.shard import remove_stale_temps

    if os.environ.get(SLOW_VARIABLE):
        time.sleep(float(os.environ[SLOW_VARIABLE]))
    holder = get_worker().plugins[plugin]
    messages: list[tuple[str, str]] = []
    reporter = Reporter(quiet=quiet, verbose=verbose, out=lambda m: messages.append(("out", m)),
                        err=lambda m: messages.append(("err", m)), progress=_NoBar if bar else None)
    remove_stale_temps([j.output for j in jobs])
    earlier = {k for k, j in enumerate(jobs) if _written_since(j, started)}  # by a previous attempt of this chunk
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
                        reporter.result(_line_from_disk(j, work, mip_tile, session.ran or session.name))
                    report.done.append(j)
            elif not halted and (keep_going or not report.failed):
                r = run_jobs(part, work, session, **options)
                report.done += r.done
                report.skipped += r.skipped
                report.failed += r.failed
    return ChunkResult(report, messages, session.ran or session.name)


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
        self.stop = None  # the distributed.Variable the workers read it from
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
                report.done += result.report.done
                report.skipped += result.report.skipped
                report.failed += result.report.failed
        return report

    def stop_variable(self) -> str | None:
        """Set up the stop (without --keep-going) before the chunks are submitted; its name for the workers."""
        if self.keep_going:
            return None
        from distributed import Variable

        self.stop = Variable(f"pyramid-stop-{uuid.uuid4().hex[:8]}", client=self.client)
        self.stop.set(len(self.parts))
        return self.stop.name

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
            raised = _one_line(error) if isinstance(error, BaseException) else repr(error)
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
                self.stop.set(i)

    def _from_disk(self, i: int, error) -> ChunkResult:
        """Chunk ``i`` as its outputs on disk tell: written since the start, up to date, or failed (``error(jobs)``)."""
        from pyramid_cli.run.shard import remove_stale_temps

        result = ChunkResult(executor=self.executor)
        missing = []
        for job in self.parts[i]:
            if _written_since(job, self.started):
                result.report.done.append(job)
                if not self.bar_shown and not self.reporter.quiet:
                    result.messages.append(("out", _line_from_disk(job, self.work, self.mip_tile, self.executor)))
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
        return not isinstance(self.bar, _NoBar)

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
    from pyramid_cli.run.pipeline import ReadOptions, Reporter, WriteOptions

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
                with (reporter.progress(len(job_list)) if show_bar else _NoBar(len(job_list))) as bar:
                    run = _Run(client, label, parts, reporter, work=work, mip_tile=mip_tile, keep_going=keep_going,
                               skip_existing=skip_existing, timeout=timeout, started=started, executor=spec.backend,
                               bar=bar if show_bar else _NoBar(0))
                    stop = run.stop_variable()

                    def submit(i: int, part: list[batch.Job]):
                        return client.submit(run_chunk, part, work, read, write, keep_going=keep_going,
                                             skip_existing=skip_existing, threads=jobs, mip_tile=mip_tile,
                                             started=started, quiet=reporter.quiet, verbose=reporter.verbose,
                                             bar=show_bar, plugin=spec.plugin_name, index=i, stop=stop,
                                             key=f"pyramid-{batch_id}-{i:05d}", retries=retries, pure=False)

                    return run.run(submit)
        finally:
            _summarise(captured, warned, reporter)


__all__ = ["SessionSpec", "SessionPlugin", "ClusterError", "ChunkResult", "Target", "run_cluster", "run_chunk",
           "connect", "resolve", "captured_output", "describe_jobs", "chunks", "default_chunk", "require",
           "PLUGIN_NAME", "CRASH_VARIABLE", "SLOW_VARIABLE", "TIMEOUT"]
