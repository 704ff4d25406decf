"""From expressions to render passes of bilinear texture taps (paper §3–§5, DESIGN.md §5).

A :class:`Plan` is the contract between the planner and the executors (the
numpy emulator in :mod:`pyramid_cli.emulate` and the GL executor): a list of
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
filter atomic (DESIGN.md §1). Every fractional offset is a multiple of ¼.

Border modes (DESIGN.md §1: clamp, mirror, wrap, zero) belong to the plan:
each :class:`Image` says how reads outside its stored extent resolve. A read
at the fractional index ``x = i + α`` (``i = ⌊x⌋``) is
``(1 − α)·read(i) + α·read(i + 1)`` per axis, where ``read`` folds an integer
index through the image's border mode (:func:`pyramid_cli.border.fold`) over
its stored extent. For ``clamp`` this is the hardware's clamped bilinear read;
the other modes only ever apply to images without guard bands: the plan's
inputs and the results of written operators (the boundaries), since the
intermediates of a named filter store every pixel later passes read.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from functools import cache, lru_cache

from . import algebra, catalogue, cost
from .algebra import Weights, mask_weights
from .expr import Expr, Named, Op, steps
from .geometry import base_index, step_size

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


@dataclass
class Plan:
    images: list[Image]
    passes: list[Pass]
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

    @property
    def fetches_per_output_pixel(self) -> float:
        """Fetches weighted by each pass's stored size relative to the output (DESIGN.md §5)."""
        out = self.output.size[0] * self.output.size[1]
        return sum(p.fetches * self.images[p.target].stored[0] * self.images[p.target].stored[1] / out
                   for p in self.passes)


# ------------------------------------------------------------------ stages
@dataclass(frozen=True)
class Stage:
    """One pass of a recipe: per phase, weights on earlier stages ("in" is the recipe's input)."""

    period: tuple[int, int]
    stride: tuple[int, int]
    phases: tuple  # ((phase, ((source, Weights-items), ...)), ...); source: -1 = input, k = stage k


def _stage(period, stride, phases: dict) -> Stage:
    return Stage(period, stride, tuple(sorted(
        (ph, tuple((src, tuple(sorted(w.items()))) for src, w in parts)) for ph, parts in phases.items())))


def conv(w: Weights, src: int = -1) -> Stage:
    return _stage((1, 1), (1, 1), {(0, 0): [(src, w)]})


def down(w: Weights, m: int = 1, src: int = -1) -> Stage:
    return _stage((1, 1), (2 ** m, 2 ** m), {(0, 0): [(src, w)]})


def up(phases: dict, src: int = -1) -> Stage:
    return _stage((2, 2), (1, 1), {p: [(src, w)] for p, w in phases.items()})


def _weights(key: str) -> Weights:
    return mask_weights(catalogue.mask(key).mask)


def _chain(*stages_outermost_last: Stage) -> list[Stage]:
    """Stages that each read the previous one (the first reads the input)."""
    out = []
    for i, s in enumerate(stages_outermost_last):
        out.append(Stage(s.period, s.stride, tuple(
            (ph, tuple((i - 1 if src == -1 and i else src, w) for src, w in parts)) for ph, parts in s.phases)))
    return out


def recipe(op: Op, f, stride: int = 1) -> list[Stage]:
    """The paper's decomposition of one named filter into box-sized stages (§3–§5).

    Each recipe is checked against the filter's exact mask by :func:`check_recipe`.
    """
    box, nw = _weights("box"), _weights("box_nw")
    if isinstance(f, Named) and op is Op.CONV:
        key = f.key
        if key == "bartlett":                       # §3.2: box↘ ⊗ (box↖ ⊗ g)
            return _chain(conv(nw), conv(box))
        if key.startswith("gauss"):                 # §3.3: (n−1)/2 Bartletts, n−1 passes
            n = int(key[5:])
            return _chain(*[conv(nw if i % 2 == 0 else box) for i in range(n - 1)])
        if key == "quasi":                          # §5.5: 10/6 δ − 16/24 (box↘ ⊗ (box↖ ⊗ g))
            first = conv(nw)
            last = _stage((1, 1), (1, 1), {(0, 0): [
                (-1, {(0, 0): Fraction(10, 6)}),
                (0, {d: -Fraction(16, 24) * v for d, v in box.items()})]})
            return [first, last]
    if isinstance(f, Named) and op is Op.DOWN and stride == 1:
        key = f.key
        if key == "box4":                           # §4.2 (erratum): box↘ ⊗ (box↖ ⊗↓ g), row 0 kept
            return _chain(down(nw), conv(box))
        if key == "quadratic":                      # §4.3: box↘ ⊗↓ (bartlett ⊗ g)
            return _chain(conv(nw), conv(box), down(box))
        if key == "cubic":                          # §4.3 (erratum): box↘ ⊗↓ (bartlett ⊗ (box↖ ⊗ g))
            return _chain(conv(nw), conv(nw), conv(box), down(box))
        if key == "bartlett":                       # §4.2 (erratum): box↘ ⊗↓ (box↖ ⊗ g)
            return _chain(conv(nw), down(box))
        if key.startswith("gauss"):
            n = int(key[5:])
            return _chain(*[conv(nw if i % 2 == 0 else box) for i in range(n - 2)], down(box))
    if isinstance(f, Named) and op is Op.UP:
        phases = {p: mask_weights(m) for p, m in catalogue.synthesis(f.key).phases.items()}
        if f.key == "cubic":                        # §5.4: box↘ ⊗ (Doo-Sabin ⊗↑ g)
            ds = {p: mask_weights(m) for p, m in catalogue.synthesis("doosabin").phases.items()}
            return _chain(up(ds), conv(box))
        if f.key == "fourpoint":                    # §5.5: rows, then columns
            split = algebra.split_step(algebra.step_of(op, f))
            if split:
                rows, cols = split
                row_pass = _stage((2, 1), (1, 1), {(p, 0): [(-1, {(d, 0): x for d, x in w.items()})]
                                                   for p, w in rows.items()})
                col_pass = _stage((1, 2), (1, 1), {(0, p): [(0, {(0, d): x for d, x in w.items()})]
                                                   for p, w in cols.items()})
                return [row_pass, col_pass]
        return [up(phases)]
    return direct_recipe(op, f, stride)


def direct_recipe(op: Op, f, stride: int = 1) -> list[Stage]:
    """One pass straight from the filter's own mask (or phase masks), taps fitted by :func:`taps_for`."""
    step = algebra.step_of(op, f, stride)
    if op is Op.UP:
        return [up({p: dict(w) for p, w in step.weights})]
    w = dict(step.weights)
    return [down(w, stride)] if op is Op.DOWN else [conv(w)]


# ------------------------------------------------------------------ cost model
def _stage_sizes(stages: list[Stage], size: tuple[int, int]) -> list[tuple[int, int]]:
    sizes: list[tuple[int, int]] = []
    for st in stages:  # a stage reading stage k takes its size
        srcs = {src for _, parts in st.phases for src, _ in parts}
        base = size if max(srcs) == -1 else sizes[max(srcs)]
        sizes.append((step_size(base[0], st.period[0], st.stride[0]), step_size(base[1], st.period[1], st.stride[1])))
    return sizes


def pass_measures(images: list[Image], ps: Pass) -> tuple[int, tuple[int, int], float, float, int]:
    """What the cost model weighs for one pass: (texture reads in its shader, the target's stored
    size, bilinear and single-texel fetches each fragment executes, stored pixels of the sources read)."""
    in_shader = sum(len(taps) for taps in ps.phases.values())
    linear, nearest = cost.executed_fetches([[(t.source, t.linear) for t in taps] for _, taps in
                                             sorted(ps.phases.items())])
    read = sum(images[s].stored[0] * images[s].stored[1] for s in ps.sources())
    return in_shader, images[ps.target].stored, linear, nearest, read


def pass_seconds(images: list[Image], ps: Pass, model: cost.CostModel | None = None) -> float:
    """The cost model's seconds for one pass: its stored target, executed fetches and sources read."""
    return (model or cost.model()).pass_seconds(*pass_measures(images, ps))


def estimate_seconds(p: Plan, model: cost.CostModel | None = None) -> float:
    """The cost model's seconds for a whole plan (passes only: no upload, read-back or compile)."""
    return sum(pass_seconds(p.images, ps, model) for ps in p.passes)


def recipe_seconds(stages: list[Stage], size: tuple[int, int], model: cost.CostModel | None = None) -> float:
    """Estimated seconds of a recipe applied to an input of ``size``, guard bands included."""
    b = Builder(size)
    b.add_stages(0, stages, "estimate")
    return sum(pass_seconds(b.images, ps, model) for ps in b.passes)


@lru_cache(maxsize=1024)
def choose_recipe(op: Op, f, stride: int, size: tuple[int, int], strategy: str = "cost") -> tuple[list[Stage], str]:
    """The paper's decomposition (§3–§5), or one fused pass when the calibrated cost model
    (:mod:`pyramid_cli.cost`) estimates it faster for an input of ``size``; and why, in one line.

    The choice depends on the size: a tiny pyramid level is all per-pass overhead, so fewer
    passes win there, while at full resolution fewer fetches do. Both candidates compute the
    same filter at every pixel (guard bands keep a named filter atomic, DESIGN.md §1).
    """
    paper = checked_recipe(op, f, stride)
    if strategy == "paper" or len(paper) == 1:
        return paper, ""
    fused = direct_recipe(op, f, stride)
    model = cost.model()
    tp, tf = recipe_seconds(paper, size, model), recipe_seconds(fused, size, model)
    fmt = cost.format_seconds
    if tf < tp:
        return fused, f"one fused pass: {fmt(tf)} < {fmt(tp)} for the paper's {len(paper)} passes ({model.name})"
    return paper, f"paper's {len(paper)} passes: {fmt(tp)} ≤ {fmt(tf)} for one fused pass ({model.name})"


@cache
def checked_recipe(op: Op, f, stride: int = 1) -> list[Stage]:
    """:func:`recipe`, verified once per filter against the filter's own exact masks."""
    stages = recipe(op, f, stride)
    if isinstance(f, Named) and not recipe_kernel_matches(stages, op, f, stride):
        raise AssertionError(f"recipe for {f.key} {op.unicode} does not match its mask")  # planner bug
    return stages


# ------------------------------------------------------------------ recipe check
def _stage_reads(stage: Stage, r: int, c: int):
    pr, pc = stage.period
    sr, sc = stage.stride
    base = (base_index(r, pr, sr), base_index(c, pc, sc))
    for ph, parts in stage.phases:
        if ph == (r % pr, c % pc):
            for src, items in parts:
                for (dr, dc), v in items:
                    yield src, (base[0] - dr, base[1] - dc), v


def recipe_kernel_matches(stages: list[Stage], op: Op, f, stride: int = 1) -> bool:
    """Does the recipe compute exactly the filter's own masks (interior, all phases)?"""
    target = algebra.kernel_of_steps([algebra.step_of(op, f, stride)])

    @cache
    def value(level: int, r: int, c: int) -> tuple:
        acc: dict = {}
        for src, (ir, ic), v in _stage_reads(stages[level], r, c):
            sub = (((ir, ic), Fraction(1)),) if src == -1 else value(src, ir, ic)
            for k, x in sub:
                acc[k] = acc.get(k, 0) + v * x
        return tuple((k, x) for k, x in acc.items() if x)

    p = target.period
    origin = 16 * max(p)
    for r in range(origin + 1, origin + p[0] + 1):
        for c in range(origin + 1, origin + p[1] + 1):
            br, bc = target.base(r, 0), target.base(c, 1)
            got = {(br - ir, bc - ic): v for (ir, ic), v in value(len(stages) - 1, r, c)}
            if got != target.phases[(r % p[0], c % p[1])]:
                return False
    return True


# ------------------------------------------------------------------ taps
_QUARTERS = {Fraction(0), Fraction(1, 4), Fraction(1, 2), Fraction(3, 4)}


def _bilinear_fit(block: list[list[Fraction]]) -> tuple[Fraction, Fraction] | None:
    """Fractions (a, b) such that a 2×2 block is W·[(1−a)(1−b), (1−a)b; a(1−b), ab], quarter steps only."""
    w = sum(sum(row) for row in block)
    if not w:
        return None
    signs = {v > 0 for row in block for v in row if v}
    if len(signs) > 1:
        return None
    a = (block[1][0] + block[1][1]) / w
    b = (block[0][1] + block[1][1]) / w
    if a not in _QUARTERS and a != 1 or b not in _QUARTERS and b != 1:
        return None
    for i in range(2):
        for j in range(2):
            if block[i][j] != w * (a if i else 1 - a) * (b if j else 1 - b):
                return None
    return a, b


def taps_for(weights: Weights, source: int) -> list[Tap]:
    """Fewest taps found greedily: 2×2 and 1×2 bilinear footprints at quarter positions, else nearest."""
    left = dict(weights)
    out: list[Tap] = []
    while left:
        # Largest footprint first: try every placement covering the smallest remaining offset.
        d0 = min(left)
        best = None
        for (oi, oj) in ((0, 0), (0, -1), (-1, 0), (-1, -1)):
            top = (d0[0] + oi, d0[1] + oj)
            block = [[left.get((top[0] + i, top[1] + j), Fraction(0)) for j in range(2)] for i in range(2)]
            covered = sum(1 for row in block for v in row if v)
            fit = _bilinear_fit(block)
            if fit and (best is None or covered > best[0]):
                best = (covered, top, fit, sum(sum(r) for r in block))
        if best is None or best[0] == 1:
            v = left.pop(d0)
            out.append(Tap(source, (Fraction(d0[0]), Fraction(d0[1])), v, False))
            continue
        _, top, (a, b), w = best
        for i in range(2):
            for j in range(2):
                left.pop((top[0] + i, top[1] + j), None)
        offset = (top[0] + a, top[1] + b)
        out.append(Tap(source, offset, w, bool(a % 1 or b % 1)))
    return out


# ------------------------------------------------------------------ bounds inference
def _needed(stage_pass: Pass, rows: tuple[int, int], cols: tuple[int, int], src: int):
    """Source index ranges read by ``rows × cols`` of a pass, for one source."""
    lo_r = lo_c = 10 ** 9
    hi_r = hi_c = -10 ** 9
    (pr, pc), (sr, sc) = stage_pass.period, stage_pass.stride
    for (phr, phc), taps in stage_pass.phases.items():
        rs = [r for r in _ends(rows, pr) if r % pr == phr]
        cs = [c for c in _ends(cols, pc) if c % pc == phc]
        for t in taps:
            if t.source != src:
                continue
            for r in rs:
                base = base_index(r, pr, sr) - t.offset[0]
                lo_r, hi_r = min(lo_r, _floor(base)), max(hi_r, _ceil(base))
            for c in cs:
                base = base_index(c, pc, sc) - t.offset[1]
                lo_c, hi_c = min(lo_c, _floor(base)), max(hi_c, _ceil(base))
    return (lo_r, hi_r), (lo_c, hi_c)


def _ends(span: tuple[int, int], p: int) -> list[int]:
    lo, hi = span
    return sorted(set(range(lo, min(hi, lo + p - 1) + 1)) | set(range(max(lo, hi - p + 1), hi + 1)))


def _floor(x) -> int:
    return int(Fraction(x).__floor__())


def _ceil(x) -> int:
    return int(Fraction(x).__ceil__())


# ------------------------------------------------------------------ planning
@lru_cache(maxsize=64)  # batches re-use a plan per image size
def plan(expr: Expr, size: tuple[int, int], strategy: str = "cost", border: str = "clamp") -> Plan:
    """Plan ``expr`` for an input of ``size`` = (rows, columns).

    ``strategy`` "paper" keeps the paper's decompositions (its fetch counts);
    "cost" lets the cost model fuse a filter into one pass where that is cheaper.
    ``border`` is how every written operator reads past its input's edges (DESIGN.md §1).
    """
    return plan_steps(steps(expr), tuple(size), text=_text(expr), paper=algebra.paper_fetches(expr),
                      strategy=strategy, border=border)


class Builder:
    """Assembles one job from written steps and combinations; any image can be read back."""

    def __init__(self, size: tuple[int, int], strategy: str = "cost", border: str = "clamp"):
        from .border import Border

        self.border = Border.parse(border).value
        self.images = [Image(tuple(size), border=self.border)]
        self.passes: list[Pass] = []
        self.inputs = [0]
        self.strategy = strategy  # "cost": cheapest of paper/fused per filter; "paper": always the paper's

    def add_input(self, size: tuple[int, int]) -> int:
        """Another uploaded image (before any pass); returns its index."""
        assert not self.passes
        self.images.append(Image(tuple(size), border=self.border))
        self.inputs.append(len(self.images) - 1)
        return self.inputs[-1]

    def step(self, source: int, op: Op, f, stride: int = 1, crop: tuple[int, int] | None = None) -> int:
        """One written operator on image ``source`` (read clamped); returns the result's image index.

        ``crop`` cuts the result to a size (top-left kept), as pyramid synthesis does for odd levels.
        """
        stages, why = choose_recipe(op, f, stride, self.images[source].size, self.strategy)
        return self.add_stages(source, stages, _label(op, f), why, crop)

    def add_stages(self, source: int, stages: list[Stage], label: str, why: str = "",
                   crop: tuple[int, int] | None = None) -> int:
        """The passes of a recipe (a named filter's, or any list of :class:`Stage`) on image
        ``source``, read clamped; intermediates get the guard bands later passes read.
        Returns the last pass's image index."""
        first = len(self.images)
        sizes = _stage_sizes(stages, self.images[source].size)
        if crop is not None:
            sizes[-1] = tuple(crop)
        for i, st in enumerate(stages):
            self.images.append(Image(sizes[i]))
            phases = {}
            for ph, parts in st.phases:
                taps = []
                for src, items in parts:
                    taps += taps_for(dict(items), source if src == -1 else first + src)
                phases[ph] = taps
            name = label + (f" [{i + 1}/{len(stages)}]" if len(stages) > 1 else "")
            self.passes.append(Pass(name, first + i, st.period, st.stride, phases, why if i == 0 else ""))
        _infer_guards(self.images, self.passes[-len(stages):], first)
        self.images[-1].border = self.border  # the result of a written operator is a boundary
        return len(self.images) - 1

    def combine(self, terms: list[tuple[int, Fraction]], label: str) -> int:
        """Σ weight · image, pixel by pixel, over images of one size (Laplacian bands, collapse)."""
        size = self.images[terms[0][0]].size
        assert all(self.images[i].size == size for i, _ in terms)
        self.images.append(Image(size, border=self.border))
        taps = [Tap(i, (Fraction(0), Fraction(0)), Fraction(w), False) for i, w in terms]
        self.passes.append(Pass(label, len(self.images) - 1, (1, 1), (1, 1), {(0, 0): taps}))
        return len(self.images) - 1

    def build(self, text: str, outputs: list[int] | None = None, paper: float | None = None) -> Plan:
        if not self.passes:  # the identity "g": one copy pass
            self.combine([(0, Fraction(1))], "g (copy)")
        return Plan(self.images, self.passes, text, paper, outputs or [len(self.images) - 1], self.inputs,
                    self.border)


def plan_steps(step_list, size: tuple[int, int], crops: dict[int, tuple[int, int]] | None = None,
               text: str = "", paper: float | None = None, strategy: str = "cost", border: str = "clamp") -> Plan:
    """Plan written steps ``(op, filter, stride)`` (innermost first) as one job;
    ``crops`` maps a step's index to the size its result is cut to."""
    crops = crops or {}
    b = Builder(size, strategy, border)
    current = 0
    for index, (op, f, stride) in enumerate(step_list):
        current = b.step(current, op, f, stride, crops.get(index))
    return b.build(text, paper=paper)


def _infer_guards(images: list[Image], passes: list[Pass], first: int) -> None:
    """Walk a named filter's passes backwards: each intermediate stores what later passes read."""
    for p in reversed(passes):
        img = images[p.target]
        t, l, b, r = img.guard
        rows, cols = (1 - t, img.size[0] + b), (1 - l, img.size[1] + r)
        for src in p.sources():
            if src < first:
                continue  # the filter's input: a boundary, read clamped
            (lo_r, hi_r), (lo_c, hi_c) = _needed(p, rows, cols, src)
            s = images[src]
            s.guard = [max(s.guard[0], 1 - lo_r), max(s.guard[1], 1 - lo_c),
                       max(s.guard[2], hi_r - s.size[0]), max(s.guard[3], hi_c - s.size[1])]
            s.guard = [max(0, g) for g in s.guard]


def _label(op: Op, f) -> str:
    from .expr import filter_text

    return f"{filter_text(f, op)} {op.unicode}"


def _text(expr: Expr) -> str:
    from .expr import to_text

    return to_text(expr)


def check(p: Plan) -> None:
    """Invariants every executor relies on; raises AssertionError on a planner bug."""
    for k, im in enumerate(p.images):
        assert im.border == "clamp" or not any(im.guard), f"image {k}: border {im.border} with a guard band"
    for ps in p.passes:
        for taps in ps.phases.values():
            for t in taps:
                assert t.source < ps.target
                for o in t.offset:
                    assert o % Fraction(1, 4) == 0, f"tap offset {o} not on a quarter texel"


__all__ = ["Plan", "Pass", "Tap", "Image", "Builder", "plan", "plan_steps", "check", "estimate_seconds",
           "choose_recipe"]


# ------------------------------------------------------------------ reports
def _tap_json(t: Tap) -> dict:
    return {"pos": [float(-t.offset[1]), float(-t.offset[0])], "weight": float(t.weight),
            "exact": str(t.weight), "sampler": t.sampler, "source": t.source}


def to_json(p: Plan) -> dict:
    """The ``pyramid plan --json`` object. ``pos`` is [x, y] in source texels relative to the
    source pixel ``R = S·⌈r/P⌉`` the output fragment maps to; sizes are [width, height].
    ``estimate_s`` is the calibrated cost model's time (per pass and in all; passes only, no
    upload, read-back or compile), ``cost_model`` where it was measured."""
    model = cost.model()
    passes = []
    for ps in p.passes:
        img = p.images[ps.target]
        entry = {"label": ps.label, "size": [img.size[1], img.size[0]], "guard": list(img.guard),
                 "period": [ps.period[1], ps.period[0]], "stride": [ps.stride[1], ps.stride[0]],
                 "fetches": ps.fetches, "estimate_s": pass_seconds(p.images, ps, model)}
        if ps.why:
            entry["why"] = ps.why
        if len(ps.phases) == 1:
            entry["taps"] = [_tap_json(t) for t in next(iter(ps.phases.values()))]
        else:
            entry["phases"] = [{"phase": list(ph), "taps": [_tap_json(t) for t in taps]}
                               for ph, taps in sorted(ps.phases.items(), reverse=True)]
        passes.append(entry)
    return {"expression": p.expression, "input": [p.images[0].size[1], p.images[0].size[0]],
            "output": [p.output.size[1], p.output.size[0]], "passes": passes, "fetches": p.fetches,
            "fetches_per_output_pixel": p.fetches_per_output_pixel, "paper_fetches": p.paper_fetches,
            "estimate_s": estimate_seconds(p, model), "cost_model": model.name}


def render(p: Plan) -> str:
    """The human-readable ``pyramid plan`` report."""
    h, w = p.images[0].size
    oh, ow = p.output.size
    lines = [f"plan   {p.expression}", f"input  {w}×{h} → output {ow}×{oh}, {len(p.passes)} pass(es)"]
    for n, ps in enumerate(p.passes, 1):
        img = p.images[ps.target]
        t, l, b, r = img.guard
        guard = f" + guard t{t} l{l} b{b} r{r}" if any(img.guard) else ""
        srcs = ", ".join("input" if s == 0 else f"pass {s}" for s in sorted(ps.sources()))
        lines.append(f"pass {n}  {ps.label}: {img.size[1]}×{img.size[0]}{guard}, reads {srcs}, "
                     f"{ps.fetches:g} fetch(es) per fragment")
        if ps.why:
            lines.append(f"        chosen: {ps.why}")
        for ph, taps in sorted(ps.phases.items(), reverse=True):
            head = f"  phase {ph[0]},{ph[1]}" if len(ps.phases) > 1 else "  "
            for i, tap in enumerate(taps):
                src = "" if len(ps.sources()) == 1 else (" input" if tap.source == 0 else f" pass {tap.source}")
                lines.append(f"{head if i == 0 else ' ' * len(head)}  {tap.sampler:<7} at "
                             f"({float(-tap.offset[1]):+.2f}, {float(-tap.offset[0]):+.2f}) × {tap.weight}{src}")
    paper = "n/a" if p.paper_fetches is None else f"{p.paper_fetches:g}"
    lines.append(f"fetches {p.fetches:g} (paper: {paper}); per output pixel {p.fetches_per_output_pixel:.2f}")
    model = cost.model()
    lines.append(f"estimate {cost.format_seconds(estimate_seconds(p, model))} for the passes "
                 f"(no upload, read-back or compile; {model.name})")
    return "\n".join(lines)
