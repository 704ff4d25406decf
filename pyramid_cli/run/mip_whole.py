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

import numpy as np

from pyramid_cli.run.report import announce_compiles, wrote_line

WRITE_ROWS = 256  # level 0's rows written between looks at whether the work failed (then the write stops)


def run_whole(job, work, session, st, plan, *, tile: int, read, write, reporter) -> bool:
    """Write ``job``'s MIP map from the open :class:`~pyramid_cli.imageio.ImageStream` ``st`` with level 0
    as stored, beside the work (see the module); False, having read nothing, when the input's rows are not 8/16-bit
    codes the CPU executor reads through their table (:func:`pyramid_cli.run.tiles.executor_codes`) or the output
    would not store them unchanged (``--constant-color-detect`` on a constant picture: read, then False).

    The input is read :data:`~pyramid_cli.workflows.mip.SHA1_BLOCK` rows at a time; each band is hashed for level
    0's header on two helper threads while the next one is read (:func:`~pyramid_cli.workflows.mip.block_digest`)
    and summed for its average colour (:class:`~pyramid_cli.workflows.mip.PixelStats`). Level 0 is then written on
    a helper thread while the plan runs on the codes and the coarser levels are encoded, and they are written after
    it. (A half EXR measured no faster so, 1.45–1.63 s against 1.42–1.51 s in the same rounds: OpenEXR already reads
    and compresses on both cores, so the overlap only added threads; it runs as before.)"""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.stream_mip import mip_metadata
    from pyramid_cli.run.tiles import executor_codes
    from pyramid_cli.workflows.mip import SHA1_BLOCK, PixelStats, block_digest, sha1_of_blocks, sha1_state

    in_path, out_path = job.input, job.output
    h, w, c = st.shape
    options = write.for_inputs([in_path])
    io.check_write_options(out_path, write.pixel_type, write.compression, write.tocolorspace, read.colorconfig)
    table = executor_codes(st, session.executor)
    if table is None or not st.keeps_stored(io.Encoder(out_path, st.info, c, check_path=False, **options)):
        return False
    stats = PixelStats(h)
    stored = np.empty((h, w, c), dtype=st.stored_dtype)
    stop = threading.Event()
    with ThreadPoolExecutor(2, thread_name_prefix="pyramid-level0") as helper:
        digests = []
        for y in range(0, h, SHA1_BLOCK):
            band = stored[y:y + SHA1_BLOCK]
            band[...] = st.read_stored(y, y + len(band))
            digests.append(helper.submit(block_digest, band))
            stats.add_encoded(band)  # level 0 is stored as read
        state = sha1_of_blocks(d.result() for d in digests) if len(digests) > 1 else sha1_state(stored)
        if stats.constant() is not None and getattr(work, "constant_detect", False):
            return False  # shrinks to one tile: run_jobs does that
        announce_compiles(session, work, [stored], reporter)
        shapes = [(h, w, c)] + [plan.images[k].size + (c,) for k in plan.outputs]
        meta = mip_metadata(work, in_path, state)
        with io.mip_stream_writer(out_path, st.info, shapes, tile=tile, meta=meta,
                                  colors=(stats.average(), stats.constant()), **options) as writer:
            written = helper.submit(_level0, writer, stored, stop)
            try:
                levels = _levels_from_codes(session.executor, plan, stored, table, writer.encoder(c).values)
                session.ran = session.name
                failed = written.exception()
            except BaseException:  # a failure or a signal: level 0 stops at its next band
                stop.set()
                futures.wait([written])  # the file is not closed under the thread
                raise
            if failed is not None:
                raise failed
            del stored
            for level in levels:
                writer.append_level(lambda r0, r1, level=level: level[r0:r1], stored=True)
    output = io.describe_output(out_path, st.info, **write.for_inputs([]))
    reporter.detail(f"{io.describe_rules(st.info)}; {output}; executor {session.ran}; level 0 written as read")
    reporter.result(wrote_line(out_path, w, h, len(shapes), session.ran))
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


def _level0(writer, stored: np.ndarray, stop: threading.Event) -> None:
    for y in range(0, len(stored), WRITE_ROWS):
        if stop.is_set():
            return
        writer.write_stored(y, stored[y:y + WRITE_ROWS])


__all__ = ["run_whole"]
