"""``pyramid tiles --cluster``: the tiles (or Zarr chunks) of one picture written in parallel on Dask workers.

The picture is cut into blocks of rows of level-0 tiles, ``2^m`` tile rows each (:func:`split`). One task per
block, on any worker, reads the input rows its block needs (and the guard rows the filter reads), makes levels
1..m of its rows on the band scheduler of :mod:`pyramid_cli.exec.tiles` restricted to them (``windows``: the pixels
of the whole run, since a window start is one more band boundary to it), and writes the tiles of levels 0..m
of its block, overlap included, into the staging folder its client made (shared storage, as every cluster run
of this tool reads and writes on it); it keeps level m's rows of its block (one row of its tiles) in a file
there. One last task makes levels m+1.. from level m with a second levels plan and writes them. The client
then writes the descriptor and moves the tile set into place
(:meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.finish`), or on any failure removes the staging folder and
leaves the previous output as it was.

Byte-identical to a local run: each ⊗↓ step of a levels plan is one pass (or the same passes) from one level
to the next whatever the plan's other levels, so levels m+1.. made from level m are the floats of the one-plan
run (checked on the CPU and GL executors at odd sizes, tests/run/test_tiles_cluster.py), and every tile is
encoded alone. A task run again (its worker lost) writes the same files again. What cannot be split is refused
in one line (exit 2): a TIFF (one file written in order), ``--border wrap`` (its levels are read whole),
``--dither`` (its pattern follows the bands), the reference backend, an array or a Zarr group of the Python API.
A lost cluster, or a task whose workers keep dying, is a :class:`~pyramid_cli.run.cluster.gather.ClusterError`
(exit 6).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from pyramid_cli.core.errors import OutputError, PyramidError, UsageError
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.stream import band_rows, open_input, run_bands

#: Test hook: a file that, while it exists, holds ``always`` (the task of block 1 kills its worker each time it
#: starts) or ``once`` (the first task to create FILE.done kills its worker after writing its tiles: its retry
#: writes them again).
CRASH_VARIABLE = "PYRAMID_TEST_TILES_CRASH"
#: Level m's rows of every block, in the staging folder (removed with it).
LEVELS_FOLDER = ".pyramid-levels"
#: Blocks per worker the default split makes at least (load balance, and what a lost worker costs).
TASKS_PER_WORKER = 2
_POLL = 0.05
_RECONCILE = 5.0


@dataclass(frozen=True)
class PartJob:
    """What one task needs: the input and how it is read, the tile set and where it is staged, the levels."""

    input: str
    output: str
    layout: str
    options: Any            # TileOptions, the tile format settled
    read: Any               # ReadOptions
    analysis: str
    border: str
    root: str               # the staging folder (TileSetWriter.begin)
    split: int              # m: blocks write levels 0..m, the last task m+1..
    block: int = -1         # -1: the last task (levels m+1..)
    blocks: int = 0


def split(n_tile_rows: int, levels: int, workers: int, chunk: int | None = None) -> int:
    """m: blocks of ``2^m`` rows of level-0 tiles (out of ``n_tile_rows``), at most ``levels − 1`` (the coarsest
    level), the largest with at least :data:`TASKS_PER_WORKER` blocks per worker (or as many as there are tile
    rows), and at least 1 (level 1, most of the filtering, is then made in parallel; the last task, which makes
    levels m+1.. alone, has a quarter of it to make at most); ``chunk`` tile rows per task, rounded up to a power
    of two, when given."""
    if chunk is not None:
        return min(levels - 1, max(0, math.ceil(math.log2(max(1, chunk)))))
    want = min(n_tile_rows, TASKS_PER_WORKER * max(1, workers))
    m = min(1, levels - 1)
    while m < levels - 1 and -(-n_tile_rows // 2 ** (m + 1)) >= want:
        m += 1
    return m


def block_rows(writer, m: int, block: int) -> dict[int, tuple[int, int]]:
    """Tile rows ``(first, end)`` of levels 0..m that block ``block`` writes (a level's tile rows, clipped)."""
    out = {}
    for j in range(m + 1):
        n = -(-writer.sizes[j][0] // writer.tile_rows(j))
        out[j] = (min(n, block * 2 ** (m - j)), min(n, (block + 1) * 2 ** (m - j)))
    return out


def kept_rows(writer, m: int, block: int) -> tuple[int, int]:
    """Rows of level m a block keeps for the last task: its one row of level-m tiles, without overlap."""
    t, h = writer.tile_rows(m), writer.sizes[m][0]
    return min(h, block * t), min(h, (block + 1) * t)


def _level_file(root: str, m: int, block: int) -> str:
    return os.path.join(root, LEVELS_FOLDER, f"{m}-{block:06d}.npy")


def _writer(job: PartJob, info, shape):
    from pyramid_cli.imageio import tilesets

    return tilesets.writer_class(job.layout)(job.output, info, shape[:2], shape[2], job.options)


def _open(job: PartJob):
    return open_input(job.input, job.read, keep_half=False)


def _crash(after: bool, block: int) -> None:
    """The test hook :data:`CRASH_VARIABLE`."""
    flag = os.environ.get(CRASH_VARIABLE)
    try:
        mode = open(flag, encoding="utf-8").read().strip() if flag else ""
    except OSError:
        return
    if mode == "always" and block == 1 and not after:
        os._exit(17)
    if mode == "once" and after:
        try:
            os.close(os.open(f"{flag}.done", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return
        os._exit(17)


def write_block(job: PartJob, session) -> dict:
    """A block's task (see the module): levels 0..m of its tile rows written, level m's rows kept on disk; returns
    the writer's :meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.end_part` state."""
    from pyramid_cli.exec import tiles
    from pyramid_cli.jobs.work import Levels

    _crash(False, job.block)
    m = job.split
    with _open(job) as stream:
        h, w, c = stream.shape
        writer = _writer(job, stream.info, stream.shape)
        _decide(session, job, writer, stream.shape)
        rows = block_rows(writer, m, job.block)
        spans = {j: writer.span(j, *rows[j]) for j in rows}
        keep0, keep1 = kept_rows(writer, m, job.block)
        writer.part(job.root, rows)
        try:
            executor = session.executor
            native = np.float64 if executor is not None and executor.work_dtype == np.float64 else np.float32
            kept = np.empty((keep1 - keep0, writer.sizes[m][1], c), native)
            level0 = [spans[0][0]]  # the next input row the writer takes

            def take0(y0: int, px: np.ndarray) -> None:  # input rows, in order: level 0's that the part writes
                a, b = max(y0, level0[0]), min(y0 + px.shape[0], spans[0][1])
                if a < b and a == level0[0]:
                    writer.rows(0, a, px[a - y0:b - y0].astype(np.float32, copy=False))
                    level0[0] = b

            def keep(j: int, y0: int, px: np.ndarray) -> None:
                if j == m:
                    a, b = max(y0, keep0), min(y0 + px.shape[0], keep1)
                    if a < b:
                        kept[a - keep0:b - keep0] = px[a - y0:b - y0]

            if m == 0:  # no level to make: the block's input rows (tile rows and overlap) are level 0
                px = stream.read(*spans[0])
                take0(spans[0][0], px)
                keep(0, spans[0][0], px)
            else:
                plan = session.plan(Levels(levels=m, analysis=job.analysis, border=job.border), [(h, w)])
                slot = {k: j + 1 for j, k in enumerate(plan.outputs)}

                def source(k, span, cols):
                    if span[0] > level0[0] and level0[0] < spans[0][1]:  # rows the plan does not read first
                        take0(level0[0], stream.read(level0[0], min(span[0], spans[0][1])))
                    px = stream.read(*span)
                    take0(span[0], px)
                    px = px[:, cols[0]:cols[1]] if (cols[0], cols[1]) != (0, w) else px
                    return px.astype(native, copy=False)

                def sink(k, r, c0, px):
                    writer.rows(slot[k], r, px.astype(np.float32, copy=False), owned=True)  # never written again
                    keep(slot[k], r, px)

                windows = {k: spans[slot[k]] for k in plan.outputs}
                band = band_rows(plan.images[plan.outputs[0]].size[1])
                tiles.Scheduler(executor, plan, source, sink, band=band, dtype=native, windows=windows).run()
            if level0[0] < spans[0][1]:
                take0(level0[0], stream.read(level0[0], spans[0][1]))
            state = writer.end_part()
        except BaseException:
            writer.abort()
            raise
    _save(_level_file(job.root, m, job.block), kept)
    _crash(True, job.block)
    return state


def _decide(session, job: PartJob, writer, shape) -> None:
    """``auto`` chooses the executor of a worker's session for the whole pyramid, as the local run does for its
    one plan (later tasks of the worker keep the choice), not for a part."""
    from pyramid_cli.jobs.work import Levels

    if len(writer.sizes) > 1:
        session.decide(Levels(levels=len(writer.sizes) - 1, analysis=job.analysis, border=job.border),
                       [tuple(shape)], dtype=np.float32)


def _save(path: str, array: np.ndarray) -> None:
    """``array`` to ``path`` whole or not at all (a retried task writes it again); never the staging folder itself
    again (a client that gave up removed it: this task then fails, unheard)."""
    with contextlib.suppress(FileExistsError):
        os.mkdir(os.path.dirname(path))
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "wb") as f:
        np.save(f, array)
    os.replace(tmp, path)


def write_coarse(job: PartJob, session) -> dict:
    """The last task: levels m+1.. made from level m's rows (the blocks' files) with a second levels plan, and
    written; returns the writer's part state."""
    from pyramid_cli.jobs.work import Levels

    m = job.split
    with _open(job) as stream:
        info, shape = stream.info, stream.shape
    writer = _writer(job, info, shape)
    _decide(session, job, writer, shape)
    count = len(writer.sizes)
    parts = [np.load(_level_file(job.root, m, b), mmap_mode="r") for b in range(job.blocks)]
    starts = np.cumsum([0] + [p.shape[0] for p in parts])

    def read(y0: int, y1: int) -> np.ndarray:
        pieces = []
        for b, p in enumerate(parts):
            a, e = max(y0, starts[b]), min(y1, starts[b + 1])
            if a < e:
                pieces.append(p[a - starts[b]:e - starts[b]])
        return np.ascontiguousarray(np.concatenate(pieces) if len(pieces) > 1 else pieces[0])

    hm, wm = writer.sizes[m]
    if starts[-1] != hm:
        raise RuntimeError(f"level {m} has {starts[-1]} rows from the blocks, not {hm}")
    writer.part(job.root, {k: (0, -(-writer.sizes[k][0] // writer.tile_rows(k))) for k in range(m + 1, count)})
    try:
        plan = session.plan(Levels(levels=count - 1 - m, analysis=job.analysis, border=job.border), [(hm, wm)])

        def level(j: int, y0: int, px: np.ndarray) -> None:
            writer.rows(m + 1 + j, y0, px.astype(np.float32, copy=False), owned=True)

        run_bands(read, plan, session.executor, band_rows(plan.images[plan.outputs[0]].size[1]), level)
        return writer.end_part()
    except BaseException:
        writer.abort()
        raise


def run_task(job: PartJob, plugin: str):
    """A cluster task (a block, or the last one) on this worker's session: ``("ok", state, executor)``, or
    ``("error", exception)`` for an error of this tool (a bad input, a full disk), which a retry would not mend."""
    from distributed import get_worker

    from pyramid_cli.run.cluster.worker import SessionPlugin

    holder = get_worker().plugins[plugin]
    assert isinstance(holder, SessionPlugin) and holder.lock is not None, "registered by the client, set up by Dask"
    with holder.lock:
        session = holder.acquire()
        try:
            state = write_block(job, session) if job.block >= 0 else write_coarse(job, session)
        except PyramidError as exc:
            return ("error", exc)
        return ("ok", state, session.name)


def refuse(layout: str, writer, settings, spec, where: str) -> None:
    """What a split run cannot do, refused in one line (UsageError) before the cluster is reached."""
    if not writer.parallel:
        raise UsageError(f"{where}: --cluster: a {layout} tile set is one file written in order; leave out "
                         "--cluster (the layouts dz, iiif3, iiif and ome-zarr are written in parallel)")
    if settings.border == "wrap":
        raise UsageError(f"{where}: --cluster: --border wrap reads every level whole; leave out --cluster")
    if settings.options.write.get("dither"):
        raise UsageError(f"{where}: --cluster: --dither's pattern follows the bands of one process; leave out "
                         "--cluster or --dither")
    if getattr(spec, "backend", "auto") == "reference":
        raise UsageError(f"{where}: --cluster needs a plan executor (--backend auto, cpu or gl): the reference "
                         "backend holds whole pictures")


def tile_cluster(in_path: str, out: str, settings, cluster, *, settle: Callable, spec=None, read=None,
                 reporter: Reporter | None = None, force: bool = False, timeout: float | None = None,
                 chunk: int | None = None, retries: int = 2, label: str | None = None) -> dict:
    """:func:`~pyramid_cli.run.tiles.tile_file` on a Dask cluster (see the module): the same tile set, byte for
    byte, and the same description, with ``cluster`` (address, workers, tasks, split level) added.

    ``cluster``: an address, a scheduler file, ``local:N`` or a ``distributed.Client``; ``spec``: the workers'
    :class:`~pyramid_cli.run.cluster.worker.SessionSpec`; ``chunk``: rows of level-0 tiles per task (a power of two);
    ``label``: what to call a Client given as ``cluster`` in messages; ``settle(layout, options, info, reporter,
    where)``: the tile options with the tile format settled for the input (:func:`pyramid_cli.run.tiles.tile_format`).
    """
    from pyramid_cli.imageio import tilesets
    from pyramid_cli.jobs.work import Levels
    from pyramid_cli.run import cluster as dask_run
    from pyramid_cli.run.settings import ReadOptions

    reporter = reporter or Reporter()
    started = time.perf_counter()
    spec = spec if isinstance(spec, dask_run.SessionSpec) else dask_run.SessionSpec(
        getattr(spec, "backend", "auto"), getattr(spec, "precision", "float"))
    timeout = dask_run.TIMEOUT if timeout is None else float(timeout)
    if timeout <= 0:
        raise UsageError(f"--cluster-timeout {timeout:g}: a number of seconds > 0")
    where, shown = in_path, out  # as the user gave them, for messages; absolute for the workers
    in_path, out = os.path.abspath(in_path), os.path.abspath(out)
    layout = tilesets.layout_of(out, settings.layout)
    if not force and os.path.exists(out) and os.path.samefile(in_path, out):
        raise OutputError(f"refusing to overwrite input {shown} (use --force)")
    read = read or ReadOptions()
    probe = PartJob(in_path, out, layout, settings.options, read, settings.analysis, settings.border, "", 0)
    with _open(probe) as stream:
        info, shape = stream.info, stream.shape
    options = settle(layout, settings.options, info, reporter, where)
    writer = tilesets.writer_class(layout)(shown, info, shape[:2], shape[2], options)
    writer.check()
    refuse(layout, writer, settings, spec, where)
    sizes = writer.sizes
    if len(sizes) > 1:
        Levels(levels=len(sizes) - 1, analysis=settings.analysis, border=settings.border).check(
            (shape[:2],), where=where)
    dask_run.require()
    if isinstance(cluster, (str, os.PathLike)):
        cluster = dask_run.resolve(cluster, timeout)  # before Dask's import: a refused address fails at once
    import distributed  # noqa: F401 - its import sets up its loggers, which captured_output() then replaces

    base = PartJob(in_path, out, layout, options, read, settings.analysis, settings.border, "", 0)
    with dask_run.captured_output() as (captured, warned):
        try:
            with dask_run.connect(cluster, timeout) as (client, named):
                label = label or named
                client.register_plugin(dask_run.SessionPlugin(spec), name=spec.plugin_name)
                workers = len(client.nthreads())
                n0 = -(-sizes[0][0] // writer.tile_rows(0))
                m = split(n0, len(sizes), workers, chunk)
                blocks = -(-n0 // 2 ** m)
                reporter.detail(f"cluster {label}: {workers} worker(s); {blocks} task(s) of {2 ** m} row(s) of "
                                f"level-0 tiles writing levels 0..{m}"
                                + (f", then one task levels {m + 1}..{len(sizes) - 1}" if m < len(sizes) - 1 else ""))
                root = writer.begin()
                try:
                    job = dataclasses.replace(base, root=root, split=m, blocks=blocks)
                    tasks = _Tasks(client, label, spec.plugin_name, timeout, retries)
                    states = tasks.run([dataclasses.replace(job, block=b) for b in range(blocks)])
                    if m < len(sizes) - 1:
                        states += tasks.run([job])
                    writer.merge(states)
                    report = writer.finish()
                except BaseException:
                    with contextlib.suppress(Exception):
                        writer.abort()
                    raise
        finally:
            from pyramid_cli.run.cluster.logs import summarise

            summarise(captured, warned, reporter)
    ran = tasks.executor or spec.backend
    report = {**report, "path": shown, "input": where, "backend": ran, "analysis": settings.analysis,
              "border": settings.border, "band": None, "seconds": round(time.perf_counter() - started, 3),
              "cluster": {"address": label, "workers": workers, "tasks": blocks + (m < len(sizes) - 1),
                          "split_level": m}}
    h, w = shape[:2]
    reporter.result(f"wrote {shown} ({w}×{h}, {len(sizes)} levels, {layout}, {ran}, on cluster {label} in "
                    f"{report['cluster']['tasks']} tasks)")
    return report


@contextlib.contextmanager
def connection(cluster, timeout: float | None, reporter: Reporter, many: bool) -> Iterator[tuple[Any, str | None]]:
    """Where the pictures of a run go, as :func:`tile_cluster` takes it, with the name to call it in messages: None
    (no cluster), ``cluster`` itself for one picture (refusals come before a cluster is reached), else one
    connection for the batch (a ``local:N`` cluster started once)."""
    if cluster is None or not many:
        yield cluster, None
        return
    from pyramid_cli.run import cluster as dask_run

    dask_run.require()
    timeout = dask_run.TIMEOUT if timeout is None else timeout
    where = dask_run.resolve(cluster, timeout) if isinstance(cluster, (str, os.PathLike)) else cluster
    import distributed  # noqa: F401 - its loggers set up before captured_output() replaces them

    with dask_run.captured_output() as (captured, warned):
        try:
            with dask_run.connect(where, timeout) as (client, label):
                yield client, label
        finally:
            from pyramid_cli.run.cluster.logs import summarise

            summarise(captured, warned, reporter)


def tiles_on_cluster(path, out, settings, cluster, *, settle: Callable, backend: str = "auto", session=None,
                     read=None, memory: int | None = None, chunk: int | None = None,
                     timeout: float | None = None) -> dict:
    """``pyr.tiles(path, out, cluster=...)`` (:func:`pyramid_cli.run.tiles.tiles`): an image file's tile set written
    on a Dask cluster by :func:`tile_cluster`; an array, a Zarr group and ``memory`` are refused (UsageError)."""
    from pyramid_cli.run.cluster import SessionSpec
    from pyramid_cli.run.report import PythonReporter

    if not isinstance(path, (str, os.PathLike)):
        raise UsageError("cluster=: the workers read an image file; an array is written in this process (leave out "
                         "cluster=)")
    if not isinstance(out, (str, os.PathLike)):
        raise UsageError("cluster=: the workers write into a staging folder beside a path; give out as a path")
    if memory is not None:
        raise UsageError("memory= is not for cluster= runs: each worker streams its rows of tiles in bands of its own")
    spec = SessionSpec(backend) if session is None else SessionSpec(session.backend, session.precision)
    return tile_cluster(os.fspath(path), os.fspath(out), settings, cluster, settle=settle, spec=spec, read=read,
                        reporter=PythonReporter(quiet=True), timeout=timeout, chunk=chunk)


class _Tasks:
    """Submits tasks and waits for them all, watching the scheduler and the workers (see the module)."""

    def __init__(self, client, label: str, plugin: str, timeout: float, retries: int):
        self.client, self.label, self.plugin, self.timeout, self.retries = client, label, plugin, timeout, retries
        self.batch = uuid.uuid4().hex[:8]
        self.executor = ""

    def run(self, jobs: list[PartJob]) -> list[dict]:
        from distributed import as_completed

        futures = [self.client.submit(run_task, job, self.plugin, key=f"pyramid-tiles-{self.batch}-{job.block:+06d}",
                                      retries=self.retries, pure=False) for job in jobs]
        by_key = {f.key: job for f, job in zip(futures, jobs, strict=True)}
        states: list[dict] = []
        try:
            pending = as_completed(futures, loop=self.client.loop, with_results=True, raise_errors=False)
            reconciled, no_worker = time.monotonic(), None
            while not pending.is_empty():
                for future, value in pending.next_batch(block=False):
                    states.append(self._take(by_key[future.key], future, value))
                now = time.monotonic()
                if self.client.status != "running":
                    raise self._lost("lost the scheduler")
                if now - reconciled > _RECONCILE:
                    reconciled = now
                    with contextlib.suppress(Exception):
                        if self.client.nthreads():
                            no_worker = None
                        elif no_worker is None:
                            no_worker = now
                if no_worker is not None and now - no_worker >= self.timeout:
                    raise self._lost(f"no worker connected for {self.timeout:g} s (--cluster-timeout)")
                time.sleep(_POLL)
        except BaseException:
            with contextlib.suppress(Exception):
                self.client.cancel([f for f in futures if not f.done()], force=True)
            raise
        return states

    def _lost(self, reason: str):
        from pyramid_cli.run.cluster import ClusterError

        return ClusterError(f"cluster {self.label}: {reason}; the tile set was not written")

    def _take(self, job: PartJob, future, value) -> dict:
        from concurrent.futures import CancelledError

        from distributed.scheduler import KilledWorker

        from pyramid_cli.run.cluster import ClusterError
        from pyramid_cli.run.cluster.connection import one_line

        if isinstance(value, tuple) and value and value[0] == "ok":
            self.executor = value[2] or self.executor
            return value[1]
        if isinstance(value, tuple) and value and value[0] == "error":
            raise value[1]
        what = f"the task of tile rows {job.block * 2 ** job.split}.. " if job.block >= 0 else "the last task "
        if isinstance(value, CancelledError) or future.status == "cancelled":
            raise self._lost("lost the scheduler")
        error = value[1] if isinstance(value, tuple) and len(value) == 3 else value
        if isinstance(error, KilledWorker):
            raise ClusterError(f"cluster {self.label}: {what}killed its workers more often than the scheduler "
                               "allows (distributed.scheduler.allowed-failures); the tile set was not written")
        raised = one_line(error) if isinstance(error, BaseException) else repr(error)
        raise PyramidError(f"cluster {self.label}: {what}raised {raised}; the tile set was not written")


__all__ = ["CRASH_VARIABLE", "PartJob", "split", "block_rows", "kept_rows", "write_block", "write_coarse", "run_task",
           "refuse", "tile_cluster", "connection", "tiles_on_cluster"]
