"""The paper's decompositions of named filters into box-sized stages (§3–§5), and their check.

A recipe is a list of :class:`Stage` s; :func:`recipe_kernel_matches` verifies one
against the filter's own exact masks (interior, every phase), and
:func:`checked_recipe` refuses to plan with one that does not match. docs/design.md §3
lists the paper's arrow errata these recipes correct.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import cache

from pyramid_cli.core import algebra, catalogue
from pyramid_cli.core.algebra import Weights, mask_weights
from pyramid_cli.core.expr import Named, Op
from pyramid_cli.core.geometry import base_index, step_size


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


def chain(*stages_outermost_last: Stage) -> list[Stage]:
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
            return chain(conv(nw), conv(box))
        if key.startswith("gauss"):                 # §3.3: (n−1)/2 Bartletts, n−1 passes
            n = int(key[5:])
            return chain(*[conv(nw if i % 2 == 0 else box) for i in range(n - 1)])
        if key == "quasi":                          # §5.5: 10/6 δ − 16/24 (box↘ ⊗ (box↖ ⊗ g))
            first = conv(nw)
            last = _stage((1, 1), (1, 1), {(0, 0): [
                (-1, {(0, 0): Fraction(10, 6)}),
                (0, {d: -Fraction(16, 24) * v for d, v in box.items()})]})
            return [first, last]
    if isinstance(f, Named) and op is Op.DOWN and stride == 1:
        key = f.key
        if key == "box4":                           # §4.2 (erratum): box↘ ⊗ (box↖ ⊗↓ g), row 0 kept
            return chain(down(nw), conv(box))
        if key == "quadratic":                      # §4.3: box↘ ⊗↓ (bartlett ⊗ g)
            return chain(conv(nw), conv(box), down(box))
        if key == "cubic":                          # §4.3 (erratum): box↘ ⊗↓ (bartlett ⊗ (box↖ ⊗ g))
            return chain(conv(nw), conv(nw), conv(box), down(box))
        if key == "bartlett":                       # §4.2 (erratum): box↘ ⊗↓ (box↖ ⊗ g)
            return chain(conv(nw), down(box))
        if key.startswith("gauss"):
            n = int(key[5:])
            return chain(*[conv(nw if i % 2 == 0 else box) for i in range(n - 2)], down(box))
    if isinstance(f, Named) and op is Op.UP:
        phases = {p: mask_weights(m) for p, m in catalogue.synthesis(f.key).phases.items()}
        if f.key == "cubic":                        # §5.4: box↘ ⊗ (Doo-Sabin ⊗↑ g)
            ds = {p: mask_weights(m) for p, m in catalogue.synthesis("doosabin").phases.items()}
            return chain(up(ds), conv(box))
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


def stage_sizes(stages: list[Stage], size: tuple[int, int]) -> list[tuple[int, int]]:
    """(rows, cols) of each stage's output, for a filter whose input is ``size``."""
    sizes: list[tuple[int, int]] = []
    for st in stages:  # a stage reading stage k takes its size
        srcs = {src for _, parts in st.phases for src, _ in parts}
        base = size if max(srcs) == -1 else sizes[max(srcs)]
        sizes.append((step_size(base[0], st.period[0], st.stride[0]), step_size(base[1], st.period[1], st.stride[1])))
    return sizes


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
