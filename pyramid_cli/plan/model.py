"""The Plan: images and passes of bilinear taps, the contract every executor runs (docs/design.md §5).

A :class:`Plan` is the contract between the planner and the executors (the
numpy emulator in :mod:`pyramid_cli.exec.emulate` and the GL executor): a list of
images (``images[0]`` is the input; image k > 0 is written by pass k − 1), and
for every pass the taps each output fragment sums.

Coordinates: every image has a *logical* 1-based pixel grid ``1..h`` (rows) and
``1..w`` (columns), plus a guard band (rows ``1 − top .. h + bottom`` …) that
bounds inference found later passes read. A pass maps output pixel ``r`` to
the source base index ``R = S·⌈r/P⌉`` (``S``, ``P`` per axis) and a tap with
offset ``t`` reads the source at the (possibly fractional) index ``R − t``:
a fraction ``α`` of ``t`` mixes ``(1 − α)·src[R − ⌊t⌋] + α·src[R − ⌊t⌋ − 1]``
(hardware bilinear filtering). Reads clamp to the source texture's stored
extent (logical grid plus guard), which is the paper's clamp at the borders of
the input and of every written operator, while guard bands keep a named
filter atomic (docs/design.md §1). Every fractional offset is a multiple of ¼.

Border modes (docs/design.md §1: clamp, mirror, wrap, zero) belong to the plan:
each :class:`Image` says how reads outside its stored extent resolve. A read
at the fractional index ``x = i + α`` (``i = ⌊x⌋``) is
``(1 − α)·read(i) + α·read(i + 1)`` per axis, where ``read`` folds an integer
index through the image's border mode (:func:`pyramid_cli.core.border.fold`) over
its stored extent. For ``clamp`` this is the hardware's clamped bilinear read;
the other modes only ever apply to images without guard bands: the plan's
inputs and the results of written operators (the boundaries), since the
intermediates of a named filter store every pixel later passes read.

Tiling (:mod:`pyramid_cli.exec.tiles`) runs any plan over rectangles of its images in bounded
memory, identical to the untiled run at every pixel. It needs two things of every pass
kind, both in 0-based half-open *logical* coordinates (row 0 is logical row 1; guard-band
rows are negative or ≥ the size):

- ``reads(rows, cols)``: for an output rectangle of the target, the rectangle of each
  source it reads (the shared pass-kind interface; it may leave the stored extent, where
  reads fold by the source's border mode);
- ``tile(rows, cols) -> TileStep``: the hook that makes a kind tileable. It widens the
  rectangle to one the pass can compute on its own (:class:`Pass`: the start rounded down
  to a multiple of the period, so phases stay aligned), and returns the pass to run on it
  with the target's logical pixel (0, 0) at ``(rows[0], cols[0])``, plus for each source
  the coordinate that becomes its logical (0, 0) in the tile (``S·r₀/P`` for :class:`Pass`:
  the base index ``R = S·⌈r/P⌉`` is unchanged by the shift). The scheduler hands every
  executor a one-pass plan whose images are the windows (their guard bands, possibly
  negative, place each window), so executors need nothing new for a kind they can run.
  A kind whose weights depend on the absolute position (per-row weight tables) returns a
  sliced copy of itself. :class:`PointwisePass` has it (the identity); :class:`ResamplePass`
  slices its table to the tile's outputs, and its executors read the window's stored
  indices (its guard band along the axis places it: ``emulate.resample_table``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from fractions import Fraction

from pyramid_cli.core.geometry import base_index

Half = Fraction(1, 2)


@dataclass(frozen=True)
class Tap:
    source: int                        # image index
    offset: tuple[Fraction, Fraction]  # t: reads source index R − t (rows, columns)
    weight: Fraction
    linear: bool                       # bilinear (fractional offset) or nearest

    @property
    def sampler(self) -> str:
        return "linear" if self.linear else "nearest"


@dataclass
class Image:
    size: tuple[int, int]                       # logical (rows, columns)
    guard: list[int] = field(default_factory=lambda: [0, 0, 0, 0])  # top, left, bottom, right
    border: str = "clamp"                       # how reads outside the stored extent resolve

    @property
    def stored(self) -> tuple[int, int]:
        """Texture size: logical size plus guard band."""
        t, l, b, r = self.guard
        return self.size[0] + t + b, self.size[1] + l + r


READS_MEMO = 4096  # shapes of rectangles whose reads a pass remembers (Pass.reads)


@dataclass(frozen=True)
class TileStep:
    """A pass restricted to a rectangle of its target (see :meth:`Pass.tile`)."""

    rows: tuple[int, int]                       # computed rows of the target (⊇ the ones asked), 0-based
    cols: tuple[int, int]
    run: Pass | ResamplePass | PointwisePass    # the pass to execute over the rectangle
    origins: dict[int, tuple[int, int]]         # per source: its coordinate at the tile's logical (0, 0)


@dataclass
class Pass:
    label: str
    target: int                                  # image index written
    period: tuple[int, int]
    stride: tuple[int, int]
    phases: dict[tuple[int, int], list[Tap]]     # keyed by (r mod Pr, c mod Pc)
    why: str = ""                                # the cost model's choice, on a filter's first pass

    def sources(self) -> set[int]:
        return {t.source for taps in self.phases.values() for t in taps}

    @property
    def fetches(self) -> float:
        """Texture reads per fragment, the mean over phases (each phase is equally frequent)."""
        return sum(len(t) for t in self.phases.values()) / len(self.phases)

    def reads(self, rows: tuple[int, int], cols: tuple[int, int]) -> dict[int, tuple[tuple[int, int], tuple[int, int]]]:
        """Source rectangles (0-based half-open logical) read by the output rectangle ``rows × cols``.

        The reads of a rectangle moved by whole periods are those of the first period moved by as many strides
        (``R = S·⌈r/P⌉``, :func:`needed`), so each shape is worked out once and moved: the band engine asks this
        thousands of times a picture, for a few shapes."""
        if rows[0] >= rows[1] or cols[0] >= cols[1]:
            return {}
        (pr, pc), (sr, sc) = self.period, self.stride
        qr, qc = rows[0] // pr, cols[0] // pc
        a, b = rows[0] - qr * pr, cols[0] - qc * pc
        key = (a, rows[1] - rows[0], b, cols[1] - cols[0])
        memo = self.__dict__.setdefault("_reads_memo", {})
        found = memo.get(key)
        if found is None:
            if len(memo) >= READS_MEMO:
                memo.clear()
            found = memo[key] = self._reads((a, a + key[1]), (b, b + key[3]))
        dr, dc = qr * sr, qc * sc
        if not dr and not dc:
            return dict(found)
        return {s: ((r0 + dr, r1 + dr), (c0 + dc, c1 + dc)) for s, ((r0, r1), (c0, c1)) in found.items()}

    def _reads(self, rows: tuple[int, int], cols: tuple[int, int]) -> dict[int, tuple[tuple[int, int], ...]]:
        out: dict[int, tuple[tuple[int, int], ...]] = {}
        for src in self.sources():
            (r0, r1), (c0, c1) = needed(self, (rows[0] + 1, rows[1]), (cols[0] + 1, cols[1]), src)
            if r0 <= r1 and c0 <= c1:
                out[src] = ((r0 - 1, r1), (c0 - 1, c1))
        return out

    def tile(self, rows: tuple[int, int], cols: tuple[int, int]) -> TileStep:
        """The pass over ``rows × cols`` of its target: starts rounded down to the period (phases stay aligned)."""
        (pr, pc), (sr, sc) = self.period, self.stride
        r0, c0 = pr * (rows[0] // pr), pc * (cols[0] // pc)
        origin = (sr * r0 // pr, sc * c0 // pc)
        return TileStep((r0, rows[1]), (c0, cols[1]), self, {s: origin for s in self.sources()})


# ---------------------------------------------------------------- what a pass reads (bounds inference asks it)
def needed(stage_pass: Pass, rows: tuple[int, int], cols: tuple[int, int], src: int):
    """Source index ranges (1-based, inclusive) read by ``rows × cols`` (1-based, inclusive) of a pass, for one
    source; empty (lo > hi) where no phase present in the rectangle reads it."""
    lo_r = lo_c = 10 ** 9
    hi_r = hi_c = -10 ** 9
    (pr, pc), (sr, sc) = stage_pass.period, stage_pass.stride
    for (phr, phc), taps in stage_pass.phases.items():
        rs = [r for r in _ends(rows, pr) if r % pr == phr]
        cs = [c for c in _ends(cols, pc) if c % pc == phc]
        for t in taps:
            if t.source != src:
                continue
            # ⌊R − t⌋ = R − ⌈t⌉ and ⌈R − t⌉ = R − ⌊t⌋ for an integer R: no Fraction per index (the band engine asks
            # this a few thousand times a picture)
            (lo_t, hi_t), (lo_u, hi_u) = (_ceil(t.offset[0]), _floor(t.offset[0])), (_ceil(t.offset[1]),
                                                                                       _floor(t.offset[1]))
            for r in rs:
                base = base_index(r, pr, sr)
                lo_r, hi_r = min(lo_r, base - lo_t), max(hi_r, base - hi_t)
            for c in cs:
                base = base_index(c, pc, sc)
                lo_c, hi_c = min(lo_c, base - lo_u), max(hi_c, base - hi_u)
    return (lo_r, hi_r), (lo_c, hi_c)


def _ends(span: tuple[int, int], p: int) -> list[int]:
    lo, hi = span
    return sorted(set(range(lo, min(hi, lo + p - 1) + 1)) | set(range(max(lo, hi - p + 1), hi + 1)))


def _floor(x) -> int:
    return math.floor(x)  # exact for ints and Fractions (and floats)


def _ceil(x) -> int:
    return math.ceil(x)


# The per-pixel operations of a :class:`PointwisePass` (the nonlinear steps of the pyramid methods:
# pull-push hole filling, Kraus 2009 after Gortler et al. 1996; multiresolution blending, Burt &
# Adelson 1983). Each reads its sources at the same pixel and channel; ``k`` is the pass's ``param``.
# One fact each; the executors (emulate, cpu, gl) implement these formulas literally, in float32.
POINTWISE_OPS: dict[str, tuple[int, str]] = {
    "mul": (2, "a·b: colour times weight (premultiplying by a weight image)"),
    "pull_colour": (2, "a·min(1, k·b)/b where b > 0, else 0: a pulled (filtered) premultiplied colour a with its "
                       "filtered weight b, renormalised so that its weight becomes min(1, k·b)"),
    "pull_weight": (1, "min(1, k·a): a filtered weight scaled by k (the fine pixels a coarse one covers) and "
                       "clamped to 1"),
    "divide": (2, "a/b where b > 0, else 0: premultiplied colour back to colour"),
    "over": (3, "a + (1 − b)·c: premultiplied colour a of weight b over the colour c (the push blend)"),
    "blend": (3, "c·a + (1 − c)·b: a where the mask c is 1, b where it is 0 (Burt & Adelson's per-level blend)"),
}


@dataclass
class PointwisePass:
    """Per-pixel arithmetic over several images of one size, at the same logical pixel and channel.

    ``op`` names one of :data:`POINTWISE_OPS` and ``srcs`` its operands in order (``a, b, c``);
    ``param`` is the constant ``k`` of the ops that take one. No source is read past its extent,
    so border modes never apply, and every source and the target have no guard band.
    """

    label: str
    target: int
    op: str
    srcs: tuple[int, ...]
    param: Fraction = Fraction(1)
    why: str = ""

    def __post_init__(self):
        arity = POINTWISE_OPS[self.op][0]  # KeyError: an unknown op is a planner bug
        assert len(self.srcs) == arity, f"{self.op} takes {arity} source(s), not {len(self.srcs)}"

    def sources(self) -> set[int]:
        return set(self.srcs)

    @property
    def fetches(self) -> float:
        """Texel reads per fragment: one per operand."""
        return float(len(self.srcs))

    def reads(self, rows: tuple[int, int], cols: tuple[int, int]) -> dict[int, tuple[tuple[int, int], tuple[int, int]]]:
        """Each source is read over the output rectangle itself (0-based half-open logical rows, columns)."""
        return {s: ((rows[0], rows[1]), (cols[0], cols[1])) for s in self.srcs}

    def tile(self, rows: tuple[int, int], cols: tuple[int, int]) -> TileStep:
        """The pass over ``rows × cols``: every source's window starts where the tile does."""
        return TileStep((rows[0], rows[1]), (cols[0], cols[1]), self, {s: (rows[0], cols[0]) for s in self.srcs})


@dataclass
class ResamplePass:
    """Separable resampling of one axis by a banded table of exact weights (MIP levels, docs/design.md §5).

    Output index ``j`` (0-based, along ``axis``: 0 rows, 1 columns) of the target is
    ``Σₖ weights[j][k] · src[starts[j] + k]`` along that axis, every other index unchanged;
    source indices outside ``0..n−1`` fold by the source's border mode (:func:`pyramid_cli.core.border.fold`:
    clamp, mirror, wrap, or zero). Every row of the table has the same width (zeros pad the short ones),
    so an executor runs one table-driven loop for every output, whatever the ratio of the sizes.
    Source and target have no guard bands in a whole plan: the source is a boundary (the plan's
    input or a level), read through its border mode. In a tile (:meth:`tile`, :mod:`pyramid_cli.exec.tiles`)
    the source is a window placed by a guard band along ``axis``, and reads fold over its stored extent.
    :mod:`pyramid_cli.plan.resample` derives the tables.
    """

    label: str
    target: int
    source: int
    axis: int                                  # 0: rows, 1: columns
    starts: tuple[int, ...]                    # per output index: the first source index read (0-based)
    weights: tuple[tuple[Fraction, ...], ...]  # per output index: the weights of starts[j], starts[j] + 1, …
    why: str = ""

    def sources(self) -> set[int]:
        return {self.source}

    @property
    def width(self) -> int:
        """Texels each output reads (the table's row width)."""
        return len(self.weights[0]) if self.weights else 0

    @property
    def fetches(self) -> float:
        """Texel reads per fragment: the mean number of nonzero weights per output."""
        return sum(sum(1 for w in row if w) for row in self.weights) / max(1, len(self.weights))

    def reads(self, rows: tuple[int, int], cols: tuple[int, int]) -> dict[int, tuple[tuple[int, int], tuple[int, int]]]:
        """Source rectangle (0-based half-open logical rows, columns) an output rectangle reads; along
        ``axis`` it may extend past the source (those reads fold by its border mode)."""
        starts = self._starts((rows, cols)[self.axis])
        if not starts:
            return {}
        read = (min(starts), max(starts) + self.width)
        return {self.source: (read, cols) if self.axis == 0 else (rows, read)}

    def _starts(self, span: tuple[int, int]) -> tuple[int, ...]:
        """The table's starts of the outputs ``span`` along ``axis`` (those past the target: none)."""
        n = len(self.starts)
        return self.starts[max(0, span[0]):min(n, span[1])]

    def tile(self, rows: tuple[int, int], cols: tuple[int, int]) -> TileStep:
        """The pass over ``rows × cols``: a copy with the table's rows of the tile, ``starts`` relative to
        the first source index the tile reads (the source window's logical 0 along ``axis``)."""
        a, b = (rows, cols)[self.axis]
        starts = self._starts((a, b))
        origin = min(starts, default=0)
        sliced = replace(self, starts=tuple(s - origin for s in starts), weights=self.weights[max(0, a):max(0, b)])
        at = (origin, cols[0]) if self.axis == 0 else (rows[0], origin)
        return TileStep((rows[0], rows[1]), (cols[0], cols[1]), sliced, {self.source: at})


@dataclass
class Plan:
    images: list[Image]
    passes: list[Pass | ResamplePass | PointwisePass]
    expression: str
    paper_fetches: float | None = None
    outputs: list[int] = field(default_factory=list)  # images read back, in order; default: the last
    inputs: list[int] = field(default_factory=lambda: [0])  # images uploaded, in order
    border: str = "clamp"                             # the border mode of every written operator

    def __post_init__(self):
        if not self.outputs:
            self.outputs = [len(self.images) - 1]

    @property
    def output(self) -> Image:
        return self.images[self.outputs[-1]]

    @property
    def fetches(self) -> float:
        return sum(p.fetches for p in self.passes)

    def releases(self) -> list[list[int]]:
        """For each pass, the images no later pass reads and the plan does not return: what an executor may
        free (or reuse) once that pass has run."""
        keep = set(self.outputs)
        last_read: dict[int, int] = {}
        for i, ps in enumerate(self.passes):
            for s in ps.sources():
                last_read[s] = i
        out: list[list[int]] = [[] for _ in self.passes]
        for s, i in last_read.items():
            if s not in keep:
                out[i].append(s)
        return out

    @property
    def fetches_per_output_pixel(self) -> float:
        """Fetches weighted by each pass's stored size relative to the output (docs/design.md §5)."""
        out = self.output.size[0] * self.output.size[1]
        return sum(p.fetches * self.images[p.target].stored[0] * self.images[p.target].stored[1] / out
                   for p in self.passes)


def check(p: Plan) -> None:
    """Invariants every executor relies on; raises AssertionError on a planner bug."""
    for k, im in enumerate(p.images):
        assert im.border == "clamp" or not any(im.guard), f"image {k}: border {im.border} with a guard band"
    for ps in p.passes:
        if isinstance(ps, ResamplePass):
            src, dst = p.images[ps.source], p.images[ps.target]
            assert ps.source < ps.target and ps.axis in (0, 1)
            # a tile's source window may carry a guard band along the axis (tiles.py), never across it
            assert not any(src.guard[1 - ps.axis::2]) and not any(dst.guard), "resampling guards only its axis"
            assert len(ps.starts) == len(ps.weights) == dst.size[ps.axis]
            assert src.size[1 - ps.axis] == dst.size[1 - ps.axis]
            assert all(len(row) == ps.width for row in ps.weights)
            continue
        if isinstance(ps, PointwisePass):
            size = p.images[ps.target].size
            for s in ps.srcs:
                assert s < ps.target, f"pass {ps.label}: source {s} is not written before {ps.target}"
                assert p.images[s].size == size, f"pass {ps.label}: source {s} is not {size}"
                assert not any(p.images[s].guard), f"pass {ps.label}: source {s} has a guard band"
            assert not any(p.images[ps.target].guard), f"pass {ps.label}: pointwise target with a guard band"
            continue
        for taps in ps.phases.values():
            for t in taps:
                assert t.source < ps.target
                for o in t.offset:
                    assert o % Fraction(1, 4) == 0, f"tap offset {o} not on a quarter texel"
