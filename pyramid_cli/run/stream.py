"""File to file in bounded memory: read a band of rows, run it through every level, write it.

A single-image job (``pyramid apply``, ``pyramid blur``) whose whole-picture run would
not fit the memory budget streams instead: the input's scanlines (or rows of tiles) are
read band by band through :mod:`pyramid_cli.imageio`, the plan runs on the demand-driven
row-band scheduler of :mod:`pyramid_cli.exec.tiles` (each image of the plan keeps only the
rows later passes still read: the guard bands, at every level), and the output's rows
are encoded and written as they complete into the temporary file that is renamed onto
the output at the end (atomic, as every write). The pixels are those of the untiled run.
Decoding, computing and encoding overlap: the input is decoded ahead on a thread of its own
and the outputs encoded and written behind on another (:mod:`pyramid_cli.run.overlap`).

The budget is ``--memory SIZE``, or by default what the limits the process is under leave
when the command starts (:mod:`pyramid_cli.run.budget`: a container's cgroup, rlimits, the memory
available). The band height is chosen from it and
from the plan's guard bands (:func:`choose`); work that cannot fit even in the smallest
band is refused before it starts. Images that fit run whole, as before (fastest).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.plan import Plan
from pyramid_cli.run.budget import available_memory, default_memory, format_size, parse_size, resolve
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.overlap import DEPTH, overlapped
from pyramid_cli.run.report import nonfinite_kept

MIN_BAND = 8            # rows: dithering's Bayer pattern and most tile heights are multiples of 8
COPIES = 3              # a band held, its next rows, and the transient concatenation of both
PADDED = 1.25           # textures this many times the pictures: the executor pads the whole picture, so run bands
PADDED_BAND_BYTES = 256 << 20  # … of at most this working set and a quarter of the whole run's (measured best)


@dataclass(frozen=True)
class Choice:
    """How a job runs in its budget: whole, or in bands of ``band`` output rows."""

    budget: int
    whole: int                  # estimated bytes of the whole-picture run
    band: int | None            # output rows per band; None: runs whole
    working_set: int            # estimated bytes of the streamed run (at ``band``)
    kept: int = 0               # a streamed MIP map: bytes of the coarser levels, kept until level 0 is written
    spill: bool = False         # ... in a temporary file beside the output rather than in memory
    padded: float = 0.0         # streams because whole, the executor's textures would be this many times the pictures
    level0: int = 0             # a streamed MIP map read once: bytes of level 0 kept in memory until its header
    faster: bool = False        # streams because it fits whole but is faster in bands (:func:`speed_band`)
    codecs: int = 0             # bytes OpenEXR's codecs hold with one thread each, in the working set (Codecs.first)

    @property
    def streams(self) -> bool:
        return self.band is not None

    def describe(self) -> str:
        if not self.streams:
            return (f"runs whole: about {format_size(self.whole)} within the memory budget of "
                    f"{format_size(self.budget)}")
        why = (" (faster than whole: decoding, computing and encoding overlap, and no whole-picture copies)"
               if self.faster else "")
        said = (f"streams in bands of {self.band} output rows{why}: working set about "
                f"{format_size(self.working_set)} "
                f"within the memory budget of {format_size(self.budget)} (the whole picture would take about "
                f"{format_size(self.whole)})")
        if self.kept:
            where = "in a temporary file beside the output" if self.spill else "in memory (in the working set)"
            said += f"; the coarser levels ({format_size(self.kept)}) are kept {where}"
        if self.level0:
            said += (f"; level 0 ({format_size(self.level0)}) is kept in memory (in the working set) until its "
                     "header is known (the input is read once)")
        if self.padded:
            said += (f"; in bands because whole, the GL textures (powers of two) would be {self.padded:.1f}× the "
                     "pictures: the bands are padded, not the picture")
        if self.codecs:
            said += f"; OpenEXR's codecs hold about {format_size(self.codecs)} of it"
        return said

    def to_json(self) -> dict:
        doc: dict[str, object] = {"budget": self.budget, "whole": self.whole, "band": self.band,
                                  "working_set": self.working_set}
        if self.kept:
            doc.update(kept=self.kept, spill=self.spill)
        if self.level0:
            doc["level0"] = self.level0
        if self.padded:
            doc["padded"] = round(self.padded, 3)
        if self.faster:
            doc["faster"] = True
        if self.codecs:
            doc["codecs"] = self.codecs
        return doc


def _footprints(plan: Plan) -> dict[int, int]:
    """Rows of each image read at once by one period of a consumer (its guard reach), plus alignment."""
    out = {k: 1 for k in range(len(plan.images))}
    for ps in plan.passes:
        target = plan.images[ps.target]
        mid = target.size[0] // 2
        period = getattr(ps, "period", (1, 1))[0]
        y = mid - mid % period
        for s, (rr, _) in ps.reads((y, y + period), (0, 1)).items():
            out[s] = max(out[s], rr[1] - rr[0] + period)
    return out


def estimate(plan: Plan, channels: int, band: int | None, in_bytes: int = 4, out_bytes: int = 4,
             work_bytes: int = 4, texture: Callable[[tuple[int, int]], int] | None = None,
             keeps_input: bool = False) -> int:
    """Bytes a run of ``plan`` holds: whole (``band`` None) or streamed in bands of ``band`` output rows.

    Whole: every image of the plan at once (the executors free images no later pass reads, so this
    is an upper bound), the decoded input and the encoded output. Streamed: per image, its rows per band
    (its share of the band) plus the rows its consumers' guard bands reach, :data:`COPIES` times.
    ``texture``: bytes of the texture an executor keeps for each image's (rows, columns) held, on top
    (the GL executor's power-of-two RGBA textures, host memory on llvmpipe: :func:`costs`).
    ``keeps_input``: the input is written too, as level 0 (``levels``, ``mipmap``), by a writer of its own.
    Streamed, the bands in flight between the threads of :mod:`pyramid_cli.run.overlap` count too."""
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    total = 0
    feet = _footprints(plan)
    for k, im in enumerate(plan.images):
        rows, cols = im.stored
        item = in_bytes if k in plan.inputs else work_bytes
        if band is None:
            total += rows * cols * channels * item
        else:
            share = -(-band * im.size[0] // anchor)
            rows = min(rows, share + feet[k])
            total += COPIES * rows * cols * channels * item
            if k in plan.inputs:  # decoded ahead (run.overlap: the queue and the step being decoded)
                total += (DEPTH + 1) * min(im.size[0], share) * cols * channels * item
        if texture is not None:
            total += texture((rows, cols))
    written = [plan.inputs[0]] * keeps_input + list(plan.outputs)
    for k in written:  # what the writers hold (whole: the results; streamed: a band being encoded)
        rows, cols = plan.images[k].size
        share = rows if band is None else (2 + DEPTH) * -(-band * rows // anchor)  # + the writer's queue
        total += share * cols * channels * out_bytes
    return total


def _band_within(cost: Callable[[int], int], rows: int, avail: int) -> int | None:
    """The largest multiple of :data:`MIN_BAND` rows, up to a band past ``rows``, whose ``cost`` fits ``avail``
    bytes (a bisection: the cost grows with the band); None when not even MIN_BAND rows fit."""
    if cost(MIN_BAND) > avail:
        return None
    lo, hi = MIN_BAND, (rows // MIN_BAND + 2) * MIN_BAND
    while hi - lo > MIN_BAND:
        mid = (lo + hi) // (2 * MIN_BAND) * MIN_BAND  # strictly between lo and hi
        lo, hi = (mid, hi) if cost(mid) <= avail else (lo, mid)
    return lo


def _too_small(where: str, need: int, budget: int, codecs: int = 0) -> DataError:
    prefix = f"{where}: " if where else ""
    held = f", and {format_size(codecs)} that OpenEXR's codecs hold on one thread" if codecs else ""
    return DataError(f"{prefix}this job needs at least {format_size(need)} of memory in bands of {MIN_BAND} "
                     f"rows (its guard bands at every level{held}), over the budget of {format_size(budget)}; "
                     "give more with --memory (memory= in Python)")


def padding(plan: Plan, texture: Callable[[tuple[int, int]], int] | None) -> float:
    """How many times the bytes of textures the pictures' size an executor's textures take in a whole run of
    ``plan`` (1.0 without textures, or with textures the pictures' size; ``texture((1, 1))``: a texel's bytes)."""
    if texture is None:
        return 1.0
    ims = plan.images
    return sum(texture(im.stored) for im in ims) / sum(im.stored[0] * im.stored[1] * texture((1, 1)) for im in ims)


def _pick(plan: Plan, whole: int, budget: int, texture, force: bool, fit: Callable[[int], Choice | None],
          where: str, cost: Callable[[int], int], prefer: int | None = None, codecs: int = 0) -> Choice:
    """Whole, or the bands ``fit(avail)`` finds within ``avail`` bytes (None: not even :data:`MIN_BAND` rows;
    then DataError with the working set ``cost`` gives bands of MIN_BAND rows).

    A run of a picture whose textures the executor pads (GL: :func:`padding` over :data:`PADDED`) goes in
    bands even when it fits the budget, in at most :data:`PADDED_BAND_BYTES` and a quarter of the whole run's,
    so that the bands' textures are padded instead of the picture's; pictures too small for such bands run
    whole. Measured on llvmpipe, fresh processes interleaved, blur --levels 5: 5000x3000 1.9-2.0 s and 424 MB
    peak in bands against 2.0-2.6 s and 1.1 GB whole; 1920x1080 0.70-0.87 s and 229 MB against 0.75-0.83 s
    and 295 MB; mipmap 5000x3000 3.5-3.9 s and 521 MB against 3.4-3.8 s and 1.3 GB, the same bytes.

    ``prefer``: bands of about this many rows are faster than the whole run (:func:`speed_band`); a picture that
    fits whole then streams in them all the same (``Choice.faster``), and one that does not streams in them
    rather than in the largest bands the budget holds (larger bands were no faster, and held gigabytes at 16K)."""
    pad = padding(plan, texture)
    if pad > PADDED:
        choice = fit(min(budget, PADDED_BAND_BYTES, whole // 4))
        if choice is not None:
            return dataclasses.replace(choice, padded=pad)
    faster = fit(min(budget, cost(prefer))) if prefer else None
    if whole <= budget and not force:
        if faster is not None and faster.working_set < whole:
            return dataclasses.replace(faster, faster=True)
        return Choice(budget, whole, None, whole, codecs=codecs)
    if faster is not None:  # bands of the fastest size, not the largest the budget holds: flat memory
        return faster
    choice = fit(budget)
    if choice is None:
        raise _too_small(where, cost(MIN_BAND), budget, codecs)
    return choice


def choose(plan: Plan, channels: int, budget: int, *, in_bytes: int = 4, out_bytes: int = 4, work_bytes: int = 4,
           texture: Callable[[tuple[int, int]], int] | None = None, keeps_input: bool = False, force: bool = False,
           where: str = "", prefer: int | None = None, codecs: int = 0) -> Choice:
    """Whole or streamed, and the band: the largest multiple of :data:`MIN_BAND` rows within ``budget``.

    ``force`` streams even when the whole picture fits; so does a picture whose textures the executor would
    pad, and one for which bands of about ``prefer`` rows are faster (:func:`_pick`, :func:`speed_band`).
    ``codecs``: bytes OpenEXR's codecs hold for the files whatever the band (``Codecs.first``:
    :mod:`pyramid_cli.run.codec_budget`), in every working set. DataError when not even the smallest band fits."""
    def cost(band: int | None) -> int:
        return codecs + estimate(plan, channels, band, in_bytes=in_bytes, out_bytes=out_bytes, work_bytes=work_bytes,
                                 texture=texture, keeps_input=keeps_input)

    whole = cost(None)
    rows = max(plan.images[k].size[0] for k in plan.outputs)

    def fit(avail: int) -> Choice | None:
        band = _band_within(cost, rows, avail)
        return None if band is None else Choice(budget, whole, band, cost(band), codecs=codecs)

    return _pick(plan, whole, budget, texture, force, fit, where, cost, prefer, codecs)


def choose_mip(plan: Plan, channels: int, budget: int, *, in_bytes: int = 4, work_bytes: int = 4,
               texture: Callable[[tuple[int, int]], int] | None = None, level0: int = 0,
               where: str = "", codecs: int = 0, whole: int | None = None) -> Choice:
    """:func:`choose` for a MIP map streamed as :func:`run_mip` streams it.

    Level 0's writer holds a band of rows and their encoding. The coarser levels (``plan.outputs``, about a
    third of level 0) are kept until level 0 is written: in memory when half the budget holds them beside
    the working set, else in a temporary file beside the output (``Choice.spill``). Level 0 itself
    (``level0`` bytes, as read; 0: never) is kept in memory under the same rule when it fits, and the input
    is then read once (``Choice.level0``); otherwise twice (:func:`run_mip`). On disk it would not pay:
    spilling 512 MiB of level 0 at 8K took as long as decoding the input again. ``codecs``: as :func:`choose`.
    ``whole``: the bytes of the whole run where it is not :func:`estimate`'s (a MIP map from its codes:
    :func:`pyramid_cli.run.weight.mip_codes_bytes`), besides the codecs'."""
    def cost(band: int | None) -> int:
        return codecs + estimate(plan, channels, band, in_bytes=in_bytes, out_bytes=4, work_bytes=work_bytes,
                                 texture=texture, keeps_input=True)

    whole = cost(None) if whole is None else codecs + whole
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    kept = sum(a * b * channels * 4 for a, b in (plan.images[k].size for k in plan.outputs))

    def fit(avail: int) -> Choice | None:
        for level0_held, kept_held in ((True, True), (True, False), (False, True), (False, False)):
            if level0_held and not level0:
                continue
            held = kept * kept_held + level0 * level0_held
            band = _band_within(cost, anchor, min(avail, budget - held)) if 2 * held <= budget else None
            if band is not None:
                return Choice(budget, whole, band, cost(band) + held, kept, not kept_held,
                              level0=level0 * level0_held, codecs=codecs)
        return None

    return _pick(plan, whole, budget, texture, False, fit, where, cost, codecs=codecs)


# Pictures of at least STREAM_PIXELS stream on the CPU executor even when they fit whole, in bands of about
# BAND_PIXELS pixels of the widest output (64 rows of 4K). Measured (fresh processes interleaved, the CPU
# seconds, since the 2 shared cores were loaded): a 4K 8-bit PNG blurred with sigma 8 took 2.45 s of CPU whole,
# 2.94 in bands of 16 rows, 2.48 of 32, 2.07 of 64, 2.19 of 128; a 4K half EXR blur --levels 5 2.13 whole, 2.42,
# 2.27, 2.01 and 2.00: from 64 rows no more work than whole, and decoding and encoding then overlap the work.
# At 1080p the CPU seconds were equal within the noise (1.17 whole, 1.24-1.28 in bands), below a megapixel
# a run is over before a pipeline pays.
STREAM_PIXELS = 1 << 20
BAND_PIXELS = 1 << 18


def speed_band(plan: Plan, executor) -> int | None:
    """Rows of the bands in which ``plan`` runs faster streamed than whole on ``executor``, or None when it
    runs whole faster (a small picture; an executor other than the CPU's; a ``wrap`` border, whose images the
    scheduler keeps whole; a plan that does not tile). See :data:`STREAM_PIXELS`."""
    from pyramid_cli.exec.tiles import tileable

    rows = max(plan.images[k].size[0] for k in plan.outputs)
    cols = max(plan.images[k].size[1] for k in plan.outputs)
    if getattr(executor, "backend", None) != "cpu" or rows * cols < STREAM_PIXELS or not tileable(plan):
        return None
    if any(im.border == "wrap" for im in plan.images):
        return None
    band = band_rows(cols)
    return band if rows >= 4 * band else None


def band_rows(width: int, pixels: int | None = None) -> int:
    """Rows of a band of about ``pixels`` (default :data:`BAND_PIXELS`, read when called) pixels of a
    ``width``-pixel-wide image: a multiple of :data:`MIN_BAND`, at least one."""
    return max(MIN_BAND, (BAND_PIXELS if pixels is None else pixels) // max(1, width) // MIN_BAND * MIN_BAND)


def executor_codes(source, executor) -> np.ndarray | None:
    """The table through which the CPU executor reads ``source``'s stored codes itself (no float copy of level 0;
    :func:`pyramid_cli.imageio.read.code_table`), or None (another executor, or rows not decoded code by code)."""
    from pyramid_cli.imageio.read import code_table

    if not reads_codes(executor) or not hasattr(source, "read_stored"):
        return None
    return code_table(source.info, source.stored_dtype, source.shape[2])


def reads_codes(executor) -> bool:
    """Whether ``executor`` reads 8/16-bit codes through a table itself (``run_outputs(..., codes=)``): the CPU
    executor's float32 runs."""
    return getattr(executor, "backend", None) == "cpu" and executor.work_dtype == np.float32


def executor_of(session):
    """The session's plan executor (a UsageError for the reference backend), which from now on also encodes 8-bit
    sRGB where it can (:func:`encode_on`)."""
    ex = session.executor
    if ex is None:
        raise UsageError("--memory needs a plan executor (--backend gl or cpu): the reference backend "
                         "holds whole pictures")
    encode_on(ex)
    return ex


def encode_on(executor) -> None:
    """Have 8-bit sRGB encoding (:func:`pyramid_cli.imageio.colour.srgb8`, the writers' and tile encoders') run on
    the compiled CPU executor's loop (its ``encode8``), where ``executor`` is one: the same codes, 3× faster than
    numpy's lookups. The loop is asked for at its first call, so an executor still loading in the background is
    not waited for here."""
    if not callable(getattr(type(executor), "encode8", None)):
        return
    from pyramid_cli.imageio.colour import use_srgb8_loop

    loop: list = []

    def first(*args) -> None:
        if not loop:
            loop.append(executor.encode8())
        loop[0](*args)

    use_srgb8_loop(first)


def costs(executor) -> dict:
    """What ``executor`` holds per pixel beyond the pictures, as :func:`choose` takes it: float64 working
    images (the emulator), and textures in host memory (GL on a software renderer: ``host_textures``; a GPU's
    are in its own memory, which ``--memory`` does not budget)."""
    return {"work_bytes": np.dtype(executor.work_dtype).itemsize,
            "texture": executor.texture_bytes if executor.host_textures else None}


def read_step(plan: Plan, band: int) -> int:
    """Input rows decoded at a time ahead of a scheduler running ``plan`` in bands of ``band`` output rows: the
    input's share of a band (:mod:`pyramid_cli.run.overlap`)."""
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    rows = max(plan.images[k].size[0] for k in plan.inputs)
    return max(MIN_BAND, -(-band * rows // anchor))


def open_input(path: str, read, keep_half: bool = True):
    """An :class:`~pyramid_cli.imageio.ImageStream` of ``path`` as ``read`` (ReadOptions) asks, half kept half
    (``keep_half`` False: decoded to float32, as the tile writers take every level)."""
    from pyramid_cli import imageio as io

    return io.open_stream(path, colorspace=read.colorspace, alpha=read.alpha, nan=read.nan, keep_half=keep_half,
                          colorconfig=read.colorconfig)


def warn_nonfinite(streams, read, reporter) -> None:
    """Say, as a whole read does (:func:`pyramid_cli.run.inputs.read_input`), how many NaN/Inf each stream kept."""
    if reporter is None or read.nan != "keep":
        return
    for st in streams:
        if st.nonfinite:
            reporter.warn(nonfinite_kept(st.path, st.nonfinite))


@dataclass(frozen=True)
class BandTimes:
    """CPU seconds of a band run's three threads (:func:`run_bands`)."""

    decoding: float
    computing: float
    encoding: float

    def describe(self) -> str:
        return (f"CPU seconds: decoding {self.decoding:.2f}, computing {self.computing:.2f} (this thread), "
                f"encoding and writing {self.encoding:.2f}, each on a thread of its own")


def run_bands(read: Callable[[int, int], np.ndarray], plan: Plan, executor, band: int,
              output_rows: Callable[[int, int, np.ndarray], None],
              input_rows: Callable[[int, np.ndarray], None] | None = None, codes: np.ndarray | None = None
              ) -> BandTimes:
    """The band engine: ``plan`` (one input) on the row-band scheduler of :mod:`pyramid_cli.exec.tiles` in bands of
    ``band`` output rows, the input decoded ahead by ``read(y0, y1)`` and the rows handed behind
    (:mod:`pyramid_cli.run.overlap`).

    ``output_rows(j, y0, px)``: rows of ``plan.outputs[j]`` (the executor's working type), in order within each
    output: read-only views of the scheduler's rows, never written again, which it may keep without a copy;
    ``input_rows(y0, px)``: each input row once, in order, as decoded (a job that keeps its input writes it as
    level 0). Both are called on the writer's thread, in the order the scheduler makes the rows.
    Whatever they hold is theirs to release; an error on any thread, or an interruption, stops and joins both
    threads before it goes on (:func:`~pyramid_cli.run.overlap.overlapped`).

    ``codes``: ``read`` gives 8/16-bit codes, which the executor reads through this table of their float32 values
    (a CPU executor's; :func:`pyramid_cli.imageio.read.code_table`): no float copy of the input exists.
    ``input_rows`` is then given the codes."""
    from pyramid_cli.exec import tiles

    emu = executor.work_dtype == np.float64
    if emu and codes is not None:
        raise ValueError("codes are read by a float32 executor")
    (h, w), = (plan.images[k].size for k in plan.inputs)
    slot = {k: i for i, k in enumerate(plan.outputs)}
    with overlapped(read, h, read_step(plan, band)) as (reader, writer):
        def source(k, rows, cols):
            parts, y = reader.parts(*rows), rows[0]
            for px in parts:  # as decoded: the steps' own arrays, joined once by the scheduler
                if input_rows is not None:
                    writer.call(input_rows, y, px)
                y += len(px)
            if (cols[0], cols[1]) != (0, w):
                parts = [px[:, cols[0]:cols[1]] for px in parts]
            return [px.astype(np.float64) for px in parts] if emu else parts

        def sink(k, r, c0, px):  # the scheduler's rows, never written again: handed on as they are
            writer.call(output_rows, slot[k], r, px)

        scheduler = tiles.Scheduler(executor, plan, source, sink, band=band, dtype=np.float64 if emu else np.float32,
                                    codes=codes)
        started = time.thread_time()
        scheduler.run()
        computed = time.thread_time() - started
    assert reader is not None, "overlapped reads read"
    return BandTimes(reader.busy, computed, writer.busy)


def write_options(write, in_path: str) -> dict:
    """The write options of a job's outputs as a dict (``write``: WriteOptions, a dict, or None)."""
    from pyramid_cli.run.settings import WriteOptions

    wo = write or WriteOptions()
    return wo.for_inputs([in_path]) if not isinstance(wo, dict) else dict(wo)


def output_sizes(work, plan: Plan, h: int, w: int) -> list[tuple[int, int]]:
    """(rows, columns) of each output of ``work``'s ``plan`` on an ``h`` × ``w`` input (the input first, as level
    0, when the job keeps it)."""
    return [(h, w)] * (1 if work.keeps_input else 0) + [plan.images[k].size for k in plan.outputs]


def stream_file(in_path: str, out_path: str | list[str], work, session, choice: Choice | None = None, *,
                budget: int, read=None, write=None, reporter=None, stream=None, attributes: dict | None = None
                ) -> Choice:
    """Run ``work`` from ``in_path`` to ``out_path`` band by band (see the module); a list of paths for a job
    of several outputs (``levels``: level 0, the input, first when the job keeps it).

    ``stream``: an open :class:`pyramid_cli.imageio.ImageStream` of ``in_path`` (opened here if None);
    ``attributes``: metadata added to every output. Returns the :class:`Choice` it ran with."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    ro, wo = read or ReadOptions(), write or WriteOptions()
    executor = executor_of(session)
    paths = [out_path] if isinstance(out_path, (str, os.PathLike)) else list(out_path)
    owned = stream is None
    if owned:
        stream = open_input(in_path, ro)
    try:
        h, w, c = stream.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        options = write_options(wo, in_path)
        info = stream.info
        if attributes:
            info = dataclasses.replace(info, attributes={**info.attributes, **attributes})
        kept = 1 if work.keeps_input else 0
        sizes = output_sizes(work, plan, h, w)
        if len(paths) != len(sizes):
            raise ValueError(f"{work.label} writes {len(sizes)} image(s), got {len(paths)} path(s)")
        half = stream.dtype == np.float16
        dtypes = [np.float16 if half and io.stores_half_unchanged(p, info, pixel_type=options.get("pixel_type"))
                  else np.float32 for p in paths]
        codecs = Codecs.of([stream], list(zip(paths, sizes, strict=True)), info, c, options)
        if choice is None:
            choice = choose(plan, c, budget, in_bytes=stream.dtype.itemsize, out_bytes=4, force=True, where=in_path,
                            keeps_input=bool(kept), codecs=codecs.first, **costs(executor))
        band = choice.band or MIN_BAND
        with (codecs.within(choice, reporter, in_path),
              io.stream_writers(paths, [info] * len(paths), [s + (c,) for s in sizes], **options) as writers):
            def keep(y0: int, px: np.ndarray) -> None:  # level 0 is the input: each row once, in order
                writers[0].write(y0, px.astype(dtypes[0], copy=False))

            def encode(j: int, r: int, px: np.ndarray) -> None:  # on the writer's thread
                writers[kept + j].write(r, px.astype(dtypes[kept + j], copy=False))  # float32 to half: slow, so here

            times = run_bands(stream.read, plan, executor, band, encode, keep if kept else None)
        if reporter is not None:
            reporter.detail(f"{in_path}: {times.describe()}")
        session.ran = session.name
        warn_nonfinite([stream], ro, reporter)
        return choice
    finally:
        if owned:
            stream.close()


STREAMABLE = ("apply", "blur")  # single-image jobs of one output (Work.label); levels: run_levels


def streamable(work) -> bool:
    """Whether :func:`run_job` can stream ``work`` (one of :data:`STREAMABLE`, of one input it does not keep)."""
    return work.label in STREAMABLE and work.n_inputs == 1 and not work.keeps_input


def choose_run(plan: Plan, channels: int, budget: int, executor, *, where: str, reporter=None, in_bytes: int = 4,
               keeps_input: bool = False, codecs: Codecs | None = None,
               limits: contextlib.ExitStack | None = None) -> Choice:
    """A file job's :func:`choose` on ``executor``, bands preferred where faster (:func:`speed_band`), said under
    ``-v``. ``codecs``: the job's files' (:class:`~pyramid_cli.run.codec_budget.Codecs`): their first threads
    counted in the working set, and for a run that goes whole the further ones limited until ``limits`` closes."""
    choice = choose(plan, channels, budget, in_bytes=in_bytes, out_bytes=4, where=where, keeps_input=keeps_input,
                    prefer=speed_band(plan, executor), codecs=codecs.first if codecs else 0, **costs(executor))
    if reporter is not None:
        reporter.detail(f"{where}: {choice.describe()}")
    if not choice.streams and codecs is not None:
        codecs.hold(limits, choice, reporter, where)
    return choice


def _decide(in_path: str, work, session, memory: int | None, read, reporter, outputs: list[str], write=None,
            limits: contextlib.ExitStack | None = None):
    """(open stream, choice) when ``work`` on ``in_path`` streams to ``outputs`` (written as ``write`` asks), else
    None (it runs whole, as before, its codec threads limited in ``limits``: ``Codecs.hold``)."""
    from pyramid_cli.run.settings import ReadOptions

    if session is None or session.executor is None:
        if memory is not None:
            executor_of(session)  # refuses with the reason
        return None
    given = resolve(memory)
    budget = given.size
    if reporter is not None:
        reporter.detail(f"{in_path}: {given.describe()}")
    st = open_input(in_path, read or ReadOptions())
    try:
        h, w, c = st.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        if plan is None:
            st.close()
            return None
        codecs = Codecs.of([st], list(zip(outputs, output_sizes(work, plan, h, w), strict=True)), st.info, c,
                           write_options(write, in_path))
        choice = choose_run(plan, c, budget, executor_of(session), where=in_path, reporter=reporter,
                            in_bytes=st.dtype.itemsize, keeps_input=work.keeps_input, codecs=codecs, limits=limits)
    except DataError as exc:
        st.close()
        raise given.refusal(exc) from None
    except BaseException:
        st.close()
        raise
    if not choice.streams:
        st.close()
        return None
    return st, choice


def run_job(job, work, session, *, memory: int | None, read=None, write=None, reporter=None,
            limits: contextlib.ExitStack | None = None) -> bool:
    """Stream ``job`` when its whole-picture run would not fit the budget (``memory``, else
    :func:`pyramid_cli.run.budget.default_budget`); False when it runs whole as before (it fits, or cannot
    stream: another kind of job, an output format encoded whole, the reference backend without ``memory``), then
    with OpenEXR's codec threads limited to what the budget leaves them until ``limits`` closes."""
    from pyramid_cli import imageio as io

    if not streamable(work):
        if memory is not None:
            raise UsageError(f"--memory: {work.label} runs whole pictures (it streams apply, blur and levels)")
        return False
    if not io.streams_to(job.output):
        return False
    decided = _decide(job.input, work, session, memory, read, reporter, [job.output], write, limits)
    if decided is None:
        return False
    st, choice = decided
    if reporter is not None:
        options = write.for_inputs([]) if hasattr(write, "for_inputs") else dict(write or {})
        reporter.detail(f"{io.describe_rules(st.info)}; {io.describe_output(job.output, st.info, **options)}")
    with st:
        stream_file(job.input, job.output, work, session, choice, budget=choice.budget, read=read, write=write,
                    reporter=reporter, stream=st)
        h, w = st.shape[:2]
    if reporter is not None:
        reporter.result(f"wrote {job.output} ({w}×{h}, {session.ran}, streamed in bands of {choice.band} rows)")
    return True


def run_levels(in_path: str, paths: list[str], work, session, *, memory: int | None, read=None, options=None,
               attributes: dict | None = None, reporter=None, limits: contextlib.ExitStack | None = None) -> bool:
    """``pyramid levels`` (one file per level) streamed when the whole pyramid would not fit the budget;
    False when it runs whole as before (OpenEXR's codec threads limited until ``limits`` closes, as
    :func:`run_job`). ``options``: the write options (:func:`pyramid_cli.imageio.write_image`)."""
    from pyramid_cli import imageio as io

    if not all(io.streams_to(p) for p in paths):
        return False
    decided = _decide(in_path, work, session, memory, read, reporter, paths, options, limits)
    if decided is None:
        return False
    st, choice = decided
    with st:
        stream_file(in_path, paths, work, session, choice, budget=choice.budget, read=read, write=options,
                    reporter=reporter, stream=st, attributes=attributes)
    return True


__all__ = ["BandTimes", "Choice", "choose", "choose_mip", "estimate", "parse_size", "default_memory",
           "available_memory", "stream_file", "open_input", "format_size", "run_job", "run_levels", "costs",
           "executor_of", "read_step", "run_bands", "speed_band", "band_rows", "warn_nonfinite", "streamable",
           "choose_run", "reads_codes", "output_sizes", "write_options", "MIN_BAND",
           "STREAM_PIXELS", "BAND_PIXELS"]
