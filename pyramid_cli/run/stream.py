"""File to file in bounded memory: read a band of rows, run it through every level, write it.

A single-image job (``pyramid apply``, ``pyramid blur``) whose whole-picture run would
not fit the memory budget streams instead: the input's scanlines (or rows of tiles) are
read band by band through :mod:`pyramid_cli.imageio`, the plan runs on the demand-driven
row-band scheduler of :mod:`pyramid_cli.exec.tiles` (each image of the plan keeps only the
rows later passes still read: the guard bands, at every level), and the output's rows
are encoded and written as they complete into the temporary file that is renamed onto
the output at the end (atomic, as every write). The pixels are those of the untiled run.

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
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pyramid_cli.core.errors import DataError, OutputError, UsageError
from pyramid_cli.plan import Plan
from pyramid_cli.run.budget import available_memory, default_memory, format_size, parse_size, resolve

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

    @property
    def streams(self) -> bool:
        return self.band is not None

    def describe(self) -> str:
        if not self.streams:
            return (f"runs whole: about {format_size(self.whole)} within the memory budget of "
                    f"{format_size(self.budget)}")
        said = (f"streams in bands of {self.band} output rows: working set about {format_size(self.working_set)} "
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
        return said

    def to_json(self) -> dict:
        doc = {"budget": self.budget, "whole": self.whole, "band": self.band, "working_set": self.working_set}
        if self.kept:
            doc.update(kept=self.kept, spill=self.spill)
        if self.level0:
            doc["level0"] = self.level0
        if self.padded:
            doc["padded"] = round(self.padded, 3)
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
    ``keeps_input``: the input is written too, as level 0 (``levels``, ``mipmap``), by a writer of its own."""
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    total = 0
    feet = _footprints(plan)
    for k, im in enumerate(plan.images):
        rows, cols = im.stored
        item = in_bytes if k in plan.inputs else work_bytes
        if band is None:
            total += rows * cols * channels * item
        else:
            rows = min(rows, -(-band * im.size[0] // anchor) + feet[k])
            total += COPIES * rows * cols * channels * item
        if texture is not None:
            total += texture((rows, cols))
    written = [plan.inputs[0]] * keeps_input + list(plan.outputs)
    for k in written:  # what the writers hold (whole: the results; streamed: a band being encoded)
        rows, cols = plan.images[k].size
        share = rows if band is None else 2 * -(-band * rows // anchor)
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


def _too_small(where: str, need: int, budget: int) -> DataError:
    prefix = f"{where}: " if where else ""
    return DataError(f"{prefix}this job needs at least {format_size(need)} of memory in bands of {MIN_BAND} "
                     f"rows (its guard bands at every level), over the budget of {format_size(budget)}; "
                     "give more with --memory (memory= in Python)")


def padding(plan: Plan, texture: Callable[[tuple[int, int]], int] | None) -> float:
    """How many times the bytes of textures the pictures' size an executor's textures take in a whole run of
    ``plan`` (1.0 without textures, or with textures the pictures' size; ``texture((1, 1))``: a texel's bytes)."""
    if texture is None:
        return 1.0
    ims = plan.images
    return sum(texture(im.stored) for im in ims) / sum(im.stored[0] * im.stored[1] * texture((1, 1)) for im in ims)


def _pick(plan: Plan, whole: int, budget: int, texture, force: bool, fit: Callable[[int], Choice | None],
          where: str, cost: Callable[[int], int]) -> Choice:
    """Whole, or the bands ``fit(avail)`` finds within ``avail`` bytes (None: not even :data:`MIN_BAND` rows;
    then DataError with the working set ``cost`` gives bands of MIN_BAND rows).

    A run of a picture whose textures the executor pads (GL: :func:`padding` over :data:`PADDED`) goes in
    bands even when it fits the budget, in at most :data:`PADDED_BAND_BYTES` and a quarter of the whole run's,
    so that the bands' textures are padded instead of the picture's; pictures too small for such bands run
    whole. Measured on llvmpipe, fresh processes interleaved, blur --levels 5: 5000x3000 1.9-2.0 s and 424 MB
    peak in bands against 2.0-2.6 s and 1.1 GB whole; 1920x1080 0.70-0.87 s and 229 MB against 0.75-0.83 s
    and 295 MB; mipmap 5000x3000 3.5-3.9 s and 521 MB against 3.4-3.8 s and 1.3 GB, the same bytes."""
    pad = padding(plan, texture)
    if pad > PADDED:
        choice = fit(min(budget, PADDED_BAND_BYTES, whole // 4))
        if choice is not None:
            return dataclasses.replace(choice, padded=pad)
    if whole <= budget and not force:
        return Choice(budget, whole, None, whole)
    choice = fit(budget)
    if choice is None:
        raise _too_small(where, cost(MIN_BAND), budget)
    return choice


def choose(plan: Plan, channels: int, budget: int, *, in_bytes: int = 4, out_bytes: int = 4, work_bytes: int = 4,
           texture: Callable[[tuple[int, int]], int] | None = None, keeps_input: bool = False, force: bool = False,
           where: str = "") -> Choice:
    """Whole or streamed, and the band: the largest multiple of :data:`MIN_BAND` rows within ``budget``.

    ``force`` streams even when the whole picture fits; so does a picture whose textures the executor would
    pad (:func:`_pick`). DataError when not even the smallest band fits."""
    kw = {"in_bytes": in_bytes, "out_bytes": out_bytes, "work_bytes": work_bytes, "texture": texture,
          "keeps_input": keeps_input}
    whole = estimate(plan, channels, None, **kw)
    rows = max(plan.images[k].size[0] for k in plan.outputs)

    def cost(band: int) -> int:
        return estimate(plan, channels, band, **kw)

    def fit(avail: int) -> Choice | None:
        band = _band_within(cost, rows, avail)
        return None if band is None else Choice(budget, whole, band, cost(band))

    return _pick(plan, whole, budget, texture, force, fit, where, cost)


def choose_mip(plan: Plan, channels: int, budget: int, *, in_bytes: int = 4, work_bytes: int = 4,
               texture: Callable[[tuple[int, int]], int] | None = None, level0: int = 0,
               where: str = "") -> Choice:
    """:func:`choose` for a MIP map streamed as :func:`run_mip` streams it.

    Level 0's writer holds a band of rows and their encoding. The coarser levels (``plan.outputs``, about a
    third of level 0) are kept until level 0 is written: in memory when half the budget holds them beside
    the working set, else in a temporary file beside the output (``Choice.spill``). Level 0 itself
    (``level0`` bytes, as read; 0: never) is kept in memory under the same rule when it fits, and the input
    is then read once (``Choice.level0``); otherwise twice (:func:`run_mip`). On disk it would not pay:
    spilling 512 MiB of level 0 at 8K took as long as decoding the input again."""
    kw = {"in_bytes": in_bytes, "out_bytes": 4, "work_bytes": work_bytes, "texture": texture, "keeps_input": True}
    whole = estimate(plan, channels, None, **kw)
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    kept = sum(a * b * channels * 4 for a, b in (plan.images[k].size for k in plan.outputs))

    def cost(band: int) -> int:
        return estimate(plan, channels, band, **kw)

    def fit(avail: int) -> Choice | None:
        for level0_held, kept_held in ((True, True), (True, False), (False, True), (False, False)):
            if level0_held and not level0:
                continue
            held = kept * kept_held + level0 * level0_held
            band = _band_within(cost, anchor, min(avail, budget - held)) if 2 * held <= budget else None
            if band is not None:
                return Choice(budget, whole, band, cost(band) + held, kept, not kept_held,
                              level0=level0 * level0_held)
        return None

    return _pick(plan, whole, budget, texture, False, fit, where, cost)


def _executor(session):
    ex = session.executor
    if ex is None:
        raise UsageError("--memory needs a plan executor (--backend gl or cpu): the reference backend "
                         "holds whole pictures")
    return ex


def costs(executor) -> dict:
    """What ``executor`` holds per pixel beyond the pictures, as :func:`choose` takes it: float64 working
    images (the emulator), and textures in host memory (GL on a software renderer: ``host_textures``; a GPU's
    are in its own memory, which ``--memory`` does not budget)."""
    return {"work_bytes": np.dtype(executor.work_dtype).itemsize,
            "texture": executor.texture_bytes if executor.host_textures else None}


def stream_file(in_path: str, out_path: str | list[str], work, session, choice: Choice | None = None, *,
                budget: int, read=None, write=None, reporter=None, stream=None, attributes: dict | None = None
                ) -> Choice:
    """Run ``work`` from ``in_path`` to ``out_path`` band by band (see the module); a list of paths for a job
    of several outputs (``levels``: level 0, the input, first when the job keeps it).

    ``stream``: an open :class:`pyramid_cli.imageio.ImageStream` of ``in_path`` (opened here if None);
    ``attributes``: metadata added to every output. Returns the :class:`Choice` it ran with."""
    from pyramid_cli import imageio as io
    from pyramid_cli.exec import tiles
    from pyramid_cli.run.settings import ReadOptions, WriteOptions

    ro, wo = read or ReadOptions(), write or WriteOptions()
    executor = _executor(session)
    paths = [out_path] if isinstance(out_path, (str, os.PathLike)) else list(out_path)
    owned = stream is None
    if owned:
        stream = io.open_stream(in_path, colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan, keep_half=True)
    try:
        h, w, c = stream.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        options = wo.for_inputs([in_path]) if not isinstance(wo, dict) else dict(wo)
        info = stream.info
        if attributes:
            info = dataclasses.replace(info, attributes={**info.attributes, **attributes})
        kept = 1 if work.keeps_input else 0
        sizes = [(h, w)] * kept + [plan.images[k].size for k in plan.outputs]
        if len(paths) != len(sizes):
            raise ValueError(f"{work.label} writes {len(sizes)} image(s), got {len(paths)} path(s)")
        half = stream.dtype == np.float16
        dtypes = [np.float16 if half and io.stores_half_unchanged(p, info, pixel_type=options.get("pixel_type"))
                  else np.float32 for p in paths]
        emu = executor.work_dtype == np.float64
        if choice is None:
            choice = choose(plan, c, budget, in_bytes=stream.dtype.itemsize, out_bytes=4, force=True, where=in_path,
                            keeps_input=bool(kept), **costs(executor))
        band = choice.band or MIN_BAND
        slot = {k: kept + i for i, k in enumerate(plan.outputs)}
        with io.stream_writers(paths, [info] * len(paths), [s + (c,) for s in sizes], **options) as writers:
            def source(k, rows, cols):
                px = stream.read(*rows)
                if kept:  # level 0 is the input: written as it is read (each row once, in order)
                    writers[0].write(rows[0], px.astype(dtypes[0], copy=False))
                px = px[:, cols[0]:cols[1]] if (cols[0], cols[1]) != (0, w) else px
                return px.astype(np.float64) if emu else px

            def sink(k, r, c0, px):  # px is the scheduler's buffer: the writer may keep rows, so a copy
                j = slot[k]
                writers[j].write(r, px.astype(dtypes[j]))

            scheduler = tiles.Scheduler(executor, plan, source, sink, band=band,
                                        dtype=np.float64 if emu else np.float32)
            scheduler.run()
        session.ran = session.name
        if reporter is not None and stream.nonfinite and ro.nan == "keep":
            reporter.warn(f"{in_path}: {stream.nonfinite} NaN/Inf value(s) kept; they spread through the filter "
                          "(--nan zero or --nan fail to change that)")
        return choice
    finally:
        if owned:
            stream.close()


STREAMABLE = ("apply", "blur")  # single-image jobs of one output (Work.label); levels: run_levels


def _decide(in_path: str, work, session, memory: int | None, read, reporter):
    """(open stream, choice) when ``work`` on ``in_path`` streams, else None (it runs whole, as before)."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.settings import ReadOptions

    if session is None or session.executor is None:
        if memory is not None:
            _executor(session)  # refuses with the reason
        return None
    ro = read or ReadOptions()
    given = resolve(memory)
    budget = given.size
    if reporter is not None:
        reporter.detail(f"{in_path}: {given.describe()}")
    st = io.open_stream(in_path, colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan, keep_half=True)
    try:
        h, w, c = st.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        if plan is None:
            st.close()
            return None
        choice = choose(plan, c, budget, in_bytes=st.dtype.itemsize, out_bytes=4, where=in_path,
                        keeps_input=work.keeps_input, **costs(_executor(session)))
    except BaseException:
        st.close()
        raise
    if reporter is not None:
        reporter.detail(f"{in_path}: {choice.describe()}")
    if not choice.streams:
        st.close()
        return None
    return st, choice


def run_job(job, work, session, *, memory: int | None, read=None, write=None, reporter=None) -> bool:
    """Stream ``job`` when its whole-picture run would not fit the budget (``memory``, else
    :func:`default_memory`); False when it runs whole as before (it fits, or cannot stream: another kind
    of job, an output format encoded whole, the reference backend without ``memory``)."""
    from pyramid_cli import imageio as io

    if work.label not in STREAMABLE or work.n_inputs != 1 or work.keeps_input:
        if memory is not None:
            raise UsageError(f"--memory: {work.label} runs whole pictures (it streams apply, blur and levels)")
        return False
    if not io.streams_to(job.output):
        return False
    decided = _decide(job.input, work, session, memory, read, reporter)
    if decided is None:
        return False
    st, choice = decided
    with st:
        stream_file(job.input, job.output, work, session, choice, budget=choice.budget, read=read, write=write,
                    reporter=reporter, stream=st)
        h, w = st.shape[:2]
    if reporter is not None:
        reporter.result(f"wrote {job.output} ({w}×{h}, {session.ran}, streamed in bands of {choice.band} rows)")
    return True


def run_levels(in_path: str, paths: list[str], work, session, *, memory: int | None, read=None, options=None,
               attributes: dict | None = None, reporter=None) -> bool:
    """``pyramid levels`` (one file per level) streamed when the whole pyramid would not fit the budget;
    False when it runs whole as before. ``options``: the write options (:func:`pyramid_cli.imageio.write_image`)."""
    from pyramid_cli import imageio as io

    if not all(io.streams_to(p) for p in paths):
        return False
    decided = _decide(in_path, work, session, memory, read, reporter)
    if decided is None:
        return False
    st, choice = decided
    with st:
        stream_file(in_path, paths, work, session, choice, budget=choice.budget, read=read, write=options,
                    reporter=reporter, stream=st, attributes=attributes)
    return True


class _Kept:
    """MIP levels' rows until their turn (a MIP file holds level 0 first, its header before its rows): arrays
    of ``dtype`` in memory, or, given ``spill``, a raw file read and written with explicit I/O (no mapping: the
    rows on disk do not count in the process's memory). A spill that fails (a full disk) is an OutputError
    naming ``beside``, the output the file sits beside (exit 4)."""

    def __init__(self, shapes: list[tuple[int, int, int]], spill: str | None = None, dtype=np.float32,
                 beside: str = ""):
        self.shapes, self.dtype, self.beside = shapes, np.dtype(dtype), beside
        self.arrays = None if spill else [np.empty(s, dtype=self.dtype) for s in shapes]
        self.fd = None
        self.offsets = [0]
        for h, w, c in shapes:
            self.offsets.append(self.offsets[-1] + h * w * c * self.dtype.itemsize)
        if spill:
            self.fd = os.open(spill, os.O_RDWR)

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def _at(self, i: int, r: int) -> int:
        _, w, c = self.shapes[i]
        return self.offsets[i] + r * w * c * self.dtype.itemsize

    def write(self, i: int, r: int, px: np.ndarray) -> None:
        if self.arrays is not None:
            self.arrays[i][r:r + len(px)] = px
            return
        view = memoryview(np.ascontiguousarray(px, dtype=self.dtype)).cast("B")
        at = self._at(i, r)
        try:
            while view:
                n = os.pwrite(self.fd, view, at)
                view, at = view[n:], at + n
        except OSError as exc:
            raise self._failed(exc) from None

    def _failed(self, exc: OSError) -> OutputError:
        from pyramid_cli.imageio.atomic import error_reason

        return OutputError(f"cannot write {self.beside}: {error_reason(exc)} (in the temporary file of its coarser "
                           "MIP levels beside it)")

    def rows(self, i: int, r0: int, r1: int) -> np.ndarray:
        if self.arrays is not None:
            return self.arrays[i][r0:r1]
        _, w, c = self.shapes[i]
        size = (r1 - r0) * w * c * self.dtype.itemsize
        data = bytearray()
        try:
            while len(data) < size:
                chunk = os.pread(self.fd, size - len(data), self._at(i, r0) + len(data))
                if not chunk:
                    raise OSError(f"the spill file ends {size - len(data)} bytes early")
                data += chunk
        except OSError as exc:
            raise self._failed(exc) from None
        return np.frombuffer(data, dtype=self.dtype).reshape(r1 - r0, w, c)


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
    st.on_stored = stats.hash_rows
    try:
        for y in range(0, h, step):
            px = st.read(y, min(h, y + step)).astype(np.float32, copy=False)
            stats.add_decoded(px)
            stats.add_encoded(io.encoded_rows(out_path, io.Image(px, st.info), **options))
    finally:
        st.on_stored = None
    return stats


def run_mip(job, work, session, *, memory: int | None, tile: int, read=None, write=None, reporter=None) -> bool:
    """``pyramid mipmap`` of one input streamed when its whole run would not fit the budget (``memory``, else
    :func:`default_memory`); False when it runs whole as before.

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
            _executor(session)  # refuses with the reason
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
    executor = _executor(session)
    emu = executor.work_dtype == np.float64

    def open_input():
        return io.open_stream(in_path, colorspace=ro.colorspace, alpha=ro.alpha, nan=ro.nan, keep_half=True)

    with contextlib.ExitStack() as stack:
        st = stack.enter_context(open_input())
        h, w, c = st.shape
        work.check(((h, w),), where=in_path)
        plan = session.plan(work, [(h, w)])
        if plan is None:
            return False
        kw = {"in_bytes": st.dtype.itemsize, "where": in_path, **costs(executor)}
        choice = choose_mip(plan, c, budget, level0=h * w * c * st.dtype.itemsize, **kw)
        reporter.detail(f"{in_path}: {choice.describe()}")
        if not choice.streams:
            return False
        if not tiles.tileable(plan):
            if memory is not None:
                raise UsageError(f"--memory: the MIP levels of a {w}×{h} picture cannot stream (a pass of its plan "
                                 "does not tile); leave --memory out to run it whole")
            return False
        shapes = [(h, w, c)] + [plan.images[k].size + (c,) for k in plan.outputs]
        info = st.info
        options = wo.for_inputs([in_path])
        io.check_write_options(out_path, wo.pixel_type, wo.compression)  # refused before any work
        step = 2 * max(MIN_BAND, choice.band)  # level 0's rows at a time outside the scheduler (multiples of 8)
        stats = PixelStats(h)
        once = bool(choice.level0)
        if once:  # level 0 kept as read while the scheduler runs; its header's statistics gathered on the way
            level0 = _Kept([shapes[0]], None, st.dtype)
            st.on_stored = stats.hash_rows
        else:  # the first read, for the header; the scheduler reads again, writing level 0 as it reads it
            _level0_stats(st, stats, step, out_path, options)
            if _constant(work, stats):
                return _write_constant(work, session, stats, shapes[0], tile, in_path, out_path, info, options,
                                       reporter)
            st = stack.enter_context(open_input())
        kept = _Kept(shapes[1:], stack.enter_context(_scratch(out_path)) if choice.spill else None,
                     beside=out_path)
        stack.callback(kept.close)

        def open_writer():
            meta = mip_metadata(work, in_path, stats.sha1())
            return stack.enter_context(io.mip_stream_writer(out_path, info, shapes, tile=tile, meta=meta,
                                                            colors=(stats.average(), stats.constant()), **options))

        writer = None if once else open_writer()
        slot = {k: i for i, k in enumerate(plan.outputs)}

        def source(k, rows, cols):
            px = st.read(*rows)
            if once:
                level0.write(0, rows[0], px)
                stats.add_decoded(px)
            else:
                writer.write(rows[0], px.astype(np.float32, copy=False))  # level 0: each row once, in order
            px = px[:, cols[0]:cols[1]] if (cols[0], cols[1]) != (0, w) else px
            return px.astype(np.float64) if emu else px

        def sink(k, r, c0, px):
            kept.write(slot[k], r, px)

        tiles.Scheduler(executor, plan, source, sink, band=choice.band, dtype=np.float64 if emu else np.float32).run()
        if once:
            st.on_stored = None
            for y in range(0, h, step):  # level 0 as encoded, in the bands of the two-read way (dithering lines up)
                rows = level0.rows(0, y, min(h, y + step)).astype(np.float32, copy=False)
                stats.add_encoded(io.encoded_rows(out_path, io.Image(rows, info), **options))
            if _constant(work, stats):
                return _write_constant(work, session, stats, shapes[0], tile, in_path, out_path, info, options,
                                       reporter)
            writer = open_writer()
            for y in range(0, h, step):
                writer.write(y, level0.rows(0, y, min(h, y + step)).astype(np.float32, copy=False))
        for i in range(len(shapes) - 1):
            writer.append_level(lambda r0, r1, i=i: kept.rows(i, r0, r1))
    session.ran = session.name
    if st.nonfinite and ro.nan == "keep":
        reporter.warn(f"{in_path}: {st.nonfinite} NaN/Inf value(s) kept; they spread through the filter "
                      "(--nan zero or --nan fail to change that)")
    reporter.result(f"wrote {out_path} ({w}×{h}, {len(shapes)} MIP levels, {session.ran}, streamed in bands of "
                    f"{choice.band} rows{', the input read once' if once else ''})")
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
    reporter.detail(f"{in_path}: constant colour, made from one {small.shape[1]}×{small.shape[0]} tile")
    outs = session.run(work, [small], np.float32)
    io.write_levels(out_path, [io.Image(px, info) for px in outs], mode="mipmap", tile=tile,
                    meta=mip_metadata(work, in_path, stats.sha1()), **options)
    reporter.result(f"wrote {out_path} ({w}×{h}, {len(outs)} MIP levels, {session.ran})")
    return True


__all__ = ["Choice", "choose", "choose_mip", "estimate", "parse_size", "default_memory", "available_memory",
           "stream_file", "format_size", "run_job", "run_levels", "run_mip", "mip_metadata"]
