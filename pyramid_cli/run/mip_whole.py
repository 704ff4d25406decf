"""``pyramid mipmap`` of one 8/16-bit input held whole, level 0 written as stored while the coarser levels are made.

A MIP file's level 0 is the input itself (:attr:`~pyramid_cli.jobs.work.Work.keeps_input`). Where the output
stores every code of the input as the input stores it (an 8-bit sRGB PNG made into an 8-bit ``.tx``:
:meth:`~pyramid_cli.imageio.ImageStream.keeps_stored`), level 0 needs neither decoding nor encoding: its rows as
read are written on a thread of their own while the plan runs, then the coarser levels follow. The codes are not
decoded at all: the CPU executor reads them through their table, band by band on the scheduler, and each band of
each coarser level is encoded as it is made (so a 4K 8-bit picture's .tx holds its codes and the coarser levels'
codes, no floats but a band's). The file is the one :func:`pyramid_cli.run.local.run_jobs` writes (the same
header, the same stored values); only the order of the work changes.

Measured on the bench's 4K inputs (fresh processes interleaved; ``bench/peers.py``): see ``docs/performance.md``.
"""

from __future__ import annotations

import threading
from concurrent import futures
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from pyramid_cli.run.report import announce_compiles, wrote_line
from pyramid_cli.run.weight import HASHERS, LEVEL0_ROWS, stored_codes

WRITE_ROWS = LEVEL0_ROWS  # level 0's rows written between looks at whether the work failed (then the write stops)


@dataclass
class Level0:
    """An input read as stored for a MIP file whose level 0 it is (:func:`level0_as_read`)."""

    path: str
    stored: np.ndarray        # the codes, (H, W, C)
    info: Any                 # the input's ImageInfo
    sha1: Any                 # the unfinished SHA-1 of the source (workflows.mip.sha1_state)
    colors: tuple[list[float], list[float] | None]  # level 0's average and constant colour as stored
    table: np.ndarray         # the float32 value of every code (imageio.read.code_table)


def level0_as_read(st, out_path: str, options: dict) -> Level0 | None:
    """The open :class:`~pyramid_cli.imageio.ImageStream` ``st`` read as stored, with level 0's header statistics,
    when its rows are 8/16-bit codes decoded code by code (:func:`pyramid_cli.imageio.read.code_table`) that the
    output ``out_path`` stores unchanged (:meth:`~pyramid_cli.imageio.ImageStream.keeps_stored`; ``options`` as
    the write takes them); None, having read nothing, otherwise.

    Read :data:`~pyramid_cli.workflows.mip.SHA1_BLOCK` rows at a time, each band hashed on two helper threads while
    the next one is read (:func:`~pyramid_cli.workflows.mip.block_digest`) and summed for the average colour."""
    from pyramid_cli.workflows.mip import SHA1_BLOCK, PixelStats, block_digest, sha1_of_blocks, sha1_state

    h, w, c = st.shape
    table = stored_codes(st, out_path, options)
    if table is None:
        return None
    stats = PixelStats(h)
    stored = np.empty((h, w, c), dtype=st.stored_dtype)
    with ThreadPoolExecutor(HASHERS, thread_name_prefix="pyramid-sha1") as helper:
        digests = []
        for y in range(0, h, SHA1_BLOCK):
            band = stored[y:y + SHA1_BLOCK]
            band[...] = st.read_stored(y, y + len(band))
            digests.append(helper.submit(block_digest, band))
            stats.add_encoded(band)  # level 0 is stored as read
        sha1 = sha1_of_blocks(d.result() for d in digests) if len(digests) > 1 else sha1_state(stored)
    return Level0(st.path, stored, st.info, sha1, (stats.average(), stats.constant()), table)


def make_levels(session, work, level0: Level0, encode, plan=None) -> list[np.ndarray]:
    """The coarser levels of ``level0`` as ``encode`` stores them: from the codes on the CPU executor
    (:func:`_levels_from_codes`, on ``plan``, else the session's), else decoded and run by the session (GL, the
    reference, which runs no plans)."""
    from pyramid_cli.imageio.read import decode_stored
    from pyramid_cli.run.stream import reads_codes

    if reads_codes(session.executor):
        plan = plan if plan is not None else session.plan(work, [level0.stored.shape])
        levels = _levels_from_codes(session.executor, plan, level0.stored, level0.table, encode)
        session.ran = session.name
        return levels
    outs = session.run(work, [decode_stored(level0.stored.copy(), level0.info)], np.float32)
    return [encode(level) for level in outs[1:]]  # outs[0] is the input


def mip_writer(level0: Level0, out_path: str, work, shapes: list[tuple[int, int, int]], tile: int, options: dict):
    """The :func:`~pyramid_cli.imageio.mip_stream_writer` of ``level0``'s MIP file of levels ``shapes`` (rows,
    columns, channels; level 0 first), its header known."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.stream_mip import mip_metadata

    return io.mip_stream_writer(out_path, level0.info, shapes, tile=tile, meta=mip_metadata(work, level0.path,
                                level0.sha1), colors=level0.colors, **options)


def write_levels(writer, level0: Level0, levels: list[np.ndarray], stop: threading.Event | None = None) -> None:
    """Level 0 as read, then ``levels`` as stored, into ``writer`` (:func:`mip_writer`); level 0 stops at its
    next band once ``stop`` is set (its coarser levels are then not written)."""
    stored = level0.stored
    for y in range(0, len(stored), WRITE_ROWS):
        if stop is not None and stop.is_set():
            return
        writer.write_stored(y, stored[y:y + WRITE_ROWS])
    for level in levels:
        writer.append_level(lambda r0, r1, level=level: level[r0:r1], stored=True)


def said(level0: Level0, out_path: str, session, write) -> str:
    """The ``-v`` line of a MIP file written so."""
    from pyramid_cli import imageio as io

    output = io.describe_output(out_path, level0.info, **write.for_inputs([]))
    return f"{io.describe_rules(level0.info)}; {output}; executor {session.ran}; level 0 written as read"


def run_whole(job, work, session, st, plan, *, tile: int, read, write, reporter) -> bool:
    """Write ``job``'s MIP map from the open :class:`~pyramid_cli.imageio.ImageStream` ``st`` with level 0
    as read (:func:`level0_as_read`), on a helper thread while the plan runs and the coarser levels are encoded,
    which are written after it; False, having read nothing, where level 0 cannot be written as read
    (``--constant-color-detect`` on a constant picture: read, then False). A half EXR measured no faster so
    (1.45–1.63 s against 1.42–1.51 s in the same rounds: OpenEXR already reads and compresses on both cores, so
    the overlap only added threads): half inputs run as before."""
    from pyramid_cli import imageio as io

    in_path, out_path = job.input, job.output
    h, w, c = st.shape
    options = write.for_inputs([in_path])
    io.check_write_options(out_path, write.pixel_type, write.compression, write.tocolorspace, read.colorconfig)
    level0 = level0_as_read(st, out_path, options)
    if level0 is None or level0.colors[1] is not None and getattr(work, "constant_detect", False):
        return False  # a constant picture shrinks to one tile: run_jobs does that
    announce_compiles(session, work, [level0.stored], reporter)
    stop = threading.Event()
    shapes = [(h, w, c)] + [plan.images[k].size + (c,) for k in plan.outputs]
    with mip_writer(level0, out_path, work, shapes, tile, options) as writer, \
            ThreadPoolExecutor(1, thread_name_prefix="pyramid-level0") as helper:
        written = helper.submit(write_levels, writer, level0, [], stop)
        try:
            levels = make_levels(session, work, level0, writer.encoder(c).values, plan)
            failed = written.exception()
        except BaseException:  # a failure or a signal: level 0 stops at its next band
            stop.set()
            futures.wait([written])  # the file is not closed under the thread
            raise
        if failed is not None:
            raise failed
        for level in levels:
            writer.append_level(lambda r0, r1, level=level: level[r0:r1], stored=True)
    reporter.detail(said(level0, out_path, session, write))
    reporter.result(wrote_line(out_path, w, h, len(levels) + 1, session.ran))
    return True


def _levels_from_codes(executor, plan, stored: np.ndarray, table: np.ndarray, encode) -> list[np.ndarray]:
    """``plan``'s outputs as ``encode`` stores them, made from the codes ``stored`` read through ``table`` by the
    CPU executor: in bands of rows on the scheduler where the plan tiles, each band encoded as it is made (neither
    a float copy of the codes nor float levels are held: a 4K PNG's .tx took 175 MiB with float levels, 199 MiB
    run whole), else whole. Encoding is pixel by pixel here (no dither): a band encodes as the whole level does."""
    from pyramid_cli.exec import tiles
    from pyramid_cli.run.stream import speed_band

    band = speed_band(plan, executor)
    if band is None:
        return [encode(level) for level in executor.run_outputs(plan, [stored], np.float32, codes=table)]
    outs: dict[int, np.ndarray] = {}

    def source(k, rows, cols):
        return stored[rows[0]:rows[1], cols[0]:cols[1]]

    def sink(k, r, c0, px):
        values = encode(px)
        if k not in outs:
            outs[k] = np.empty(plan.images[k].size + values.shape[2:], values.dtype)
        outs[k][r:r + len(px), c0:c0 + px.shape[1]] = values

    tiles.Scheduler(executor, plan, source, sink, band=band, codes=table).run()
    return [outs[k] for k in plan.outputs]


__all__ = ["Level0", "level0_as_read", "make_levels", "mip_writer", "run_whole", "said", "write_levels"]
