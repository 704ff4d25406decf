"""Lowering: written steps to passes, choosing each filter's recipe by the cost model.

:func:`plan` plans an expression; :class:`Builder` assembles a job of several
written steps, inputs and combinations (pyramids), giving intermediates their guard
bands and every boundary the plan's border mode.
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

from pyramid_cli.core import algebra
from pyramid_cli.core.expr import Expr, Op, steps
from pyramid_cli.plan import cost
from pyramid_cli.plan.bounds import infer_guards
from pyramid_cli.plan.estimate import pass_seconds
from pyramid_cli.plan.model import Image, Pass, Plan, PointwisePass, ResamplePass, Tap
from pyramid_cli.plan.recipes import Stage, checked_recipe, direct_recipe, stage_sizes
from pyramid_cli.plan.taps import taps_for


def recipe_seconds(stages: list[Stage], size: tuple[int, int], model: cost.CostModel | None = None) -> float:
    """Estimated seconds of a recipe applied to an input of ``size``, guard bands included."""
    b = Builder(size)
    b.add_stages(0, stages, "estimate")
    return sum(pass_seconds(b.images, ps, model) for ps in b.passes)


FUSED_WHY = "one fused pass per filter (the executor's choice: fewer passes over memory)"


@lru_cache(maxsize=1024)
def choose_recipe(op: Op, f, stride: int, size: tuple[int, int], strategy: str = "cost") -> tuple[list[Stage], str]:
    """The paper's decomposition (§3–§5), or one fused pass when the calibrated cost model
    (:mod:`pyramid_cli.plan.cost`) estimates it faster for an input of ``size``; and why, in one line.

    The choice depends on the size: a tiny pyramid level is all per-pass overhead, so fewer
    passes win there, while at full resolution fewer fetches do. Both candidates compute the
    same filter at every pixel (guard bands keep a named filter atomic, docs/design.md §1).
    ``strategy`` "paper" always takes the paper's decomposition, "fused" always one pass per
    filter (what a CPU executor wants: each pass streams its whole target through memory).
    """
    paper = checked_recipe(op, f, stride)
    if strategy == "paper" or len(paper) == 1:
        return paper, ""
    fused = direct_recipe(op, f, stride)
    if strategy == "fused":
        return fused, FUSED_WHY
    model = cost.model()
    tp, tf = recipe_seconds(paper, size, model), recipe_seconds(fused, size, model)
    fmt = cost.format_seconds
    if tf < tp:
        return fused, f"one fused pass: {fmt(tf)} < {fmt(tp)} for the paper's {len(paper)} passes ({model.name})"
    return paper, f"paper's {len(paper)} passes: {fmt(tp)} ≤ {fmt(tf)} for one fused pass ({model.name})"


@lru_cache(maxsize=64)  # batches re-use a plan per image size
def plan(expr: Expr, size: tuple[int, int], strategy: str = "cost", border: str = "clamp") -> Plan:
    """Plan ``expr`` for an input of ``size`` = (rows, columns).

    ``strategy`` "paper" keeps the paper's decompositions (its fetch counts);
    "cost" lets the cost model fuse a filter into one pass where that is cheaper.
    ``border`` is how every written operator reads past its input's edges (docs/design.md §1).
    """
    return plan_steps(steps(expr), (size[0], size[1]), text=_text(expr), paper=algebra.paper_fetches(expr),
                      strategy=strategy, border=border)


class Builder:
    """Assembles one job from written steps and combinations; any image can be read back."""

    def __init__(self, size: tuple[int, int], strategy: str = "cost", border: str = "clamp"):
        from pyramid_cli.core.border import Border

        self.border = Border.parse(border).value
        self.images = [Image((size[0], size[1]), border=self.border)]
        self.passes: list[Pass | ResamplePass | PointwisePass] = []
        self.inputs = [0]
        self.strategy = strategy  # "cost": cheapest of paper/fused per filter; "paper": always the paper's

    def add_input(self, size: tuple[int, int]) -> int:
        """Another uploaded image (before any pass); returns its index."""
        assert not self.passes
        self.images.append(Image((size[0], size[1]), border=self.border))
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
        sizes = stage_sizes(stages, self.images[source].size)
        if crop is not None:
            sizes[-1] = (crop[0], crop[1])
        added: list[Pass] = []
        for i, st in enumerate(stages):
            self.images.append(Image(sizes[i]))
            phases = {}
            for ph, parts in st.phases:
                taps = []
                for src, items in parts:
                    taps += taps_for(dict(items), source if src == -1 else first + src)
                phases[ph] = taps
            name = label + (f" [{i + 1}/{len(stages)}]" if len(stages) > 1 else "")
            added.append(Pass(name, first + i, st.period, st.stride, phases, why if i == 0 else ""))
        self.passes += added
        infer_guards(self.images, added, first)
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

    def resample(self, source: int, axis: int, starts, weights, label: str, why: str = "") -> int:
        """One :class:`ResamplePass` of image ``source`` along ``axis`` (0 rows, 1 columns) with the table
        ``starts``/``weights`` (:func:`pyramid_cli.plan.resample.axis_table`); the result is a boundary."""
        rows, cols = self.images[source].size
        self.images.append(Image((len(starts), cols) if axis == 0 else (rows, len(starts)), border=self.border))
        self.passes.append(ResamplePass(label, len(self.images) - 1, source, axis, tuple(starts),
                                        tuple(tuple(row) for row in weights), why))
        return len(self.images) - 1

    def pointwise(self, op: str, sources: list[int], label: str, param=1) -> int:
        """A :class:`~pyramid_cli.plan.model.PointwisePass` (``op`` of :data:`~pyramid_cli.plan.model.POINTWISE_OPS`)
        over images of one size; returns the result's image index (a boundary, like a written step's result)."""
        size = self.images[sources[0]].size
        assert all(self.images[i].size == size for i in sources)
        self.images.append(Image(size, border=self.border))
        self.passes.append(PointwisePass(label, len(self.images) - 1, op, tuple(sources), Fraction(param)))
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


def _label(op: Op, f) -> str:
    from pyramid_cli.core.expr import filter_text

    return f"{filter_text(f, op)} {op.unicode}"


def _text(expr: Expr) -> str:
    from pyramid_cli.core.expr import to_text

    return to_text(expr)
