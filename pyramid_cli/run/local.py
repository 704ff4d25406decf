"""The local runner: read → run → write a list of jobs on one session, in this process.

:func:`pyramid_cli.run.pipeline.process` calls it for a batch on this machine (:func:`run_in_budget`), and each
Dask worker for its chunk (:mod:`pyramid_cli.run.cluster`).
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable

import numpy as np

from pyramid_cli import imageio as io
from pyramid_cli.core.errors import PyramidError
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.work import Work
from pyramid_cli.run import batch, mip_whole
from pyramid_cli.run.inputs import read_input
from pyramid_cli.run.report import Reporter, announce_compiles, wrote_line
from pyramid_cli.run.settings import ReadOptions, WriteOptions


def texture_channels(image: io.Image, work, path: str, reporter: Reporter) -> io.Image:
    """maketx's ``--monochrome-detect`` and ``--nchannels`` on a texture's source
    (:func:`pyramid_cli.workflows.mip.channel_plan`); ``-v`` says what changed."""
    import dataclasses

    from pyramid_cli.workflows.mip import apply_channels, channel_plan, is_monochrome

    spec, px = image.spec, image.pixels
    n = px.shape[2]
    mono = work.monochrome_detect and n == 3 and spec.alpha_channel < 0 and is_monochrome(px)
    change = channel_plan(n, list(spec.channel_names), spec.alpha_channel, work.nchannels, work.monochrome_detect,
                          mono)
    if change is None:
        return image
    kept, names, alpha = change
    reporter.detail(f"{path}: {n} channel(s) → {len(names)} ({', '.join(names)})"
                    + (": monochrome" if mono and work.nchannels is None else ""))
    new = dataclasses.replace(spec, channel_names=names, alpha_channel=alpha,
                              alpha_mode=spec.alpha_mode if alpha >= 0 else "none", channel_pixel_types=[])
    return io.Image(apply_channels(px, kept, len(names)), new)


def _level0_as_read(job, read: ReadOptions, write: WriteOptions):
    """:func:`pyramid_cli.run.mip_whole.level0_as_read` of ``job``'s input, or None."""
    from pyramid_cli.run.stream import open_input

    with open_input(job.input, read) as st:
        return mip_whole.level0_as_read(st, job.output, write.for_inputs([job.input]))


def run_jobs(job_list: list[batch.Job], work: Work, session: Session, *, read: ReadOptions, write: WriteOptions,
             reporter: Reporter, keep_going: bool = False, skip_existing: bool = False, jobs: int = 2,
             mip_tile: int | None = None, many: bool = True) -> batch.Report:
    """Read → run → write every job of ``job_list`` on this machine's ``session``, decoding and encoding in
    ``jobs`` threads beside the work (:func:`pyramid_cli.run.batch.run`); a cluster's workers run their chunks
    with it too. With ``mip_tile`` each output is one tiled MIP-mapped file."""
    ro, wo = read, write
    first = io.read_shape(job_list[0].input) if job_list else None
    if first is not None:  # auto decides for the whole list (a cluster worker's chunk too); numba loads meanwhile
        session.prepare_async(work, [first], count=len(job_list))

    def prepare(job):
        shape = io.read_shape(job.input)
        if shape is not None:
            session.prepare(work, [shape[:2]])

    def read_job(job):
        # refused before any work
        io.check_write_options(job.output, wo.pixel_type, wo.compression, wo.tocolorspace, ro.colorconfig)
        if as_read:  # a MIP file's level 0 written as read where it can be (8/16-bit codes the output keeps)
            level0 = _level0_as_read(job, ro, wo)
            if level0 is not None:
                work.check((level0.stored.shape[:2],), where=job.input)
                return job, level0
        image = read_input(job.input, ro, reporter, keep_half=True, hash_source=bool(mip_tile))  # no float32 copy
        if mip_tile and getattr(work, "constant_detect", False):
            from pyramid_cli.workflows.mip import shrink_constant

            small = shrink_constant(image.pixels, mip_tile)
            if small is not None and small.shape != image.pixels.shape:
                reporter.detail(f"{job.input}: constant colour, made from one {small.shape[1]}×{small.shape[0]} tile")
                image = io.Image(small, image.spec)
        if mip_tile and (getattr(work, "nchannels", None) or getattr(work, "monochrome_detect", False)):
            image = texture_channels(image, work, job.input, reporter)
        work.check((image.pixels.shape[:2],), where=job.input)
        return job, image

    announced: list[bool] = []
    as_read = bool(mip_tile) and work.keeps_input and not any(
        getattr(work, name, False) for name in ("fill", "nchannels", "monochrome_detect", "constant_detect"))

    def compute(job_image):
        job, image = job_image
        if isinstance(image, mip_whole.Level0):
            if not announced:
                announced.append(True)
                announce_compiles(session, work, [image.stored], reporter)
            enc = io.Encoder(job.output, image.info, image.stored.shape[2], check_path=False,
                             **wo.for_inputs([job.input]))
            levels = mip_whole.make_levels(session, work, image, enc.values)
            reporter.detail(mip_whole.said(image, job.output, session, wo))
            return image, levels
        if mip_tile and getattr(work, "fill", False):  # mipmap --fill: pull-push before the MIP chain (issue 17)
            from pyramid_cli.run.methods_files import fill_texture

            image = fill_texture(image, session, work.border, where=job.input)
        if not announced:
            announced.append(True)
            announce_compiles(session, work, [image.pixels], reporter)
        half = (image.pixels.dtype == np.float16
                and io.stores_half_unchanged(job.output, image.spec, pixel_type=wo.pixel_type))
        outs = session.run(work, [image.pixels], np.float16 if half else np.float32)
        output = io.describe_output(job.output, image.spec, **wo.for_inputs([]))
        reporter.detail(f"{io.describe_rules(image.spec)}; {output}; executor {session.ran}")
        return [io.Image(px, image.spec) for px in (outs if mip_tile else outs[-1:])]

    def write_job(job, images):
        options = wo.for_inputs([job.input])
        if isinstance(images, tuple):  # level 0 as read (compute): the codes, then the levels as stored
            level0, levels = images
            assert mip_tile, "only MIP files are written from level 0 as read"
            shapes = [level0.stored.shape] + [level.shape for level in levels]
            with mip_whole.mip_writer(level0, job.output, work, shapes, mip_tile, options) as writer:
                mip_whole.write_levels(writer, level0, levels)
            h, w = level0.stored.shape[:2]
            return wrote_line(job.output, w, h, len(levels) + 1, session.ran)
        if mip_tile:
            from pyramid_cli.run.stream_mip import mip_metadata

            # the source's SHA-1 hashed as it was read: the file is not read again
            meta = mip_metadata(work, job.input, images[0].spec.pixel_hash)
            io.write_levels(job.output, images, mode="mipmap", tile=mip_tile, meta=meta, **options)
        else:
            io.write_image(job.output, images[0], **options)
        h, w = images[0].pixels.shape[:2]
        return wrote_line(job.output, w, h, len(images) if mip_tile else None, session.ran)

    def written(job, line):  # in job order, whichever write ended first
        if not show_bar:
            reporter.result(line)

    progress = reporter.progress if many and not reporter.quiet else None
    show_bar = progress is not None
    # GL compiles and allocates while the first image decodes; so does the CPU executor for MIP maps
    # (loading its kernels, about 0.3 s of a cold process, beside the read and the source's hash)
    early = prepare if session.on_gl or mip_tile else None
    if progress is not None:
        with progress(len(job_list)) as bar:
            return batch.run(job_list, read_job, compute, write_job, keep_going=keep_going,
                             skip_existing=skip_existing, workers=jobs, written=written, prepare=early,
                             progress=lambda job: bar.update(1))
    return batch.run(job_list, read_job, compute, write_job, keep_going=keep_going, skip_existing=skip_existing,
                     workers=jobs, written=written, prepare=early)


# Pictures of ALONE_PIXELS or more that stream faster alone (run.stream.speed_band) leave a batch's overlap and
# stream alone: whole, two of them thrash memory. Measured with fresh processes interleaved, 2-3 rounds, the
# streamed runs one after another against the same batch overlapped whole: two 8K (7680x4320) half EXRs
# `blur --levels 5` 5.14 s, 141 MiB against 7.49 s, 1.8 GB; two 8K 8-bit PNGs `blur --sigma 8` 6.50 s, 133 MiB
# against 7.02 s, 2.6 GB. At 4K the overlap keeps two of PNG's one-thread encoders busy: four 4K PNGs 4.40 s
# streamed against 3.59 s overlapped (four 4K half EXRs: 2.46 against 2.79 s), so 4K overlaps. With --jobs 1 the
# same threshold holds: twelve 1080p half EXRs ran whole one after another in 1.99 s, streamed in 2.32 s.
ALONE_PIXELS = 1 << 24


def held_at_once(jobs: int, count: int | None = None) -> int:
    """Pictures a batch of ``count`` overlapping its I/O in ``jobs`` threads holds at once
    (:func:`pyramid_cli.run.batch.run`): ``jobs + 1`` read ahead, the one computed, and up to ``jobs`` written
    behind, but never more than the batch has; one with ``jobs`` 1, which reads, computes and writes one picture
    after another."""
    held = 1 if jobs <= 1 else 2 * jobs + 2
    return held if count is None else max(1, min(held, count))


def run_alone(job: batch.Job, work: Work, session: Session, *, memory: int | None, read: ReadOptions,
              write: WriteOptions, reporter: Reporter, mip_tile: int | None = None,
              limits: contextlib.ExitStack | None = None) -> bool:
    """One input's run: streamed when its whole run would not fit the budget (:func:`pyramid_cli.run.stream.run_job`,
    a MIP file :func:`pyramid_cli.run.stream_mip.run_mip`, which writes it whole itself where it can); False,
    having written nothing, where the caller runs it whole (its codec threads limited until ``limits`` closes)."""
    from pyramid_cli.run.stream import run_job
    from pyramid_cli.run.stream_mip import run_mip

    if mip_tile:
        return run_mip(job, work, session, memory=memory, tile=mip_tile, read=read, write=write, reporter=reporter,
                       whole=mip_whole.run_whole, limits=limits)
    return run_job(job, work, session, memory=memory, read=read, write=write, reporter=reporter, limits=limits)


def run_in_budget(job_list: list[batch.Job], work: Work, session: Session, *, memory: int | None, read: ReadOptions,
                  write: WriteOptions, reporter: Reporter, keep_going: bool = False, skip_existing: bool = False,
                  jobs: int = 2, mip_tile: int | None = None, many: bool = True) -> batch.Report:
    """:func:`run_jobs` on this machine within the memory budget (``memory``, else
    :func:`pyramid_cli.run.budget.default_budget`: a container's limits), in job order. A picture runs alone, as
    one input does (:func:`run_alone`: streamed where it would not fit alone either, or where that is faster),
    where its whole run (:func:`pyramid_cli.run.weight.weigh`), held :func:`held_at_once` times (no more than
    the batch has pictures), would not fit the budget, and where it streams faster alone and has
    :data:`ALONE_PIXELS` (16.8 million) or more; the others run in stretches of overlapped I/O (with ``jobs`` 1,
    one whole picture after another). Two 8K half EXRs blurred in one call held 1.8 GB, which a 700 MiB
    container kills."""
    from pyramid_cli.run.budget import resolve
    from pyramid_cli.run.weight import weigh

    share = resolve(memory).size // held_at_once(jobs, len(job_list))
    runs: list[tuple[bool, list[batch.Job]]] = []
    for job in job_list:
        weight = None if skip_existing and batch.is_fresh(job) else weigh(job.input, work, session, read, job.output,
                                                                          write, mip_tile or 0)
        alone = weight is not None and (weight.whole > share or weight.streamed >= ALONE_PIXELS)
        if runs and runs[-1][0] == alone:
            runs[-1][1].append(job)
        else:
            runs.append((alone, [job]))

    def overlapped(part: list[batch.Job], threads: int, bar: bool, says: Reporter) -> batch.Report:
        return run_jobs(part, work, session, read=read, write=write, reporter=says, keep_going=keep_going,
                        skip_existing=skip_existing, jobs=threads, mip_tile=mip_tile, many=bar)

    if not any(alone for alone, _ in runs):
        return overlapped(job_list, jobs, many, reporter)
    with contextlib.ExitStack() as shown:
        bar = None
        if many and reporter.progress is not None and not reporter.quiet:
            # one bar for the whole batch, as an overlapped one shows: the parts move it, and the pictures run
            # alone do not print their lines either
            bar = shown.enter_context(reporter.progress(len(job_list)))
            reporter = dataclasses.replace(reporter, out=lambda msg: None,
                                           progress=lambda total: contextlib.nullcontext(bar))
        return _run_parts(runs, overlapped, work, session, memory=memory, read=read, write=write, reporter=reporter,
                          keep_going=keep_going, mip_tile=mip_tile, jobs=jobs, bar=bar)


def _run_parts(runs: list[tuple[bool, list[batch.Job]]], overlapped: Callable, work: Work, session: Session, *,
               memory: int | None, read: ReadOptions, write: WriteOptions, reporter: Reporter, keep_going: bool,
               mip_tile: int | None, jobs: int, bar) -> batch.Report:
    """:func:`run_in_budget`'s stretches in order: ``overlapped(part, threads, show_bar, reporter)`` for those that
    overlap, :func:`run_alone` for each picture of the others; ``bar`` (or None) moves by one per picture run
    alone."""
    report = batch.Report()

    def alone(job: batch.Job) -> None:
        try:
            with contextlib.ExitStack() as limits:
                if run_alone(job, work, session, memory=memory, read=read, write=write, reporter=reporter,
                             mip_tile=mip_tile, limits=limits):
                    report.done.append(job)
                else:  # it fits alone: whole, with nothing beside it
                    report.extend(overlapped([job], 1, False, reporter))
        except PyramidError as e:
            report.failed.append((job, e))
        if bar is not None:
            bar.update(1)

    for runs_alone, part in runs:
        for group in ([job] for job in part) if runs_alone else [part]:
            if report.failed and not keep_going:
                return report
            if runs_alone:
                alone(group[0])
            else:
                report.extend(overlapped(group, jobs, bar is not None, reporter))
    return report


__all__ = ["ALONE_PIXELS", "held_at_once", "run_alone", "run_in_budget", "run_jobs", "texture_channels"]
