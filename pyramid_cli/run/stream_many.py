"""Several files in, one picture out, band by band: ``pyramid blend`` and ``pyramid collapse`` streamed.

The engine of :mod:`pyramid_cli.run.stream` for jobs of several inputs. Each input file is decoded ahead on a
thread of its own (a :class:`~pyramid_cli.run.overlap.Reader`, in steps of its share of a band: the Laplacian
bands of a collapse have several sizes), the plan runs on the demand-driven row-band scheduler of
:mod:`pyramid_cli.exec.tiles`, which asks every input for its rows as the guard bands of every level need
them, and the output's rows are encoded and written behind on a writer thread into the temporary that is
renamed onto the output at the end (atomic, as every write). A :class:`Feed` turns the rows of one or more
files into the rows of one or more of the plan's inputs with a per-pixel function (a blend's mask: its
channel, clipped to [0, 1]); rows one input has taken stay until the others sharing the feed have taken
them too. The pixels are those of the whole run.

Whole or streamed is decided as for a single image (:func:`pyramid_cli.run.stream.choose`): streamed when
the whole run would not fit the budget (``--memory``, else the container-aware default of
:mod:`pyramid_cli.run.budget`), or by default where bands are faster
(:func:`pyramid_cli.run.stream.speed_band`: from a megapixel on the CPU executor).
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from pyramid_cli.core.errors import DataError, InputError
from pyramid_cli.plan import Plan
from pyramid_cli.run.budget import resolve
from pyramid_cli.run.codec_budget import Codecs
from pyramid_cli.run.overlap import Reader, overlapped
from pyramid_cli.run.stream import (
    MIN_BAND,
    Choice,
    choose_run,
    executor_of,
    open_input,
    warn_nonfinite,
)

Prepare = Callable[[int, list[np.ndarray]], list[np.ndarray]]


@dataclass
class Feed:
    """Rows of ``streams`` (open :class:`~pyramid_cli.imageio.ImageStream` s of one height) made into the rows of
    the plan's inputs ``keys`` by ``prepare(y0, [rows of each stream])`` (one array per key, per pixel: a
    band's result is that band of the whole picture's). None: each stream's rows as they are."""

    streams: list
    keys: list[int]
    prepare: Prepare | None = None


class _Tee:
    """A feed's prepared rows, handed to each of its keys in order, kept until every key has taken them."""

    def __init__(self, feed: Feed, readers: list[Reader]):
        self.feed, self.readers = feed, readers
        self.held: list[np.ndarray] | None = None  # one array per key, rows [start, done)
        self.start = self.done = 0
        self.taken = dict.fromkeys(feed.keys, 0)

    def rows(self, k: int, y0: int, y1: int) -> np.ndarray:
        if y1 > self.done:
            raw = [r.rows(self.done, y1) for r in self.readers]
            new = self.feed.prepare(self.done, raw) if self.feed.prepare else raw
            if self.held is None or self.done == self.start:
                self.held, self.start = list(new), self.done
            else:
                self.held = [np.concatenate([a, b]) for a, b in zip(self.held, new, strict=True)]
            self.done = y1
        held = self.held
        assert held is not None, "rows are read before they are handed out"
        out = held[self.feed.keys.index(k)][y0 - self.start:y1 - self.start]
        self.taken[k] = max(self.taken[k], y1)
        keep = min(self.taken.values())
        if keep > self.start:  # no key asks for rows before what it took (the scheduler reads in order)
            self.held = [a[keep - self.start:] for a in held]
            self.start = keep
        return out


def decide(plan: Plan | None, channels: int, session, memory: int | None, *, where: str, reporter=None,
           in_bytes: int = 4, codecs: Codecs | None = None, limits: contextlib.ExitStack | None = None
           ) -> Choice | None:
    """The :class:`~pyramid_cli.run.stream.Choice` of a job of ``plan`` when it streams, else None (it runs whole:
    it fits and is no faster in bands; the reference backend without ``memory``, which is then refused).
    ``codecs``: the job's files' (:class:`~pyramid_cli.run.codec_budget.Codecs`): their first threads counted in
    the working set, and for a whole run the further ones limited until ``limits`` closes."""
    if session is None or session.executor is None:
        if memory is not None:
            executor_of(session)  # refuses with the reason
        return None
    assert plan is not None, "a plan to decide on wherever there is an executor"
    given = resolve(memory)
    if reporter is not None:
        reporter.detail(f"{where}: {given.describe()}")
    try:
        choice = choose_run(plan, channels, given.size, executor_of(session), where=where, reporter=reporter,
                            in_bytes=in_bytes, codecs=codecs, limits=limits)
    except DataError as exc:
        raise given.refusal(exc) from None
    return choice if choice.streams else None


@contextlib.contextmanager
def _reading(feeds: Sequence[Feed], plan: Plan, band: int) -> Iterator[dict[int, _Tee]]:
    """A started :class:`Reader` per stream, each decoding its plan input's share of a band at a time; on leaving
    every reader is stopped and joined."""
    anchor = max(plan.images[k].size[0] for k in plan.outputs)
    readers: list[Reader] = []
    tees: dict[int, _Tee] = {}
    try:
        for feed in feeds:
            rows = plan.images[feed.keys[0]].size[0]
            step = max(MIN_BAND, -(-band * rows // anchor))
            mine = [Reader(st.read, st.shape[0], step) for st in feed.streams]
            for r in mine:
                readers.append(r)
                r.thread.start()
            tee = _Tee(feed, mine)
            tees.update(dict.fromkeys(feed.keys, tee))
        yield tees
    finally:
        for r in readers:
            r.halt()


def stream_plan(plan: Plan, feeds: Sequence[Feed], out_path: str, info, channels: int, options: dict, session,
                choice: Choice, *, where: str = "", reporter=None,
                finish: Callable[[int, np.ndarray], np.ndarray] | None = None) -> None:
    """Run ``plan`` (one output) from ``feeds`` to ``out_path`` in bands of ``choice.band`` rows (see the module);
    ``info`` and ``options`` as :func:`pyramid_cli.imageio.stream_writers` takes them, ``channels`` the output's.
    ``finish(y0, rows)``: the output's rows from the plan's (per pixel; a fill puts the alpha channel back)."""
    from pyramid_cli import imageio as io
    from pyramid_cli.exec import tiles

    band = choice.band
    if band is None:
        raise ValueError("stream_plan runs a Choice that streams (decide's)")
    executor = executor_of(session)
    emu = executor.work_dtype == np.float64
    (out,) = plan.outputs
    h, w = plan.images[out].size
    streams = [st for feed in feeds for st in feed.streams]
    with (Codecs.of(streams, [(out_path, (h, w))], info, channels, options).within(choice, reporter, where),
          io.stream_writers([out_path], [info], [(h, w, channels)], **options) as (bw,),
          overlapped(None, 0, 1) as (_, writer),
          _reading(feeds, plan, band) as tees):
        def source(k, rows, cols):
            px = tees[k].rows(k, *rows)
            px = px[:, cols[0]:cols[1]] if (cols[0], cols[1]) != (0, px.shape[1]) else px
            return px.astype(np.float64) if emu else np.ascontiguousarray(px, dtype=np.float32)

        def sink(k, r, c0, px):  # px is the scheduler's buffer: the writer keeps rows, so a copy
            writer.call(bw.write, r, np.array(finish(r, px) if finish else px, dtype=np.float32))

        scheduler = tiles.Scheduler(executor, plan, source, sink, band=band,
                                    dtype=np.float64 if emu else np.float32)
        started = time.thread_time()
        scheduler.run()
        computed = time.thread_time() - started
    if reporter is not None:
        decoding = sum(r.busy for t in {id(t): t for t in tees.values()}.values() for r in t.readers)
        reporter.detail(f"{where}: CPU seconds: decoding {decoding:.2f}, computing {computed:.2f} (this thread), "
                        f"encoding and writing {writer.busy:.2f}, each on a thread of its own")
    session.ran = session.name


def mask_layout(path: str, info, mask_shape: tuple[int, ...], shape: tuple[int, ...], warn) -> int | None:
    """Which channel of a mask or weight image (header ``info``, (H, W, C) ``mask_shape``) weights an image of
    ``shape``: None, every channel as it is (one, or one per channel); else its alpha channel's index, with
    ``warn`` told (which channel of such a file holds the matte is a guess). Refused (InputError) for another
    size, or another count without an alpha channel."""
    if tuple(mask_shape[:2]) != tuple(shape[:2]):
        raise InputError(f"{path}: the mask is {mask_shape[1]}×{mask_shape[0]}, the image {shape[1]}×{shape[0]}")
    channels = shape[2] if len(shape) == 3 else 1
    n = mask_shape[2]
    if n == 1 or n == channels:
        return None
    alpha = info.alpha_channel
    if not 0 <= alpha < n:
        raise InputError(f"{path}: the mask has {n} channels ({', '.join(info.channel_names)}) and no "
                         f"alpha, the image {channels}: give one channel, one per channel, or an alpha channel")
    warn(f"{path}: {n} channels for an image of {channels}: its alpha channel {info.channel_names[alpha]} is the mask")
    return alpha


class MaskCounts:
    """NaN/Inf and values outside [0, 1] of a mask read in bands, said once at the end as a whole read says them
    (:func:`pyramid_cli.workflows.methods.mask_weights`)."""

    def __init__(self):
        self.bad = self.outside = 0
        self.lo, self.hi = np.inf, -np.inf

    def add(self, m: np.ndarray) -> None:
        m = np.asarray(m, dtype=np.float32)
        self.bad += int(m.size - np.count_nonzero(np.isfinite(m)))
        self.outside += int(np.count_nonzero((m < 0) | (m > 1)))
        seen = m[~np.isnan(m)]
        if seen.size:
            self.lo, self.hi = min(self.lo, float(seen.min())), max(self.hi, float(seen.max()))

    def say(self, where: str, warn, nan_hint: str) -> None:
        if self.bad:
            warn(f"{where}: {self.bad} NaN/Inf value(s) kept in the mask; they spread through the filter ({nan_hint})")
        if self.outside:
            warn(f"{where}: {self.outside} mask value(s) outside [0, 1] (from {self.lo:g} to {self.hi:g}) clipped to "
                 "[0, 1]")



def _runs_whole(output_path: str, session, memory: int | None, where: str) -> bool:
    """Whether a job cannot stream here: its output is encoded whole (JPEG, …), or there is no executor to run
    bands on (the reference backend: ``--memory`` is then refused with the reason)."""
    from pyramid_cli import imageio as io

    if not io.streams_to(output_path):
        return True
    if session is None or session.executor is None:
        decide(None, 0, session, memory, where=where)
        return True
    return False

def blend_streamed(a_path: str, b_path: str, mask_path: str, output_path: str, work, session, *,
                   memory: int | None, read, write, reporter, limits: contextlib.ExitStack | None = None
                   ) -> dict | None:
    """``pyramid blend`` (:func:`pyramid_cli.run.methods_files.blend_files`) streamed: A, B and the mask each read
    in bands on a thread of its own, the output written in bands. Returns what ``--json`` prints, or None when
    the job runs whole (it fits and is no faster in bands, an output encoded whole, or inputs that do not
    match: the whole run then says why as before)."""
    from pyramid_cli import imageio as io
    from pyramid_cli.run.report import NAN_HINT
    from pyramid_cli.workflows.methods import mask_channels

    if _runs_whole(output_path, session, memory, a_path):
        return None
    ro = read
    with contextlib.ExitStack() as stack:
        a, b = (stack.enter_context(open_input(p, ro)) for p in (a_path, b_path))
        m = stack.enter_context(io.open_stream(mask_path, colorspace="linear", alpha="none", nan=ro.nan,
                                               colorconfig=ro.colorconfig))
        if a.shape != b.shape or a.shape[:2] != m.shape[:2]:
            return None
        (h, w, c) = a.shape
        work.check(((h, w),) * 3, where=a_path)
        plan = session.plan(work, [(h, w)] * 3)
        options = write.for_inputs([a_path, b_path, mask_path])
        codecs = Codecs.of([a, b, m], [(output_path, (h, w))], a.info, c, options)
        choice = decide(plan, c, session, memory, where=a_path, reporter=reporter, codecs=codecs, limits=limits)
        if choice is None:
            return None
        alpha = mask_layout(mask_path, m.info, m.shape, a.shape, reporter.warn)
        for message in work.warnings((h, w)):
            reporter.warn(message)
        counts = MaskCounts()

        def weights(y0: int, raw: list[np.ndarray]) -> list[np.ndarray]:
            px = raw[0] if alpha is None else raw[0][:, :, alpha]
            counts.add(px)
            like = np.broadcast_to(np.float32(0), (px.shape[0], w, c))  # the image's shape: no pixels needed
            return [mask_channels(px, like, where=mask_path, warn=lambda _: None)]

        def in_a_space(y0: int, raw: list[np.ndarray]) -> list[np.ndarray]:  # B in A's linear space, as whole
            return [io.pixels_in(io.Image(raw[0], b.info), a.info.linear_space)]

        ka, kb, km = plan.inputs
        moved = b.info.linear_space != a.info.linear_space
        feeds = [Feed([a], [ka]), Feed([b], [kb], in_a_space if moved else None), Feed([m], [km], weights)]
        stream_plan(plan, feeds, output_path, a.info, c, options, session, choice, where=a_path, reporter=reporter)
        warn_nonfinite([a, b], ro, reporter)
        counts.say(mask_path, reporter.warn, NAN_HINT)
        reporter.detail(f"{io.describe_rules(a.info)}; executor {session.ran}")
    n = work.count((h, w))
    reporter.result(f"wrote {output_path} ({w}×{h}, {n} level(s), {session.ran}, streamed in bands of {choice.band} "
                    "rows)")
    return {"output": output_path, "width": w, "height": h, "levels": n, "analysis": work.analysis,
            "synthesis": work.synthesis, "border": work.border, "executor": session.ran}


def collapse_streamed(paths: list[str], output_path: str, session, settle: Callable, *, memory: int | None, read,
                      write, options_from: list[str], reporter, limits: contextlib.ExitStack | None = None
                      ) -> Choice | None:
    """``pyramid collapse`` of band files L_0 … L_m−1, G_m (``paths``, in order) streamed: each band read in
    bands of its share of the output's rows on a thread of its own, the output written in bands. ``settle(info)``:
    the (synthesis, border) of the bands whose first file's header is ``info`` (refusing a contradiction);
    ``options_from``: the inputs the write options follow. Returns the choice it ran with, or None when the
    job runs whole (it fits and is no faster in bands, an output encoded whole, or bands that do not make a
    pyramid: the whole run then says why as before)."""
    from pyramid_cli.core.geometry import halved
    from pyramid_cli.jobs.work import Collapse

    if len(paths) < 2 or _runs_whole(output_path, session, memory, paths[0]):
        return None
    ro = read
    with contextlib.ExitStack() as stack:
        streams = [stack.enter_context(open_input(p, ro)) for p in paths]
        shapes = [st.shape for st in streams]
        if (len({s[2] for s in shapes}) > 1
                or any(tuple(shapes[k][:2]) != halved(tuple(shapes[k - 1][:2])) for k in range(1, len(shapes)))):
            return None
        synthesis, border = settle(streams[0].info)
        work = Collapse(bands=len(paths), synthesis=synthesis, border=border)
        sizes = [tuple(s[:2]) for s in shapes]
        plan = session.plan(work, sizes)
        h, w, c = shapes[0]
        options = write.for_inputs(options_from)
        codecs = Codecs.of(streams, [(output_path, (h, w))], streams[0].info, c, options)
        choice = decide(plan, c, session, memory, where=paths[0], reporter=reporter, codecs=codecs, limits=limits)
        if choice is None:
            return None
        feeds = [Feed([st], [k]) for st, k in zip(streams, plan.inputs, strict=True)]
        stream_plan(plan, feeds, output_path, streams[0].info, c, options, session, choice, where=paths[0],
                    reporter=reporter)
        warn_nonfinite(streams, ro, reporter)
    reporter.result(f"wrote {output_path} ({w}×{h}, {session.ran}, streamed in bands of {choice.band} rows)")
    return choice


FILL_COARSEST = 16  # a fill streams only while its coarsest pull level keeps this many rows (see fill_streamed)


def _known_row(holes: str, width: int, channels: int, alpha: int | None, mask_channels: int
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """One row of known pixels (weight 1) as an image of ``channels`` and its mask (``holes`` mask)."""
    px = np.zeros((1, width, channels), np.float32)
    if holes == "alpha":
        px[:, :, alpha] = 1
    return px, (np.ones((1, width, mask_channels), np.float32) if holes == "mask" else None)


class _Rows:
    """Rows of an array kept from when they are read until the output's rows that need them are written."""

    def __init__(self):
        self.start, self.held = 0, None

    def add(self, px: np.ndarray) -> None:
        self.held = px if self.held is None or not len(self.held) else np.concatenate([self.held, px])

    def take(self, y0: int, y1: int) -> np.ndarray:
        out = self.held[y0 - self.start:y1 - self.start]
        self.held, self.start = self.held[y1 - self.start:], y1
        return out


def fill_streamed(input_path: str, output_path: str, session, work_for: Callable, *, mask: str | None, holes: str,
                  levels: int | None, keep_alpha: bool, memory: int | None, read, write, reporter,
                  limits: contextlib.ExitStack | None = None) -> tuple[tuple[int, int], dict, int] | None:
    """``pyramid fill`` (:func:`pyramid_cli.run.methods_files.fill_file`) streamed: the image and the mask read in
    bands on threads of their own, each band made colours and weights by
    :func:`~pyramid_cli.workflows.methods.fill_inputs` (per pixel), the filled rows finished by
    :func:`~pyramid_cli.workflows.methods.fill_output` and written in bands; the ``--json`` counts summed over the
    bands. ``work_for(premultiplied)``: the :class:`~pyramid_cli.jobs.work.Fill` to run (the whole run's).
    Returns ((rows, columns), {known, partial, empty}, band rows), or None when the job runs whole.

    Only a pull of ``levels`` whose coarsest level keeps :data:`FILL_COARSEST` rows streams: pulled down to 1×1
    (the default), the first output row depends on every input row, so every band would wait for the whole
    picture (``memory`` is then refused: give ``--levels``). Checks that need the whole picture come at its end:
    an image without a known pixel is refused once its last band is read (before the output is renamed)."""
    from pyramid_cli import imageio as io
    from pyramid_cli.core.errors import UsageError
    from pyramid_cli.core.geometry import level_sizes, mip_levels
    from pyramid_cli.run.report import NAN_HINT
    from pyramid_cli.workflows.methods import fill_inputs, fill_output, mask_weights

    if _runs_whole(output_path, session, memory, input_path):
        return None
    ro = read
    quiet = lambda _: None  # noqa: E731 - the per-band calls' messages are said once, over the bands
    with contextlib.ExitStack() as stack:
        st = stack.enter_context(open_input(input_path, ro))
        ms = (stack.enter_context(io.open_stream(mask, colorspace="linear", alpha="none", nan=ro.nan,
                                                 colorconfig=ro.colorconfig)) if mask else None)
        info = st.info
        h, w, c = st.shape
        alpha = info.alpha_channel if info.alpha_channel >= 0 and info.alpha_mode != "none" else None
        if (holes == "alpha" and alpha is None) or (ms is not None and ms.shape[:2] != st.shape[:2]):
            return None  # the whole run says why
        m = mip_levels((h, w)) if levels is None else levels
        if level_sizes((h, w), m)[-1][0] < FILL_COARSEST:
            if memory is not None:
                raise UsageError(f"{input_path}: --memory: a fill pulled down to {level_sizes((h, w), m)[-1][0]} "
                                 f"row(s) reads the whole picture before its first row; give --levels so that the "
                                 f"coarsest level keeps {FILL_COARSEST} rows (at most "
                                 f"{_fill_levels((h, w))} here) to stream it")
            return None
        layout_channels = 1 if ms is None else (c if ms.shape[2] == c else 1)
        probe = _known_row(holes, 1, c, alpha, layout_channels)
        colour, _, premultiplied = fill_inputs(probe[0], holes, probe[1], alpha, where=input_path, warn=quiet)
        cc = colour.shape[2]
        work = work_for(premultiplied)
        plan = session.plan(work, [(h, w)] * 2)
        options = write.for_inputs([input_path] + ([mask] if mask else []))
        spec = dataclasses.replace(info, alpha_mode="none") if keep_alpha else info
        codecs = Codecs.of([st] + ([ms] if ms is not None else []), [(output_path, (h, w))], spec, c, options)
        choice = decide(plan, cc, session, memory, where=input_path, reporter=reporter, codecs=codecs,
                        limits=limits)
        if choice is None:
            return None
        layout = (mask_layout(mask, ms.info, ms.shape, st.shape, reporter.warn)
                  if ms is not None and mask is not None else None)
        for message in work.warnings((h, w)):
            reporter.warn(message)
        counts = {"known": 0, "partial": 0, "empty": 0}
        said = MaskCounts()
        kept = _Rows()  # the input's alpha, for --keep-alpha
        known_px, known_mask = _known_row(holes, w, c, alpha, layout_channels)

        def prepare(y0: int, raw: list[np.ndarray]) -> list[np.ndarray]:
            px = raw[0]
            weights = None
            if ms is not None and mask is not None:  # (a mask stream is opened for a mask path)
                mk = raw[1] if layout is None else raw[1][:, :, layout:layout + 1]
                said.add(mk)
                weights = mask_weights(mk, px, mask, quiet)
            # a row of known pixels below the band: fill_inputs refuses a band without one, which a picture may have
            colour, weight, _ = fill_inputs(np.concatenate([px, known_px]), holes,
                                            None if weights is None else np.concatenate([weights, known_mask]),
                                            alpha, where=input_path, warn=quiet)
            colour, weight = colour[:-1], weight[:-1]
            w0 = weight[..., 0]
            counts["known"] += int(np.sum(w0 >= 1))
            counts["partial"] += int(np.sum((w0 > 0) & (w0 < 1)))
            counts["empty"] += int(np.sum(w0 <= 0))
            if keep_alpha:
                kept.add(px[:, :, alpha].copy())
            if y0 + len(px) == h and counts["known"] + counts["partial"] == 0:  # the whole run's refusal, its words
                fill_inputs(px[:0], holes, None if weights is None else weights[:0], alpha, where=input_path,
                            warn=quiet)
            return [colour, weight]

        def finish(y0: int, filled: np.ndarray) -> np.ndarray:
            shape = (len(filled), w, c)
            if not keep_alpha:
                return fill_output(filled, np.broadcast_to(np.float32(0), shape), holes, alpha)
            like = np.zeros(shape, np.float32)
            like[:, :, alpha] = kept.take(y0, y0 + len(filled))
            return fill_output(filled, like, holes, alpha, True)

        kc, kw = plan.inputs
        feed = Feed([st] + ([ms] if ms is not None else []), [kc, kw], prepare)
        stream_plan(plan, [feed], output_path, spec, c, options, session, choice, where=input_path, reporter=reporter,
                    finish=finish)
        if mask is not None:  # (a whole fill says nothing of the image's NaN/Inf: its holes)
            said.say(mask, reporter.warn, NAN_HINT)
        reporter.detail(f"{io.describe_rules(info)}; executor {session.ran}")
    assert choice.band is not None, "decide returns a Choice that streams"
    return (h, w), counts, choice.band


def _fill_levels(size: tuple[int, int]) -> int:
    """The most pull levels whose coarsest level keeps :data:`FILL_COARSEST` rows."""
    from pyramid_cli.core.geometry import halved

    n, rows = 0, size[0]
    while halved((rows, 1))[0] >= FILL_COARSEST and rows > 1:
        rows = halved((rows, 1))[0]
        n += 1
    return n


__all__ = ["Feed", "decide", "stream_plan", "warn_nonfinite", "mask_layout", "MaskCounts", "blend_streamed",
           "collapse_streamed", "fill_streamed", "FILL_COARSEST"]
