"""Files in, files out: the one dispatcher at the top of :mod:`pyramid_cli.run`.

The CLI and the Python API's file helpers call these functions; they hold the
policies that used to live in command bodies: which inputs become which outputs,
whether one picture streams (:mod:`pyramid_cli.run.stream`), runs here
(:mod:`pyramid_cli.run.local`) or on a cluster (:mod:`pyramid_cli.run.cluster`), refusals
before work (:mod:`pyramid_cli.workflows.limits`, options a format would ignore), and what
is said on the way (a :class:`~pyramid_cli.run.report.Reporter`). Writes are atomic
(:mod:`pyramid_cli.imageio`). Nothing else in :mod:`pyramid_cli.run` imports this module.
"""

from __future__ import annotations

import contextlib
import os
import re
from typing import TYPE_CHECKING

from pyramid_cli import imageio as io
from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.imageio.texture import check_texture_tile
from pyramid_cli.jobs.work import Collapse, Laplacian, Levels, Work, same_setting
from pyramid_cli.run import batch
from pyramid_cli.run.codec_budget import holds_codec_limits
from pyramid_cli.run.inputs import read_input
from pyramid_cli.run.local import run_alone, run_in_budget
from pyramid_cli.run.report import Reporter, announce_compiles
from pyramid_cli.run.settings import ReadOptions, WriteOptions

if TYPE_CHECKING:  # importing the cluster package imports distributed
    from pyramid_cli.run.cluster import SessionSpec


@holds_codec_limits
def process(paths: list[str], template: str | None, work: Work, session: Session | SessionSpec | None, *,
            read: ReadOptions | None = None, write: WriteOptions | None = None, reporter: Reporter | None = None,
            keep_going: bool = False, skip_existing: bool = False, jobs: int = 2,
            mip_tile: int | None = None, frames: str | None = None, shard=None, cluster=None,
            chunk: int | None = None, memory: int | None = None, cluster_timeout: float | None = None,
            limits: contextlib.ExitStack | None = None) -> batch.Report:
    """Run ``work`` on every input of ``paths`` (``IN OUT``, or inputs with ``template``).

    One session for the whole batch; decoding and encoding overlap the work in ``jobs``
    threads. Half inputs whose output stores half unchanged travel as half. With
    ``mip_tile`` every output of ``work`` goes into one tiled MIP-mapped file. A single
    job's failure is raised; a batch's failures are reported and collected in the
    returned report (its ``exit_code`` is the first failure's).

    Inputs may be frame sequences (``frames`` selects frames; :mod:`pyramid_cli.run.sequence`);
    ``shard`` (``"K/N"``, ``"auto"`` or a :class:`pyramid_cli.run.shard.Shard`) keeps one
    contiguous chunk of the job list; ``cluster`` (an address, ``"local:N"`` or a
    ``distributed.Client``) runs the jobs on a Dask cluster in chunks of ``chunk`` jobs,
    each worker with its own session like ``session`` (``session`` may then be a
    :class:`~pyramid_cli.run.cluster.worker.SessionSpec`, or None: ``Session()``'s defaults),
    connecting and waiting for workers up to ``cluster_timeout`` seconds (:mod:`pyramid_cli.run.cluster`).

    One input of ``apply`` or ``blur`` streams from file to file in bands (:mod:`pyramid_cli.run.stream`),
    decoding, computing and encoding at once, when it is large enough to be faster so
    (:func:`pyramid_cli.run.stream.speed_band`) or when its whole-picture run would not fit ``memory`` bytes
    (default: :func:`pyramid_cli.run.budget.default_budget`); ``mipmap`` only in the latter case
    (:mod:`pyramid_cli.run.stream_mip`). Other images run whole; one of them with OpenEXR's codec threads limited
    to what its budget leaves (``limits``, given by :func:`~pyramid_cli.run.codec_budget.holds_codec_limits`).
    A batch on this machine keeps to the same budget: a picture too large to be held beside the others in flight
    runs alone, streamed where it would not fit alone either (:func:`pyramid_cli.run.local.run_in_budget`).
    """
    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    if mip_tile:
        check_texture_tile(mip_tile, template or (paths[-1] if len(paths) > 1 else ""))
    for message in work.notes():  # a --sigma blur's blend
        reporter.say(message)
    for message in work.warnings():  # said once, before the first input is read (the CLI and process_files)
        reporter.warn(message)
    if cluster is None and (chunk is not None or cluster_timeout is not None):
        raise UsageError("--chunk and --cluster-timeout are for --cluster runs")
    job_list, many = batch.select_jobs(paths, template, frames=frames, shard=shard, keep_going=keep_going,
                                       reporter=reporter)
    if isinstance(session, Session) and cluster is None and job_list:  # auto decides for all; numba loads meanwhile
        first = _header(job_list[0].input)
        if first is not None:
            session.prepare_async(work, [first[0]], count=len(job_list), dtype=first[1])
    if (not many and len(job_list) == 1 and cluster is None and frames is None
            and not (skip_existing and batch.is_fresh(job_list[0]))):
        assert isinstance(session, Session), "a session, unless the jobs run on a cluster"
        if run_alone(job_list[0], work, session, memory=memory, read=ro, write=wo, reporter=reporter,
                     mip_tile=mip_tile, limits=limits):
            return batch.Report(done=list(job_list))
    elif memory is not None and cluster is not None:
        raise UsageError("--memory budgets this machine's run (not --cluster: the workers' memory is their own)")
    if cluster is not None:
        from pyramid_cli.run.cluster import run_cluster

        report = run_cluster(job_list, work, cluster, session=session, read=ro, write=wo, reporter=reporter,
                             keep_going=keep_going, skip_existing=skip_existing, jobs=jobs, mip_tile=mip_tile,
                             chunk=chunk, many=many, timeout=cluster_timeout)
    else:
        assert isinstance(session, Session), "a session, unless the jobs run on a cluster"
        report = run_in_budget(job_list, work, session, memory=memory, read=ro, write=wo, reporter=reporter,
                               keep_going=keep_going, skip_existing=skip_existing, jobs=jobs, mip_tile=mip_tile,
                               many=many)
    if not many and report.failed:
        raise report.failed[0][1]
    if many:
        if not reporter.quiet:
            reporter.err(f"pyramid: {len(report.done)} written, {len(report.skipped)} up to date, "
                         f"{len(report.failed)} failed")
        said = set()
        for _job, err in report.failed:  # a lost cluster's one error names all the frames it failed
            if id(err) not in said:
                said.add(id(err))
                reporter.error(str(err))
    return report


def _header(path: str):
    """(shape, dtype the pixels will arrive as: half files as half, MIP maps included) from ``path``'s header, or
    None (the read reports why)."""
    if io.read_shape(path) is None:  # not a regular, readable picture (a FIFO would block the stream)
        return None
    try:
        with io.open_stream(path, keep_half=True) as st:
            return st.shape, st.dtype
    except Exception:  # noqa: BLE001 - an optimisation only: the read reports every error
        return None


def level_path(pattern: str, level: int) -> str:
    """``pattern`` with ``{level}`` filled in (levels and bands written one file each)."""
    if "{level}" not in pattern:
        raise UsageError(f"output pattern {pattern!r} needs {{level}}, e.g. out_{{level}}.exr (or use --multipart)")
    return pattern.replace("{level}", str(level))


@holds_codec_limits
def write_levels_files(input_path: str, pattern: str, work: Levels | Laplacian, session: Session, *,
                       read: ReadOptions | None = None, write: WriteOptions | None = None,
                       reporter: Reporter | None = None, multipart: bool = False,
                       sheet: str | None = None, memory: int | None = None,
                       limits: contextlib.ExitStack | None = None) -> list[str]:
    """Every level of a pyramid (or the Laplacian bands) of one image, one file each or one multipart EXR.

    Returns the paths written. Laplacian bands are stored as float and record the
    synthesis filter and border (``pyramid:synthesis``, ``pyramid:border``) so that :func:`collapse_files`
    can undo them. One file per level streams, every level band by band, when the whole pyramid would not
    fit ``memory`` bytes (default: :func:`pyramid_cli.run.budget.default_budget`; :mod:`pyramid_cli.run.stream`).
    """
    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    laplacian = isinstance(work, Laplacian)
    if memory is not None and (multipart or sheet):
        raise UsageError("--memory streams one file per level (not --multipart or --sheet, which hold every level)")
    if not multipart and not sheet:
        shape = io.read_shape(input_path)
        if shape is not None:
            session.prepare_async(work, [shape])  # auto decides for this job; numba loads meanwhile
        p = session.plan(work, [shape[:2]]) if shape is not None and session.executor is not None else None
        if p is not None or memory is not None:
            from pyramid_cli.run.stream import run_levels

            n = (1 if work.keeps_input else 0) + (len(p.outputs) if p is not None else 0)
            written = [level_path(pattern, k) for k in range(n)]
            options = wo.for_inputs([input_path])
            attributes = None
            if isinstance(work, Laplacian):
                options["pixel_type"] = wo.pixel_type or "float"
                attributes = {"pyramid:synthesis": work.synthesis, "pyramid:border": work.border}
                if wo.tocolorspace is None:  # in the space they were computed in, as whole (below): the header's
                    with io.open_stream(input_path, colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan,
                                        colorconfig=ro.colorconfig) as st:
                        options["colorspace"] = st.info.linear_space
                else:
                    options["colorspace"] = wo.tocolorspace
            if run_levels(input_path, written, work, session, memory=memory, read=ro, options=options,
                          attributes=attributes, reporter=reporter, limits=limits):
                for path in written:
                    reporter.result(f"wrote {path}")
                return written
    image = read_input(input_path, ro, reporter)
    work.check((image.pixels.shape[:2],), where=input_path)
    announce_compiles(session, work, [image.pixels], reporter)
    stack = session.run(work, [image.pixels])
    images = [io.Image(px, image.spec) for px in stack]
    options = wo.for_inputs([input_path])
    if isinstance(work, Laplacian):
        options["pixel_type"] = wo.pixel_type or "float"
        # band-pass detail is signed linear light: it stays in the space it was computed in
        options["colorspace"] = wo.tocolorspace or image.spec.linear_space
        for im in images:
            im.spec.attributes["pyramid:synthesis"] = work.synthesis
            im.spec.attributes["pyramid:border"] = work.border
    first = pattern if multipart else level_path(pattern, 0)
    reporter.detail(f"{io.describe_rules(image.spec)}; {io.describe_output(first, image.spec, **options)}; "
                    f"executor {session.ran}")
    if multipart:
        io.write_levels(pattern, images, mode="multipart", **options)
        written = [pattern]
    else:
        written = [level_path(pattern, k) for k in range(len(images))]
        io.write_images(written, images, **options)  # all or nothing
    if sheet:
        from pyramid_cli.run.sheet import contact_sheet

        panel = contact_sheet([im.pixels if not laplacian or k == len(images) - 1 else im.pixels + 0.5
                               for k, im in enumerate(images)])
        info = io.ImageInfo(path=sheet, format="png", pixel_type="uint8", channel_names=["R", "G", "B"],
                            alpha_channel=-1, colorspace="srgb", alpha_mode="none",
                            linear_space=image.spec.linear_space, colorconfig=image.spec.colorconfig)
        io.write_image(sheet, io.Image(panel, info), pixel_type="uint8")
        written.append(sheet)
    for path in written:
        reporter.result(f"wrote {path}")
    return written


def _level_key(path: str):
    digits = re.findall(r"\d+", os.path.basename(path))
    return (int(digits[-1]) if digits else 0, path)


def _as_recorded(spec: io.ImageInfo, path: str, what: str, asked: str | None, default: str) -> str:
    """``asked`` when it agrees with what the bands record (``pyramid:<what>`` in their first file's header
    ``spec``), the record when not asked."""
    recorded = spec.attributes.get(f"pyramid:{what}")
    if asked is None:
        return recorded or default
    if recorded is not None and not same_setting(what, asked, recorded):
        raise UsageError(f"{path}: the bands were made with --{what} {recorded} (recorded in the file); "
                         f"collapsing with --{what} {asked} would not give the image back")
    return asked


@holds_codec_limits
def collapse_files(inputs: list[str], output_path: str, session: Session, *, synthesis: str | None = None,
                   border: str | None = None, read: ReadOptions | None = None, write: WriteOptions | None = None,
                   reporter: Reporter | None = None, memory: int | None = None,
                   limits: contextlib.ExitStack | None = None) -> str:
    """Sum Laplacian bands back to the image: a multipart EXR, or band files L_0 … L_m−1, G_m in order.

    ``synthesis`` and ``border`` default to what the bands record (``pyramid levels --laplacian`` writes
    both); one that contradicts the record is refused, since it would not give the image back.
    Band files stream, each read band by band (:func:`pyramid_cli.run.stream_many.collapse_streamed`), when the
    whole run would not fit ``memory`` bytes (default: :func:`pyramid_cli.run.budget.default_budget`) or is
    slower than bands (from a megapixel on the CPU executor); a multipart EXR is read whole.
    """
    ro, wo, reporter = read or ReadOptions(), write or WriteOptions(), reporter or Reporter()
    paths = batch.expand(list(inputs))
    if len(paths) == 1 and memory is not None:
        raise UsageError("--memory streams band files (L_0 … G_m), not a multipart EXR, whose parts are read whole")
    if len(paths) > 1:
        from pyramid_cli.run.stream_many import collapse_streamed

        ordered = sorted(paths, key=_level_key)

        def settle(spec: io.ImageInfo) -> tuple[str, str]:
            return (_as_recorded(spec, paths[0], "synthesis", synthesis, catalogue.DEFAULT_SYNTHESIS),
                    _as_recorded(spec, paths[0], "border", border, "clamp"))

        if collapse_streamed(ordered, output_path, session, settle, memory=memory, read=ro, write=wo,
                             options_from=paths, reporter=reporter, limits=limits) is not None:
            return output_path
    if len(paths) == 1:
        bands = io.read_parts(paths[0], colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan,
                              colorconfig=ro.colorconfig)
    else:
        bands = [read_input(p, ro, reporter) for p in sorted(paths, key=_level_key)]
    if len(bands) < 2:
        raise UsageError(f"collapse needs at least two levels, {paths[0]} holds {len(bands)}")
    io.check_pyramid(bands)
    synthesis = _as_recorded(bands[0].spec, paths[0], "synthesis", synthesis, catalogue.DEFAULT_SYNTHESIS)
    border = _as_recorded(bands[0].spec, paths[0], "border", border, "clamp")
    work = Collapse(bands=len(bands), synthesis=synthesis, border=border)
    announce_compiles(session, work, [b.pixels for b in bands], reporter)
    (out,) = session.run(work, [b.pixels for b in bands])
    io.write_image(output_path, io.Image(out, bands[0].spec), **wo.for_inputs(paths))
    h, w = out.shape[:2]
    reporter.result(f"wrote {output_path} ({w}×{h}, {session.ran})")
    return output_path


__all__ = ["process", "write_levels_files", "collapse_files", "level_path"]
