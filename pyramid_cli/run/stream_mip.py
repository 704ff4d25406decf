"""``pyramid mipmap`` of one input streamed: a MIP file's level 0 comes first, its header before its rows.

:func:`run_mip` runs the plan on the row-band scheduler as :mod:`pyramid_cli.run.stream` does, with the
decoding and the writing of level 0 overlapped (:mod:`pyramid_cli.run.overlap`), and keeps the coarser
levels (:class:`~pyramid_cli.imageio.spill.KeptRows`: in memory or in a temporary file beside the output)
until level 0 is written.
"""

from __future__ import annotations

import contextlib

import numpy as np

from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.imageio.spill import KeptRows
from pyramid_cli.run.budget import resolve
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.overlap import overlapped
from pyramid_cli.run.stream import (
    MIN_BAND,
    choose_mip,
    costs,
    executor_of,
    open_input,
    read_step,
    warn_nonfinite,
)
from pyramid_cli.run.weight import mip_codes_bytes, mip_from_codes


@contextlib.contextmanager
def _scratch(beside: str):
    """A hidden temporary file beside ``beside`` (as :mod:`pyramid_cli.imageio.atomic` names them), removed on success,
    failure and interruption alike."""
    from pyramid_cli.imageio.atomic import make_temp, remove_quietly

    tmp = make_temp(beside + ".levels")
    try:
        yield tmp
    finally:
        remove_quietly(tmp)


# mipmap options that need the whole picture before the levels: they run whole
_MIP_WHOLE = {"resize": "--resize", "fill": "--fill", "nchannels": "--nchannels",
              "monochrome_detect": "--monochrome-detect"}


def mip_metadata(work, path: str, state=None) -> dict[str, str]:
    """The attributes ``pyramid mipmap`` gives level 0 besides the colours
    (:func:`pyramid_cli.workflows.mip.texture_metadata`):
    the SHA-1 from ``state`` (:func:`pyramid_cli.workflows.mip.sha1_state`), else hashed from the file ``path``."""
    from pyramid_cli import imageio as io
    from pyramid_cli.workflows.mip import finish_sha1, hash_extra, texture_metadata

    border = getattr(work, "border", "clamp")
    analysis = getattr(work, "filter_name", getattr(work, "analysis", ""))
    extra = hash_extra(border, analysis)
    sha1 = finish_sha1(state, extra) if state is not None else io.source_sha1(path, extra)
    return texture_metadata(border, analysis, sha1, io.oiio_version())


def _level0_stats(st, stats, step: int, out_path: str, options: dict):
    """Read ``st`` once, ``step`` rows at a time, into ``stats`` (a :class:`pyramid_cli.workflows.mip.PixelStats`): the
    SHA-1 of the rows as stored, the average and constant colour of level 0 as decoded and as encoded. (A
    function of its own so that no band outlives the pass: the last one stayed alive through the second.)"""
    from pyramid_cli import imageio as io

    h = st.shape[0]
    enc = io.Encoder(out_path, st.info, st.shape[2], check_path=False, **options)
    st.on_stored = stats.hash_rows
    try:
        for y in range(0, h, step):
            px = st.read(y, min(h, y + step)).astype(np.float32, copy=False)
            stats.add_decoded(px)
            stats.add_encoded(enc.values(px))
    finally:
        st.on_stored = None
    return stats


def run_mip(job, work, session, *, memory: int | None, tile: int, read=None, write=None, reporter=None,
            whole=None, limits: contextlib.ExitStack | None = None) -> bool:
    """``pyramid mipmap`` of one input streamed when its whole run would not fit the budget (``memory``, else
    :func:`pyramid_cli.run.budget.default_budget`); False when it runs whole as before. A whole run has
    OpenEXR's codec threads limited to what the budget leaves them until ``limits`` closes
    (:meth:`~pyramid_cli.run.codec_budget.Codecs.hold`).

    Level 0's header must say, before its first row, the SHA-1 of the source, the average and constant colour
    of level 0 as stored (:class:`pyramid_cli.workflows.mip.PixelStats`) and, under ``--constant-color-detect``, whether
    the picture is constant (then it shrinks to one tile and runs whole, as before: it is small). The input is
    read once when level 0 can be kept in memory until then (:func:`choose_mip`): the plan runs on the row-band
    scheduler while the statistics are gathered, then level 0 and the coarser levels are written. Otherwise it
    is read twice: first band by band for the header, then through the scheduler with level 0 written as it is
    read. The coarser levels are kept in memory when they fit the budget beside the working set, else in a
    temporary file beside the output, removed on success, failure and interruption. Refused before any work:
    the options that need the whole picture (``--resize``, ``--fill``, ``--nchannels``, ``--monochrome-detect``)
    and plans that do not tile (:func:`pyramid_cli.exec.tiles.tileable`), when ``memory`` is given (without it they
    run whole).

    When it runs whole, ``whole`` (:func:`pyramid_cli.run.mip_whole.run_whole`) is given the open input and the
    plan, and may write the file itself (True); False leaves it to the caller.
    """
    from pyramid_cli import imageio as io
    from pyramid_cli.exec import tiles
    from pyramid_cli.run.report import Reporter
    from pyramid_cli.run.settings import ReadOptions, WriteOptions
    from pyramid_cli.workflows.mip import PixelStats

    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    whole_only = [flag for name, flag in _MIP_WHOLE.items() if getattr(work, name, False)]
    if session is None or session.executor is None:
        if memory is not None:
            executor_of(session)  # refuses with the reason
        return False
    if whole_only or not io.streams_to(job.output) or not work.keeps_input:
        if memory is not None:
            why = (f"{', '.join(whole_only)} need(s) the whole picture" if whole_only
                   else f"{job.output} is encoded whole")
            raise UsageError(f"--memory: mipmap cannot stream here ({why}); leave --memory out to run it whole")
        return False
    given = resolve(memory)
    budget = given.size
    reporter.detail(f"{job.input}: {given.describe()}")
    in_path, out_path = job.input, job.output
    executor = executor_of(session)
    emu = executor.work_dtype == np.float64

    with contextlib.ExitStack() as stack:
        st = stack.enter_context(open_input(in_path, ro))
        h, w, c = st.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        if plan is None:
            return False
        kw = {"in_bytes": st.dtype.itemsize, "where": in_path, **costs(executor)}
        # no preference for bands here (stream.speed_band): measured, fresh processes interleaved, a 4K 8-bit PNG's
        # .tx took 2.32 CPU seconds and 445 MiB streamed against 1.77 s and 388 MiB whole (level 0 and the
        # coarser levels are kept until level 0's header is known, so bands save little): it streams when it must
        options = wo.for_inputs([in_path])
        codecs = Codecs.of([st], [(out_path, (h, w))], st.info, c, options, tile)
        whole_run = None  # the whole run's bytes where run_whole makes it from the codes, else choose_mip's estimate
        if whole and mip_from_codes(st, out_path, options, executor):
            whole_run = mip_codes_bytes(plan, st, executor)
        try:
            choice = choose_mip(plan, c, budget, level0=h * w * c * st.dtype.itemsize, codecs=codecs.first,
                                whole=whole_run, **kw)
        except DataError as exc:
            raise given.refusal(exc) from None
        reporter.detail(f"{in_path}: {choice.describe()}")
        band = choice.band
        if band is None:  # runs whole (not Choice.streams): by ``whole`` where it says it can
            codecs.hold(limits, choice, reporter, in_path)
            return bool(whole) and whole(job, work, session, st, plan, tile=tile, read=ro, write=wo,
                                         reporter=reporter)
        if not tiles.tileable(plan):
            if memory is not None:
                raise UsageError(f"--memory: the MIP levels of a {w}×{h} picture cannot stream (a pass of its plan "
                                 "does not tile); leave --memory out to run it whole")
            return False
        shapes = [(h, w, c)] + [plan.images[k].size + (c,) for k in plan.outputs]
        info = st.info
        io.check_write_options(out_path, wo.pixel_type, wo.compression)  # refused before any work
        stack.enter_context(codecs.within(choice, reporter, in_path))
        step = 2 * max(MIN_BAND, band)  # level 0's rows at a time outside the scheduler (multiples of 8)
        stats = PixelStats(h)
        once = bool(choice.level0)
        if once:  # level 0 kept as read while the scheduler runs; its header's statistics gathered on the way
            level0 = KeptRows([shapes[0]], None, st.dtype)
            st.on_stored = stats.hash_rows
        else:  # the first read, for the header; the scheduler reads again, writing level 0 as it reads it
            _level0_stats(st, stats, step, out_path, options)
            if _constant(work, stats):
                return _write_constant(work, session, stats, shapes[0], tile, in_path, out_path, info, options,
                                       reporter)
            st = stack.enter_context(open_input(in_path, ro))
        kept = KeptRows(shapes[1:], stack.enter_context(_scratch(out_path)) if choice.spill else None,
                        beside=out_path, what="coarser MIP levels")
        stack.callback(kept.close)

        def open_writer():
            meta = mip_metadata(work, in_path, stats.sha1())
            return stack.enter_context(io.mip_stream_writer(out_path, info, shapes, tile=tile, meta=meta,
                                                            colors=(stats.average(), stats.constant()), **options))

        writer = None if once else open_writer()
        slot = {k: i for i, k in enumerate(plan.outputs)}

        encoded = [0]  # level 0's rows gathered as encoded: in the bands of the two-read way (dithering lines up)
        enc = io.Encoder(out_path, info, c, check_path=False, **options)

        def keep_level0(y: int, px: np.ndarray) -> None:  # on the writer's thread, beside the work
            level0.write(0, y, px)
            stats.add_decoded(px)
            while encoded[0] < h and y + len(px) >= min(h, encoded[0] + step):
                a, b = encoded[0], min(h, encoded[0] + step)
                rows = level0.rows(0, a, b).astype(np.float32, copy=False)
                stats.add_encoded(enc.values(rows))
                encoded[0] = b

        with overlapped(st.read, h, read_step(plan, band)) as (reader, behind):
            def source(k, rows, cols):
                px = reader.rows(*rows)
                if once:
                    behind.call(keep_level0, rows[0], px)
                else:  # level 0: each row once, in order
                    behind.call(writer.write, rows[0], px.astype(np.float32, copy=False))
                px = px[:, cols[0]:cols[1]] if (cols[0], cols[1]) != (0, w) else px
                return px.astype(np.float64) if emu else px

            def sink(k, r, c0, px):
                kept.write(slot[k], r, px)

            tiles.Scheduler(executor, plan, source, sink, band=band,
                            dtype=np.float64 if emu else np.float32).run()
        if once:
            st.on_stored = None
            if encoded[0] != h:
                raise RuntimeError(f"level 0: {encoded[0]} of {h} rows gathered")
            if _constant(work, stats):
                return _write_constant(work, session, stats, shapes[0], tile, in_path, out_path, info, options,
                                       reporter)
            writer = open_writer()
            for y in range(0, h, step):
                writer.write(y, level0.rows(0, y, min(h, y + step)).astype(np.float32, copy=False))
        assert writer is not None, "opened before the scheduler ran, or after it when level 0 was kept"
        for i in range(len(shapes) - 1):
            writer.append_level(lambda r0, r1, i=i: kept.rows(i, r0, r1))
    session.ran = session.name
    warn_nonfinite([st], ro, reporter)
    reporter.result(f"wrote {out_path} ({w}×{h}, {len(shapes)} MIP levels, {session.ran}, streamed in bands of "
                    f"{band} rows{', the input read once' if once else ''})")
    return True


def _constant(work, stats) -> bool:
    return bool(getattr(work, "constant_detect", False) and stats.decoded_constant)


def _write_constant(work, session, stats, shape, tile: int, in_path: str, out_path: str, info, options,
                    reporter) -> bool:
    """``--constant-color-detect`` on a constant picture: one tile of its colour, run and written whole."""
    from pyramid_cli import imageio as io
    from pyramid_cli.workflows.mip import shrink_constant

    h, w, c = shape
    first = stats.decoded_first.astype(np.float32)
    small = shrink_constant(np.broadcast_to(first, (min(tile, h), min(tile, w), c)), tile)
    assert small is not None, "one colour broadcast is constant"
    reporter.detail(f"{in_path}: constant colour, made from one {small.shape[1]}×{small.shape[0]} tile")
    outs = session.run(work, [small], np.float32)
    io.write_levels(out_path, [io.Image(px, info) for px in outs], mode="mipmap", tile=tile,
                    meta=mip_metadata(work, in_path, stats.sha1()), **options)
    reporter.result(f"wrote {out_path} ({w}×{h}, {len(outs)} MIP levels, {session.ran})")
    return True


__all__ = ["run_mip", "mip_metadata"]
