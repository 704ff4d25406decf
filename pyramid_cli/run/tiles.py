"""``pyramid tiles``: every level of an analysis pyramid, streamed band by band into a viewer's tile set.

One input (a file, or an array of the Python API) goes to one
:class:`~pyramid_cli.imageio.tilesets.TileSetWriter` (Deep Zoom, IIIF, OME-Zarr, pyramidal TIFF: the
layout named or read from the output's name, :func:`~pyramid_cli.imageio.tilesets.layout_of`). Its
levels are the writer's sizes, each ⌈n/2⌉ of the one before (``w.sizes``): level 0 is the input, passed
through as it is decoded; levels 1.. come from one plan (:func:`pyramid_cli.workflows.pyramids.levels_plan`,
the paper's ⊗↓ analysis filter in linear light on premultiplied alpha, exact at every border and odd size)
run by the band engine of :mod:`pyramid_cli.run.stream` (:func:`~pyramid_cli.run.stream.run_bands`): the
input decoded ahead on a thread, the levels made band by band, every level's rows handed to the writer
on a thread behind as soon as they are made. Nothing holds a whole level (the writer holds the rows of
the tile row it completes), so memory stays flat with the picture's size.

The writer builds beside its output and moves it into place at the end, descriptor last; any error or
interruption (Ctrl-C, SIGTERM) calls its ``abort``, which removes what was written and leaves the previous
output as it was.
"""

from __future__ import annotations

import collections
import dataclasses
import os
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import DataError, OutputError, PyramidError, UsageError
from pyramid_cli.run.budget import format_size, resolve
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.joblist import Report
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.stream import (
    MIN_BAND,
    band_rows,
    choose,
    costs,
    estimate,
    executor_codes,
    executor_of,
    open_input,
    run_bands,
    warn_nonfinite,
)

if TYPE_CHECKING:  # the writers load OpenImageIO: imported when a tile set is written (pyr.tiles is in the API)
    from pyramid_cli.imageio.tilesets import TileOptions

FOLDER_LAYOUTS = ("dz", "iiif3", "iiif")   # a folder of tile files: --format picks their format
TILE_FORMATS = ("jpeg", "png", "webp", "tif")
ALPHA_FORMATS = ("png", "webp", "tif")     # tile formats that hold alpha
FORMAT_ALIASES = {"jpg": "jpeg", "tiff": "tif"}
WRITER_BANDS = 3  # float bands a writer encodes at once, at most (deepzoom.MAX_BANDS; the TIFF's two)
DEFAULT_TILE = 256                         # a layout's default tile edge, for the memory estimate (dz: 254)
PASS_ROWS = 64                             # rows at a time of a one-level tile set (no plan: level 0 only)
# Pixels of the widest level made per band (level 1: the input's bands are twice the rows of it), twice the band
# engine's BAND_PIXELS: 128 rows of level 1 at 8K, 64 at 16K, 32 at 32K. Every band costs the scheduler and the
# writers the same Python work whatever its width, and the band engine's copies once kept these bands small
# (2026-11-27: 300 MiB peak at 8K in bands of 16 rows, 500 in 128). With them gone (2026-11-28; fresh processes
# interleaved, Deep Zoom to /dev/shm, 4 to 5 rounds): 8K 1.264 s and 139 MiB in bands of 32 rows, 1.152 s and
# 160 MiB in 64, 1.101 s and 211 MiB in 128; 16K 3.39 s and 195 MiB in 32, 3.07 s and 243 MiB in 64, 2.92 s and
# 319 MiB in 128; 32K 10.8 s and 315 MiB in 32, 11.2 s and 558 MiB in 128. The pyramidal TIFF alike: 16K 3.52 →
# 3.00 s in 64 rows, 8K 1.31 → 1.14 s in 128, the same bytes.
TILE_BAND_PIXELS = 1 << 19
# ... but never fewer rows than this: every band costs the same Python work whatever its width, and a 16K Deep Zoom
# took 6.8 s in bands of 16 rows against 6.0 s in 32 (3 fresh processes interleaved; 295 and 358 MiB peak, where
# libvips holds 142). Wider pictures hold wider bands, as libvips's tile rows are.
TILE_BAND_ROWS = 32


@dataclass(frozen=True)
class TileSettings:
    """What the user asked of every tile set of a run.

    Attributes
    ----------
    layout : str or None
        ``--layout`` (None: from the output's name).
    analysis : str
        The ⊗↓ filter or one-step expression each level is reduced with.
    border : str
        How the analysis reads past the edges (odd sizes are padded by it).
    options : TileOptions
        Tile size, overlap, tile format, quality, compression and the write options.
    """

    layout: str | None = None
    analysis: str = catalogue.MIP_ANALYSIS_DEFAULT
    border: str = "clamp"
    options: TileOptions = dataclasses.field(default_factory=lambda: _options())


def _options(*args, **kw) -> TileOptions:
    from pyramid_cli.imageio.tilesets import TileOptions

    return TileOptions(*args, **kw)


class ArraySource:
    """An array of linear, premultiplied pixels read as a stream is (:meth:`read` of rows), for the API.

    ``info`` says how the tiles store them (:func:`pyramid_cli.imageio.info_for_array`: float, linear,
    channels named by count, alpha premultiplied)."""

    def __init__(self, pixels: np.ndarray, info):
        self.pixels = pixels if pixels.ndim == 3 else pixels[:, :, None]
        self.info, self.path = info, "array"
        self.shape = self.pixels.shape
        self.dtype = np.dtype(np.float32)
        self.nonfinite, self.nan = 0, "keep"

    def read(self, y0: int, y1: int) -> np.ndarray:
        return np.ascontiguousarray(self.pixels[y0:y1], dtype=np.float32)

    def close(self) -> None:
        return None


def tile_format(layout: str, options: TileOptions, info, reporter: Reporter, where: str) -> TileOptions:
    """``options`` with the folder layouts' tile format settled: as asked (aliases spelled out), else JPEG as
    ``vips dzsave`` writes, or PNG when the input has alpha (-v says so). JPEG tiles of an input with alpha are
    refused (JPEG holds no alpha; flattening would choose a background for the user); the other layouts refuse
    ``--format``."""
    asked = FORMAT_ALIASES.get(options.suffix or "", options.suffix)
    alpha = getattr(info, "alpha_channel", -1) >= 0
    if layout not in FOLDER_LAYOUTS:
        if asked is not None:
            raise UsageError(f"--format {options.suffix}: the {layout} layout stores no tile files "
                             "(--compression picks its codec)")
        return options
    if asked is not None and asked not in TILE_FORMATS:
        raise UsageError(f"--format {options.suffix}: not one of {', '.join(TILE_FORMATS)}")
    if asked is None:
        asked = "png" if alpha else "jpeg"
        if alpha:
            reporter.detail(f"{where}: PNG tiles, not JPEG: the input has alpha (JPEG holds none)")
    elif asked not in ALPHA_FORMATS and alpha:
        raise UsageError(f"{where}: --format {options.suffix}: JPEG tiles hold no alpha and the input has it; "
                         "give --format png or webp")
    return dataclasses.replace(options, suffix=asked)


def writer_memory(sizes: list[tuple[int, int]], channels: int, options: TileOptions, itemsize: int = 4,
                  band: int = MIN_BAND) -> int:
    """Bytes a writer holds at most, by the contract: per level the rows of the tile row it completes (tile edge,
    :data:`DEFAULT_TILE` when the layout decides, plus twice the overlap) in the stored type (``itemsize`` bytes a
    value), two more of level 0's waiting for the file (the TIFF's queue, Deep Zoom's queued tiles), and
    :data:`WRITER_BANDS` float32 bands of ``band`` rows of level 0 being encoded (the smallest band by default:
    the band is chosen within what is left; larger bands' copies fall within the budget's reserve)."""
    rows = (options.tile_size or DEFAULT_TILE) + 2 * (options.overlap if options.overlap is not None else 1)
    (h0, w0) = sizes[0]
    stored = sum(min(h, rows) * w for h, w in sizes) + 2 * min(h0, rows) * w0
    return (stored * itemsize + WRITER_BANDS * min(h0, band) * w0 * 4) * channels


def _check_not_input(where: str, out: str, force: bool) -> None:
    if force or where == "array" or not os.path.exists(out):
        return
    try:
        same = os.path.samefile(where, out)
    except OSError:
        return
    if same:
        raise OutputError(f"refusing to overwrite input {out} (use --force)")


def tile_source(source, where: str, out: str, settings: TileSettings, session, *, memory: int | None = None,
                reporter: Reporter | None = None, force: bool = False) -> dict:
    """Write the tile set of ``source`` (an :class:`~pyramid_cli.imageio.ImageStream` or :class:`ArraySource`,
    named ``where`` in messages) at ``out`` (see the module); returns the writer's ``finish()`` description with
    ``input``, ``backend``, ``analysis``, ``border``, ``band`` (rows per band; None: one level, or run whole on
    the reference backend) and ``seconds`` added."""
    from pyramid_cli import imageio as io
    from pyramid_cli.imageio import tilesets

    reporter = reporter or Reporter()
    started = time.perf_counter()
    group = not isinstance(out, (str, os.PathLike))  # a zarr.Group: OME-Zarr written into it
    layout = "ome-zarr" if group else tilesets.layout_of(os.fspath(out), settings.layout)
    cls = tilesets.writer_class(layout)
    h, w, c = source.shape
    if not group:
        _check_not_input(where, out, force)
    options = tile_format(layout, settings.options, source.info, reporter, where)
    writer = cls(out, source.info, (h, w), c, options)
    try:
        writer.check()
        sizes = writer.sizes
        reporter.detail(io.describe_rules(source.info))
        reporter.detail(f"{out}: layout {layout}, {len(sizes)} level(s) "
                        f"({' '.join(f'{b}×{a}' for a, b in sizes)}), each ⌈n/2⌉ of the one before, reduced with "
                        f"{settings.analysis} ⊗↓ (--border {settings.border})"
                        + (f", {options.suffix} tiles" if options.suffix else ""))
        band = _make_levels(source, where, writer, sizes, options, settings, session, memory, reporter)
        report = writer.finish()
    except BaseException:
        try:
            writer.abort()
        except Exception:  # noqa: BLE001 - the first error is the one to say
            pass
        raise
    warn_nonfinite([source], source, reporter)  # its .nan: the policy it was read with
    ran = getattr(session, "ran", "") or ""
    report = {**report, "input": where, "backend": ran, "analysis": settings.analysis, "border": settings.border,
              "band": band, "seconds": round(time.perf_counter() - started, 3)}
    reporter.result(f"wrote {out} ({w}×{h}, {len(sizes)} levels, {layout}, {ran})")
    return report


def _make_levels(source, where: str, writer, sizes, options: TileOptions, settings: TileSettings, session,
                 memory: int | None, reporter: Reporter) -> int | None:
    """Every row of every level to ``writer.rows``; the band it ran in (None: no plan)."""
    from pyramid_cli.jobs.work import Levels

    h, w, c = source.shape
    if len(sizes) == 1:  # one level (a 1×1 input, or a layout whose one tile holds it): no plan to run
        for y in range(0, h, PASS_ROWS):
            writer.rows(0, y, source.read(y, min(h, y + PASS_ROWS)))
        session.ran = "none (one level: the input itself)"
        return None
    work = Levels(levels=len(sizes) - 1, analysis=settings.analysis, border=settings.border)
    work.check(((h, w),), where=where)
    session.prepare_async(work, [(h, w, c)], dtype=source.dtype)  # auto decides for this job; numba loads meanwhile
    if session.executor is None:  # the reference backend: the float64 oracle holds whole pictures
        if memory is not None:
            executor_of(session)  # refuses with the reason
        reporter.detail(f"{where}: runs whole (the reference backend holds whole pictures)")
        levels = session.run(work, [source.read(0, h)], np.float32)
        for k, px in enumerate(levels):
            writer.rows(k, 0, np.ascontiguousarray(px, dtype=np.float32))
        session.ran = session.name
        return None
    plan = session.plan(work, [(h, w)])
    made = [plan.images[k].size for k in plan.outputs]
    if [tuple(s) for s in made] != [tuple(s) for s in sizes[1:]]:
        raise RuntimeError(f"the levels plan makes {made}, the writer holds {sizes[1:]}")
    executor = executor_of(session)
    given = resolve(memory)
    stored_bytes = np.asarray(writer.encode(np.zeros((1, 1, c), np.float32))).itemsize
    held = writer_memory(sizes, c, options, stored_bytes)
    reporter.detail(f"{where}: {given.describe()}; the tile writer holds about {format_size(held)}")
    stored = stored_rows(source, writer, options)
    table = executor_codes(source, executor) if stored is not None else None
    in_bytes = source.stored_dtype.itemsize if table is not None else source.dtype.itemsize
    streams = [source] if hasattr(source, "reopen") else []  # an EXR input's codec threads as the budget allows
    codecs = Codecs.of(streams)
    kw = {"in_bytes": in_bytes, "out_bytes": 4, "keeps_input": True, **costs(executor)}
    least = codecs.first + estimate(plan, c, MIN_BAND, **kw) + held
    if least > given.size:
        by_codecs = f", {format_size(codecs.first)} that OpenEXR's codec holds on one thread" if codecs.first else ""
        raise given.refusal(DataError(
            f"{where}: this tile set needs at least {format_size(least)} of memory (bands of {MIN_BAND} rows and "
            f"its guard bands at every level{by_codecs}, and {format_size(held)} for the tile rows the writer "
            f"holds), over the budget of {format_size(given.size)}; give more with --memory (memory= in Python)"))
    choice = choose(plan, c, given.size - held, force=True, where=where, prefer=_prefer(plan), codecs=codecs.first,
                    **kw)
    reporter.detail(f"{where}: {choice.describe()}")
    band = choice.band or MIN_BAND

    if stored is not None:
        reporter.detail(f"{where}: level 0's tiles hold the input's own stored values (encoding its decoded "
                        "values gives every one of them back)"
                        + ("; level 1 is made from them through the decoding table" if table is not None else ""))

    def level0(y0: int, px: np.ndarray) -> None:  # on the writer's thread: each input row once, in order
        if table is not None:  # px are the codes: the stored rows themselves
            writer.rows(0, y0, None, px)
        else:
            writer.rows(0, y0, px.astype(np.float32, copy=False), None if stored is None else stored.take(len(px)))

    def level(j: int, y0: int, px: np.ndarray) -> None:  # on the writer's thread: the band engine's rows
        writer.rows(j + 1, y0, px.astype(np.float32, copy=False), owned=True)

    try:
        with codecs.within(choice, reporter, where):
            if table is not None:  # the codes reach level 0 themselves
                times = run_bands(source.read_stored, plan, executor, band, level, level0, codes=table)
            else:
                if stored is not None:
                    source.on_stored = stored.keep
                times = run_bands(source.read, plan, executor, band, level, level0)
    finally:
        if stored is not None:
            source.on_stored = None
    reporter.detail(f"{where}: {times.describe()}")
    session.ran = session.name
    return band


class StoredRows:
    """The input's rows as stored, kept as the reader's thread decodes them (``on_stored`` of an
    :class:`~pyramid_cli.imageio.ImageStream`) until the writer's thread hands the same rows, decoded, to the tile
    writer as level 0: both go through the rows once, in order, so the next ``n`` kept rows are theirs."""

    def __init__(self) -> None:
        self._parts: collections.deque[np.ndarray] = collections.deque()

    def keep(self, data: np.ndarray) -> None:
        """Rows as stored, the next ones (on the reader's thread)."""
        self._parts.append(data)

    def take(self, n: int) -> np.ndarray:
        """The next ``n`` stored rows (on the writer's thread; the reader kept them before it gave them decoded)."""
        parts, got = [], 0
        while got < n:
            part = self._parts[0]
            if got + len(part) <= n:
                parts.append(self._parts.popleft())
                got += len(part)
            else:
                parts.append(part[:n - got])
                self._parts[0] = part[n - got:]
                got = n
        return parts[0] if len(parts) == 1 else np.concatenate(parts)


def stored_rows(source, writer, options: TileOptions) -> StoredRows | None:
    """Level 0 as the input stores it, when that is what the writer would store (8/16-bit codes of sRGB or linear
    light, without alpha, dither or another colour space asked: every code of every channel encodes back to
    itself, :meth:`~pyramid_cli.imageio.ImageStream.gives_back` of the writer's ``encode``): the caller may then keep
    the input's rows as stored (``source.on_stored = kept.keep``) and hand them to the writer beside the decoded
    ones, which it need not encode again (three quarters of all pixels, and the same bytes). None otherwise."""
    dtype, info = getattr(source, "stored_dtype", None), source.info
    valuewise = info.colorspace == info.linear_space or (info.colorspace, info.linear_space) == ("srgb", "linear")
    if (not writer.takes_stored or not hasattr(source, "on_stored") or source.on_stored is not None
            or dtype not in (np.uint8, np.uint16) or info.alpha_channel >= 0
            or options.write.get("dither") or options.write.get("colorspace") is not None
            or not valuewise):
        return None
    if writer.channels != source.shape[2] or not source.gives_back(writer.encode):
        return None
    return StoredRows()


def _prefer(plan) -> int:
    """Rows of the bands a tile set streams in whatever the budget and the executor (flat memory): about
    :data:`TILE_BAND_PIXELS` pixels of the widest level made, at least :data:`TILE_BAND_ROWS`."""
    return max(TILE_BAND_ROWS, band_rows(max(plan.images[k].size[1] for k in plan.outputs), TILE_BAND_PIXELS))


def tile_file(in_path: str, out: str, settings: TileSettings, session, *, memory: int | None = None, read=None,
              reporter: Reporter | None = None, force: bool = False) -> dict:
    """:func:`tile_source` of the image file ``in_path`` decoded as ``read`` (ReadOptions) says."""
    from pyramid_cli.run.settings import ReadOptions

    with open_input(in_path, read or ReadOptions(), keep_half=False) as st:
        return tile_source(st, in_path, out, settings, session, memory=memory, reporter=reporter, force=force)


def tile_files(paths: list[str], template: str | None, settings: TileSettings, session, *, read=None,
               reporter: Reporter | None = None, memory: int | None = None, force: bool = False,
               keep_going: bool = False, skip_existing: bool = False, frames: str | None = None,
               shard=None, cluster=None, chunk: int | None = None, cluster_timeout: float | None = None
               ) -> tuple[Report, list[dict]]:
    """``pyramid tiles`` of ``IN OUT`` or ``IN... -o TEMPLATE`` (frame sequences, ``shard`` ``K/N`` or ``auto``,
    as :func:`pyramid_cli.run.pipeline.process` takes them), one input at a time, each streamed.

    ``cluster`` (a Dask address, ``local:N`` or a Client): each picture's tiles written on its workers in tasks of
    ``chunk`` rows of level-0 tiles (:mod:`pyramid_cli.run.tiles_cluster`); ``session`` is then the workers'
    :class:`~pyramid_cli.run.cluster.worker.SessionSpec` (or a session whose backend and precision they use).

    Returns the report (done, skipped, failed) and each written tile set's description, in job order. A
    single job's failure is raised; a batch's are reported and collected (``keep_going`` goes on past them)."""
    from pyramid_cli.run import batch
    from pyramid_cli.run.tiles_cluster import connection, tile_cluster

    reporter = reporter or Reporter()
    job_list, many = batch.select_jobs(paths, template, frames=frames, shard=shard, keep_going=keep_going,
                                       reporter=reporter)
    report, described = Report(), []
    with connection(cluster, cluster_timeout, reporter, many and bool(job_list)) as (where, label):
        for job in job_list:
            if report.failed and not keep_going:
                break
            if skip_existing and batch.is_fresh(job):
                report.skipped.append(job)
                continue
            try:
                if where is None:
                    described.append(tile_file(job.input, job.output, settings, session, memory=memory, read=read,
                                               reporter=reporter, force=force))
                else:
                    described.append(tile_cluster(job.input, job.output, settings, where, settle=tile_format,
                                                  spec=session, read=read, reporter=reporter, force=force,
                                                  timeout=cluster_timeout, chunk=chunk, label=label))
            except PyramidError as exc:
                if not many:
                    raise
                report.failed.append((job, exc))
                reporter.error(str(exc))
            else:
                report.done.append(job)
    if many and not reporter.quiet:
        reporter.err(f"pyramid: {len(report.done)} written, {len(report.skipped)} up to date, "
                     f"{len(report.failed)} failed")
    return report, described


def tiles(path_or_array, out: str | os.PathLike[str] | Any, *, layout: str | None = None,
          analysis: str = catalogue.MIP_ANALYSIS_DEFAULT, border: str = "clamp", tile_size: int | None = None,
          overlap: int | None = None, format: str | None = None, quality: int | None = None,  # noqa: A002
          compression: str | None = None, iiif_id: str | None = None, memory: int | str | None = None,
          backend: str = "auto", session=None,
          colorspace: str = "auto", alpha: str = "auto", nan: str = "keep", colorconfig: str | None = None,
          pixel_type: str | None = None, tocolorspace: str | None = None, dither: bool = False,
          cluster: Any = None, chunk: int | None = None, cluster_timeout: float | None = None) -> dict:
    """Write a viewer's tile set of an image file or an array: Deep Zoom, IIIF, OME-Zarr or pyramidal TIFF.

    The levels are the analysis pyramid of Kraus & Strengert (§4): each ⌈n/2⌉ of the one before, reduced with
    ``analysis`` in linear light on premultiplied alpha, exact at every border and odd size, streamed band by
    band in bounded memory (``pyramid tiles``; :mod:`pyramid_cli.run.tiles`). Level 0 is the input itself.

    Parameters
    ----------
    path_or_array : str, os.PathLike or array_like
        An image file (decoded as ``colorspace``, ``alpha``, ``nan``, ``colorconfig`` say, as
        :func:`pyramid_cli.api.read_image` does), or H×W or H×W×C pixels taken as linear light, alpha (a 2nd or 4th
        channel) premultiplied, as :func:`pyramid_cli.api.read_image` returns them: integer arrays are read as
        normalised codes (:func:`pyramid_cli.api.as_pixels`), not as sRGB. An array's tiles store floats where the
        format holds them (TIFF, OME-Zarr), else 8-bit codes of ``tocolorspace`` (default: sRGB for JPEG/PNG).
    out : str, os.PathLike or zarr.Group
        ``name.dzi`` (Deep Zoom), a folder with ``layout="iiif3"`` or ``"iiif"``, ``name.ome.zarr``/``name.zarr``,
        ``name.tif`` (pyramidal TIFF) or ``name.ome.tif``; replaced whole when the tile set is complete. A
        ``zarr.Group`` (an array's tiles only) gets the OME-Zarr multiscales written into it.
    layout : {"dz", "iiif3", "iiif", "ome-zarr", "tiff", "ome-tiff"}, optional
        Default: from ``out``'s name (:func:`pyramid_cli.imageio.tilesets.layout_of`).
    analysis : str
        A ⊗↓ filter (``box``, ``box4``, ``quadratic``, ``cubic``) or one-step expression.
    border : {"clamp", "mirror", "wrap", "zero"}
        How the analysis reads past the edges; odd sizes are padded by it.
    tile_size, overlap, quality, compression : optional
        The layout's defaults when None (Deep Zoom: ``vips dzsave``'s 254, 1 and Q 75).
    iiif_id : str, optional
        The IIIF layouts' base address (``vips dzsave --id``): ``info.json``'s id is ``iiif_id/NAME``, where the
        folder ``NAME`` is served.
    format : {"jpeg", "png", "webp", "tif"}, optional
        Tile files of the folder layouts: JPEG, or PNG when the input has alpha (JPEG with alpha is refused).
    memory : int or str, optional
        Working-set budget in bytes or as ``"2G"`` (default: what the process's limits leave).
    backend, session
        As in :func:`pyramid_cli.api.apply`.
    pixel_type, tocolorspace, dither
        How the tiles store the levels (``--type``, ``--tocolorspace``, ``--dither``).
    cluster, chunk, cluster_timeout : optional
        Write the tiles of an image file on a Dask cluster (an address, a scheduler file, ``"local:N"`` or a
        ``distributed.Client``), ``chunk`` rows of level-0 tiles per task, byte for byte the tile set of one
        process (:mod:`pyramid_cli.run.tiles_cluster`; ``--cluster``, ``--chunk``, ``--cluster-timeout``).

    Returns
    -------
    dict
        What ``pyramid tiles --json`` prints: ``layout``, ``path``, ``tile_size``, ``overlap``, ``format``,
        ``levels`` (each its ``level``, ``reduction``, ``size``, ``scale``, ``rule``), ``input``, ``backend``,
        ``analysis``, ``border``, ``band``, ``seconds``.

    References
    ----------
    Kraus & Strengert, "Pyramid Filters Based on Bilinear Interpolation", GRAPP 2007, §4 (analysis ⊗↓).
    """
    from pyramid_cli import imageio as io
    from pyramid_cli.exec.session import Session
    from pyramid_cli.imageio import dtypes
    from pyramid_cli.run.budget import parse_size
    from pyramid_cli.run.report import PythonReporter
    from pyramid_cli.run.settings import ReadOptions

    write: dict = {"pixel_type": pixel_type, "dither": dither}
    if tocolorspace is not None:
        write["colorspace"] = tocolorspace
    settings = TileSettings(layout, analysis, border, _options(tile_size, overlap, format, quality, compression, write,
                                                                 iiif_id))
    budget = parse_size(memory) if isinstance(memory, str) else memory
    if cluster is not None:
        from pyramid_cli.run.tiles_cluster import tiles_on_cluster

        return tiles_on_cluster(path_or_array, out, settings, cluster, settle=tile_format, backend=backend,
                                session=session,
                                read=ReadOptions(colorspace, alpha, nan, colorconfig), memory=budget, chunk=chunk,
                                timeout=cluster_timeout)
    own = session is None
    session = Session(backend) if own else session
    reporter = PythonReporter(quiet=True)
    try:
        if isinstance(path_or_array, (str, os.PathLike)):
            return tile_file(os.fspath(path_or_array), os.fspath(out), settings, session, memory=budget,
                             read=ReadOptions(colorspace, alpha, nan, colorconfig), reporter=reporter)
        pixels = dtypes.as_pixels(path_or_array, "path_or_array")
        pixels = pixels if pixels.ndim == 3 else pixels[:, :, None]
        target = os.fspath(out) if isinstance(out, (str, os.PathLike)) else out  # a zarr.Group stays one
        info = io.info_for_array(target if isinstance(target, str) else "x.zarr", pixels.shape[2])
        if colorconfig is not None:
            info.colorconfig = colorconfig
        return tile_source(ArraySource(pixels, info), "array", target, settings, session, memory=budget,
                           reporter=reporter)
    finally:
        if own:
            session.close()


__all__ = ["TileSettings", "ArraySource", "StoredRows", "stored_rows", "tile_format", "writer_memory", "tile_source",
           "tile_file", "tile_files", "tiles", "FOLDER_LAYOUTS", "TILE_FORMATS"]
