"""Tiled execution of any :class:`~pyramid_cli.plan.model.Plan`: bounded memory, the untiled run's pixels.

Every output pixel of a plan depends on a bounded window of its inputs: the rectangles
that :meth:`Pass.reads <pyramid_cli.plan.model.Pass.reads>` gives, which include the guard
bands bounds inference found (docs/design.md §1). The scheduler here is demand-driven in the
manner of libvips: the outputs are cut into column strips, and within a strip every image
of the plan (inputs, intermediates, every level of a pyramid) keeps only the band of rows
that later passes still need. Asking an output for its next rows asks the pass that
writes it for those rows, which asks its sources for the rows it reads, and so on up to
the inputs, which are read through a callback (a file's scanlines, a memory map's rows).
Rows no later pass will read are dropped at once. Nothing is computed twice along the
rows; across strips the columns of the guard bands are.

Each step runs *one pass* over a rectangle of its target, as a one-pass plan handed to
the executor unchanged: the images of that plan are the windows, each placed by its
guard band (which may be negative) so that the pass's phases and base indices
``R = S·⌈r/P⌉`` are those of the whole image (:meth:`Pass.tile`). Reads that leave a
source resolve as in the untiled run:

- a ``clamp`` source's window is cut to its stored extent, so the executor's own clamp
  acts at the same edges (window edges inside the image are never read past: the
  window holds everything the rectangle reads);
- a ``mirror``, ``wrap`` or ``zero`` source's window is gathered through the border fold
  (:func:`pyramid_cli.core.border.fold`); it is never read past, so its own fold is the identity
  and the executors use the arithmetic of the untiled run.

Hence every executor (:mod:`pyramid_cli.exec.emulate`, :mod:`pyramid_cli.exec.cpu`,
:mod:`pyramid_cli.exec.gl`) gives the same pixels tiled and untiled; the GL executor thereby
runs images larger than GL_MAX_TEXTURE_SIZE with textures of the tile's size, not the
picture's. ``wrap`` images are kept whole (their first rows read their last ones).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pyramid_cli.exec.base import Executor
from pyramid_cli.exec.gather import fold_stored, gather
from pyramid_cli.plan.model import Image, Plan

Rect = tuple[tuple[int, int], tuple[int, int]]
Source = Callable[[int, tuple[int, int], tuple[int, int]], np.ndarray]   # (input, rows, cols) → (h, w, C)
Sink = Callable[[int, int, int, np.ndarray], None]                       # (output, row, col, pixels)


def _restrict(span: tuple[int, int], extent: tuple[int, int], border: str) -> tuple[int, int]:
    """Stored indices (within ``extent``) a read of ``span`` touches: clamped, or the hull of the fold."""
    a, b = span
    e0, e1 = extent
    if border == "clamp" or (e0 <= a and b <= e1):
        lo = min(max(a, e0), e1 - 1)
        return lo, max(min(b, e1), lo + 1)
    idx = _fold(np.arange(a, b), extent, border)
    idx = idx[idx >= e0]
    if not len(idx):
        return e0, e0 + 1
    return int(idx.min()), int(idx.max()) + 1


def _fold(index: np.ndarray, extent: tuple[int, int], border: str) -> np.ndarray:
    """0-based logical indices folded into ``extent`` (an image without guard: ``(0, n)``); ``e0 − 1``: zero: the
    stored indices' fold (:func:`~pyramid_cli.exec.gather.fold_stored`) shifted by the extent's start."""
    e0, e1 = extent
    return fold_stored(index - e0, e1 - e0, border) + e0


def _union(a, b):
    if a is None:
        return b
    return min(a[0], b[0]), max(a[1], b[1])


# Rows an output other than the lead waits for before it advances (fewer when its band is smaller): fewer steps of a
# pass's fixed work, while the rows its sources keep for it stay few. A MIP map's bands of 120 rows held 34 MiB
# more when its coarse levels waited for a band of their own.
STEP_ROWS = 32


@dataclass
class _State:
    """One image in one strip: the band of rows ``[start, done)`` × ``cols`` it keeps."""

    rows: tuple[int, int]            # stored extent (0-based logical: guard rows are negative or ≥ size)
    colext: tuple[int, int]
    border: str
    cols: tuple[int, int] | None = None  # kept columns (within the extent)
    comp: tuple[int, int] | None = None  # columns its pass computes (aligned; targets only)
    start: int | None = None
    done: int | None = None
    buf: np.ndarray | None = None
    emitted: int = 0
    consumers: list = field(default_factory=list)

    def kept(self) -> tuple[int, int]:
        """``cols``: set by the strip for every image it reads or writes."""
        assert self.cols is not None, "an image outside the strip's demand"
        return self.cols

    def computed(self) -> tuple[int, int]:
        """``comp``: set by the strip for the target of every pass it runs."""
        assert self.comp is not None, "an image no pass of the strip computes"
        return self.comp

    def held(self) -> tuple[int, int]:
        """``(start, done)``: set when the image is first advanced."""
        assert self.start is not None and self.done is not None, "an image read before it is advanced"
        return self.start, self.done

    def pixels(self) -> np.ndarray:
        """``buf``: set when the first rows are appended."""
        assert self.buf is not None, "an image read before rows are appended"
        return self.buf


class Scheduler:
    """Runs ``plan`` strip by strip, band by band: see the module docstring.

    Parameters
    ----------
    executor : Executor
        Runs the one-pass plans (:class:`~pyramid_cli.exec.base.Executor`: its ``run_outputs``):
        :class:`~pyramid_cli.exec.cpu.CPUExecutor`, :class:`~pyramid_cli.exec.gl.GLExecutor`,
        :class:`~pyramid_cli.exec.emulate.Emulator`.
    plan : Plan
        Any plan of tileable passes (every kind with ``reads`` and ``tile``).
    source : callable
        ``source(k, rows, cols)``: pixels of input image ``k`` over 0-based half-open ``rows × cols``
        (inside the image), (h, w, C), or a list of such arrays of consecutive rows (joined once, with the rows
        the image keeps).
    sink : callable
        ``sink(k, row, col, pixels)``: output image ``k``'s pixels at ``(row, col)``; called in row order
        within a strip. ``pixels`` is a read-only view of the scheduler's buffers, whose rows are never written
        again once made (:meth:`_append` and :meth:`_room` make a new buffer, :meth:`_trim` only narrows the
        view): a sink may keep it without a copy, holding that buffer's memory while it does.
    band, width : int
        Rows and columns of a tile, in pixels of the largest output (smaller outputs get their share).
    dtype
        What the executor stores intermediates as (float32; the emulator keeps float64).
    windows : dict, optional
        ``{output image: (first row, end row)}``: make only these rows of each output (an output not named:
        none), with the pixels of the whole run (a part of a picture run on a cluster worker). Every image is
        then read and made from the first row its window needs (:meth:`run`).
    codes : ndarray, optional
        The sources give 8/16-bit codes, kept as they are (uint8, uint16) and read through this table of their
        float32 values by the executor (the CPU executor's ``run_outputs(..., codes=)``).
    """

    def __init__(self, executor: Executor, plan: Plan, source: Source, sink: Sink, *, band: int,
                 width: int | None = None, dtype=np.float32, windows: dict[int, tuple[int, int]] | None = None,
                 codes: np.ndarray | None = None):
        self.executor, self.plan, self.source, self.sink = executor, plan, source, sink
        self.codes = {} if codes is None else {"codes": codes}
        self.windows = None if windows is None else {k: windows.get(k, (0, 0)) for k in plan.outputs}
        self.band = max(1, int(band))
        rows = max(plan.images[k].size[0] for k in plan.outputs)
        cols = max(plan.images[k].size[1] for k in plan.outputs)
        self.anchor = (rows, cols)
        self.width = max(1, int(width)) if width else cols
        self.dtype = dtype
        self.writer = {ps.target: ps for ps in plan.passes}
        self.steps = 0          # executor calls, for reports
        self.peak_pixels = 0      # most pixels held at once (all images), for reports

    # ------------------------------------------------------------ driving
    def run(self) -> None:
        """Strip by strip, band by band. Only the tallest output follows the band; every other output
        advances as far as the rows its pass reads are already held, once that is a band of its own rows (at
        most :data:`STEP_ROWS`; or all it has left), and all finish at the last band. (Asking every output for
        its share ``⌈y·n/N⌉`` of each band would ask a 1×1 level for its one row at the first band, and with it
        the whole picture; advancing a coarse level by the row or two each band allows would cost a pass's fixed
        work per row: an 8K pyramid's 13 levels made 888 steps, 260 in bands.) The pixels are the same either
        way."""
        n_rows, n_cols = self.anchor
        lead = max(self.plan.outputs, key=lambda k: self.plan.images[k].size[0])
        for c0 in range(0, n_cols, self.width):
            c1 = min(n_cols, c0 + self.width)
            self._strip(c0, c1)
            if self.windows is not None:
                self._run_windows(lead)
                continue
            for y0 in range(0, n_rows, self.band):
                y1 = min(n_rows, y0 + self.band)
                for k in self.plan.outputs:
                    if k == lead or y1 == n_rows:
                        self._emit(k, self._share(k, 0, y1))
                    elif k in self.out_cols:
                        ready = self._ready(k)
                        if ready - self.state[k].emitted >= min(self.band, STEP_ROWS, self.plan.images[k].size[0]):
                            self._emit(k, ready)

    def _run_windows(self, lead: int) -> None:
        """:meth:`run` of the strip for :attr:`windows`: every image starts at the first row its consumers' windows
        read (:meth:`_prime`); the lead output follows the band through its window, the others as far as their
        sources allow, and all end at their window's end. A window start is one more band boundary: the pixels are
        the whole run's (the passes' phases are the whole image's, :meth:`Pass.tile`)."""
        assert self.windows is not None
        self._prime()
        a, b = self.windows[lead]
        for y1 in [*range(a + self.band, b, self.band), b]:
            for k in self.plan.outputs:
                end = self.windows[k][1]
                if k == lead or y1 == b:
                    self._emit(k, y1 if k == lead else end)
                elif k in self.out_cols:
                    self._emit(k, min(self._ready(k), end))

    def _prime(self) -> None:
        """Start every image of the strip at the first row that the windows need of it, found backwards: an
        output's window start, and the first row each pass reads for the first row its target needs."""
        assert self.windows is not None
        need: dict[int, int] = {}
        for k, (a, b) in self.windows.items():
            self.state[k].emitted = a
            if a < b and k in self.out_cols:
                need[k] = a
        for ps in reversed(self.active):
            t = need.get(ps.target)
            if t is None:
                continue
            step = ps.tile((t, t + 1), self.state[ps.target].computed())
            for s, (rr, _) in ps.reads(step.rows, step.cols).items():
                src = self.state[s]
                lo = _restrict(rr, src.rows, src.border)[0]
                need[s] = min(need.get(s, lo), lo)
        for k, first in need.items():
            st = self.state[k]
            if st.border != "wrap":  # wrap images are kept whole: their last rows read their first
                st.start = st.done = first

    def _ready(self, k: int) -> int:
        """The most rows of output ``k`` its pass can make from rows its sources already hold."""
        st, ps = self.state[k], self.writer.get(k)
        lo, hi = st.emitted, self.plan.images[k].size[0]
        if ps is None:
            return lo
        step = 1  # gallop from what is emitted (most bands ready a few rows, or none), then bisect
        while lo < hi and self._available(st, ps, min(hi, lo + step)):
            lo, step = min(hi, lo + step), 2 * step
        hi = min(hi, lo + step - 1)
        while lo < hi:  # bisect: readiness is monotone in the rows asked for
            mid = (lo + hi + 1) // 2
            if self._available(st, ps, mid):
                lo = mid
            else:
                hi = mid - 1
        return lo

    def _available(self, st: _State, ps, rows: int) -> bool:
        start = st.done if st.done is not None else st.emitted
        if rows <= start:
            return True
        step = ps.tile((start, rows), st.comp)
        for s, (rr, _) in _reads_of(ps, step.rows, step.cols).items():
            src = self.state[s]
            if src.done is None or _restrict(rr, src.rows, src.border)[1] > src.done:
                return False
        return True

    def _share(self, k: int, axis: int, y: int) -> int:
        n = self.plan.images[k].size[axis]
        return -(-y * n // self.anchor[axis])

    def _strip(self, c0: int, c1: int) -> None:
        """Fresh states for the column strip ``[c0, c1)`` of the anchor: each image's columns, found backwards."""
        plan = self.plan
        self.state: dict[int, _State] = {}
        for k, im in enumerate(plan.images):
            t, le, b, r = im.guard
            self.state[k] = _State((-t, im.size[0] + b), (-le, im.size[1] + r), im.border)
        demand: dict[int, tuple[int, int] | None] = {k: None for k in self.state}
        self.out_cols = {}
        for k in plan.outputs:
            span = (self._share(k, 1, c0), self._share(k, 1, c1))
            if span[0] < span[1]:
                self.out_cols[k] = span
                demand[k] = _union(demand[k], span)
        self.active = []
        for ps in reversed(plan.passes):
            st = self.state[ps.target]
            wanted = demand[ps.target]
            if wanted is None:
                continue
            self.active.append(ps)
            st.cols = _restrict(wanted, st.colext, st.border)
            st.comp = ps.tile((0, 1), st.cols).cols
            for s, (_, cc) in ps.reads((0, ps_period(ps)), st.comp).items():
                demand[s] = _union(demand[s], cc)
                self.state[s].consumers.append(ps)
        self.active.reverse()
        for k in plan.inputs:
            st = self.state[k]
            wanted = demand[k]
            if wanted is not None:
                st.cols = _restrict(wanted, st.colext, st.border)

    def _emit(self, k: int, hi: int) -> None:
        st = self.state[k]
        span = self.out_cols.get(k)
        if span is None or hi <= st.emitted:
            return
        self._advance(k, st.emitted, hi)
        start, kept = st.held()[0], st.kept()
        rows = slice(st.emitted - start, hi - start)
        cols = slice(span[0] - kept[0], span[1] - kept[0])
        view = st.pixels()[rows, cols]
        view.flags.writeable = False
        self.sink(k, st.emitted, span[0], view)
        st.emitted = hi
        self._trim(k)

    # ------------------------------------------------------------ producing rows
    def _advance(self, k: int, lo: int, hi: int) -> None:
        """Make image ``k`` hold stored rows up to ``hi`` (from ``lo`` on, if it holds none yet)."""
        st = self.state[k]
        if st.done is None:
            st.start = st.done = st.rows[0] if st.border == "wrap" else lo  # wrap: the last rows read the first
        start, done = st.held()
        assert lo >= start, f"image {k}: row {lo} was dropped (kept from {start})"
        if hi <= done:
            return
        ps = self.writer.get(k)
        if ps is None:  # an input
            px = self.source(k, (done, hi), st.kept())
            # codes are kept as decoded (uint8 or uint16): the executor reads both through its table
            self._append(st, px)
            return
        step = ps.tile((done, hi), st.computed())
        reads = sorted(ps.reads(step.rows, step.cols).items())
        for s, (rr, _) in reads:  # every source first: advancing one may append to another (a shared ancestor)
            self._advance(s, *_restrict(rr, self.state[s].rows, self.state[s].border))
        windows = [self._window(self.state[s], rr, cc) for s, (rr, cc) in reads]  # views, valid until the next append
        origins = [(s, step.origins[s], rr, cc) for s, (rr, cc) in reads]
        r0, (k0, k1) = st.held()[1], st.kept()
        if self.executor.writes_into and step.rows[0] == r0 and tuple(step.cols) == (k0, k1):
            # the step makes exactly the new rows of the kept columns: made in their place after the kept rows
            self._run(ps.target, step, windows, origins, self._room(st, step.rows[1] - r0, windows[0][0]))
        else:
            out = self._run(ps.target, step, windows, origins)
            self._append(st, out[r0 - step.rows[0]:, k0 - step.cols[0]:k1 - step.cols[0]])
        for s, *_ in origins:
            self._trim(s)

    def _append(self, st: _State, px: np.ndarray | list[np.ndarray]) -> None:
        parts = px if isinstance(px, list) else [px]
        kept = [] if st.buf is None or not len(st.buf) else [st.buf]
        # one copy of the kept rows and the new ones into a new buffer: rows once made are never written again, so
        # the sink keeps views (a ring buffer measured no faster, and held more)
        st.buf = np.concatenate(kept + parts) if len(kept) + len(parts) > 1 else np.array(parts[0])
        st.done = st.held()[1] + sum(p.shape[0] for p in parts)
        self._note_peak()

    def _note_peak(self) -> None:
        """:attr:`peak_pixels` with what the images hold now."""
        self.peak_pixels = max(self.peak_pixels, sum(s.buf.shape[0] * s.buf.shape[1] for s in self.state.values()
                                                 if s.buf is not None))

    def _room(self, st: _State, n: int, like: np.ndarray) -> np.ndarray:
        """:meth:`_append` of ``n`` rows still to be made: a new buffer of the kept rows and ``n`` more (the kept
        rows copied in, ``like``'s channels, the scheduler's type), which ``st`` holds from now on; its last ``n``
        rows, for the executor to write (``run_outputs(..., out=)``)."""
        (c0, c1), m = st.kept(), 0 if st.buf is None else len(st.buf)
        buf = np.empty((m + n, c1 - c0) + like.shape[2:], self.dtype)
        if m:
            buf[:m] = st.buf
        st.buf = buf
        st.done = st.held()[1] + n
        self._note_peak()
        return buf[m:]

    def _window(self, src: _State, rr: tuple[int, int], cc: tuple[int, int]):
        """(pixels, origin): what a pass reads of ``src`` over ``rr × cc``."""
        (start, done), kept, buf = src.held(), src.kept(), src.pixels()
        if src.border == "clamp":
            (a, b), (c, d) = _restrict(rr, src.rows, "clamp"), _restrict(cc, src.colext, "clamp")
            assert start <= a and b <= done and kept[0] <= c and d <= kept[1]
            px = buf[a - start:b - start, c - kept[0]:d - kept[0]]
            return px, (a, c)
        ri = _fold(np.arange(*rr), src.rows, src.border)
        ci = _fold(np.arange(*cc), src.colext, src.border)
        px = gather(buf, np.maximum(ri - start, 0), np.maximum(ci - kept[0], 0))
        if src.border == "zero":
            px[ri < src.rows[0]] = 0
            px[:, ci < src.colext[0]] = 0
        return px, (rr[0], cc[0])

    def _run(self, target: int, step, windows, origins, out: np.ndarray | None = None) -> np.ndarray:
        """One pass over ``step``'s rectangle, as a one-pass plan of windows (its pixels written into ``out``
        where given: an executor that :attr:`~pyramid_cli.exec.base.Executor.writes_into`)."""
        plan = self.plan
        images = [Image((1, 1)) for _ in plan.images]
        arrays = []
        for (px, (wr, wc)), (s, (orow, ocol), _, _) in zip(windows, origins, strict=True):
            h, w = px.shape[:2]
            top, left = orow - wr, ocol - wc
            rows, cols = max(1, h - top), max(1, w - left)
            # a gathered (folded) window keeps its border mode: never read past, it folds to itself, and
            # the executors then use the same arithmetic as untiled (GL's four folded fetches, say)
            images[s] = Image((rows, cols), [top, left, h - top - rows, w - left - cols], self.state[s].border)
            arrays.append(px)
        (r0, r1), (c0, c1) = step.rows, step.cols
        images[target] = Image((r1 - r0, c1 - c0))
        sub = Plan(images, [step.run], plan.expression, outputs=[target], inputs=[s for s, *_ in origins],
                   border=plan.border)
        self.steps += 1
        into = {} if out is None else {"out": out}
        return self.executor.run_outputs(sub, arrays, self.dtype, **self.codes, **into)[0]

    def _trim(self, s: int) -> None:
        """Drop the rows of ``s`` that no later step reads (and that are emitted, for an output)."""
        st = self.state[s]
        buf = st.buf
        if buf is None or st.border == "wrap":
            return
        start, keep = st.held()
        if s in self.out_cols:
            keep = min(keep, st.emitted)
        for ps in st.consumers:
            t = self.state[ps.target]
            if t.done is None:
                return  # a consumer that has not started yet reads from the top
            if t.done >= t.rows[1] and (ps.target not in self.out_cols or t.emitted >= t.rows[1]):
                continue
            step = ps.tile((t.done, max(t.rows[1], t.done + 1)), t.computed())  # every row still to come
            rr = _reads_of(ps, step.rows, step.cols).get(s)
            if rr is not None:
                keep = min(keep, _restrict(rr[0], st.rows, st.border)[0])
        if keep > start:
            st.buf = buf[keep - start:]
            st.start = keep


def _reads_of(ps, rows: tuple[int, int], cols: tuple[int, int]) -> dict:
    """``ps.reads(rows, cols)`` of many rows from its first and last periods: a phased pass reads its lowest
    source row in the first period and its highest in the last (each phase's source index grows with the row,
    :func:`pyramid_cli.core.geometry.base_index`), so two lookups of one shape in the pass's memo answer for
    any number of rows."""
    p = ps_period(ps) if hasattr(ps, "phases") else 0
    if not p or rows[1] - rows[0] <= 2 * p:
        return ps.reads(rows, cols)
    first = ps.reads((rows[0], rows[0] + p), cols)
    last = ps.reads((rows[1] - p, rows[1]), cols)
    return {s: ((rr[0], last[s][0][1]), cc) for s, (rr, cc) in first.items()}


def ps_period(ps) -> int:
    """Rows of one phase period of a pass (1 for kinds without phases)."""
    period = getattr(ps, "period", (1, 1))
    return int(period[0])


def run_arrays(executor: Executor, plan: Plan, images, *, band: int, width: int | None = None, dtype=np.float32,
               out: list[np.ndarray] | None = None, convert=None) -> list[np.ndarray]:
    """Run ``plan`` tiled on in-memory (or memory-mapped) arrays; every ``plan.outputs`` image.

    ``images``: one (H, W) or (H, W, C) array per ``plan.inputs`` (a ``numpy.memmap`` is read band
    by band). ``out``: arrays to write into (a memmap keeps the result on disk); default new arrays.
    Outputs have ``dtype`` (the executor's intermediates stay float32; the emulator's float64).
    ``convert``: applied to every band read (integer codes to floats, say).
    """
    arrays = list(images) if isinstance(images, (list, tuple)) else [images]
    flat = arrays[0].ndim == 2
    by_index = dict(zip(plan.inputs, arrays, strict=True))
    channels = () if flat else arrays[0].shape[2:]
    if out is None:
        out = [np.empty(plan.images[k].size + channels, dtype=dtype) for k in plan.outputs]
    slots = {k: i for i, k in enumerate(plan.outputs)}
    native = np.float64 if executor.work_dtype == np.float64 else np.float32

    def source(k, rows, cols):
        a = by_index[k][rows[0]:rows[1], cols[0]:cols[1]]
        a = np.asarray(convert(a) if convert is not None else a)
        a = a[:, :, None] if flat else a
        if native == np.float64:
            return a.astype(np.float64)
        return np.ascontiguousarray(a) if a.dtype in (np.float16, np.float32) else a.astype(np.float32)

    def sink(k, r, c, px):
        o = out[slots[k]]
        view = o[r:r + px.shape[0], c:c + px.shape[1]]
        view[...] = px[:, :, 0] if flat else px

    Scheduler(executor, plan, source, sink, band=band, width=width, dtype=native).run()
    return out


def tileable(plan: Plan) -> bool:
    """Whether every pass of ``plan`` has the tiling hook (``tile``; :mod:`pyramid_cli.plan.model`)."""
    return all(hasattr(ps, "tile") for ps in plan.passes)


__all__ = ["Scheduler", "run_arrays", "tileable", "ps_period"]
