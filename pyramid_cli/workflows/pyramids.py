"""Pyramid workflows built from written steps: blur (Strengert, Kraus & Ertl 2006; paper §2, Figure 3).

Each workflow is planned as one job (one :class:`~pyramid_cli.plan.Plan`), so
an executor runs it without read-back between levels.
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

from pyramid_cli.core import algebra, catalogue
from pyramid_cli.core.errors import UsageError
from pyramid_cli.core.expr import Op, steps
from pyramid_cli.core.geometry import level_sizes, mip_sizes
from pyramid_cli.core.parse import one_step
from pyramid_cli.core.sigma import blur_steps, sigma_blend
from pyramid_cli.plan.lower import Builder, plan_steps
from pyramid_cli.plan.model import Plan
from pyramid_cli.plan.resample import axis_table, bilinear_table, ceil2

A0, S0 = catalogue.DEFAULT_ANALYSIS, catalogue.DEFAULT_SYNTHESIS


@lru_cache(maxsize=32)  # batches re-use a plan per image size
def blur_plan_sigma(size: tuple[int, int], sigma: float, analysis: str = A0, synthesis: str = S0,
                    border: str = "clamp", strategy: str = "cost"):
    """A blur of Gaussian-equivalent ``sigma`` (input pixels): the blend of the m- and (m+1)-level blurs
    whose variance is sigma², so the strength changes continuously with sigma. Returns (plan, levels, t)."""
    m, t = sigma_blend(sigma, analysis, synthesis)
    down = steps(one_step(analysis, Op.DOWN))
    up = steps(one_step(synthesis, Op.UP))
    sizes = level_sizes(size, m + 1)
    b = Builder(size, strategy, border)
    g = [0]
    for _ in range(m + 1):
        g.append(run_steps(b, g[-1], down))
    ends = []
    for levels in (m, m + 1):
        x = g[levels]
        for k in range(levels, 0, -1):
            x = run_steps(b, x, up, crop=sizes[k - 1])
        ends.append(x)
    out = b.combine([(ends[0], Fraction(1) - Fraction(t)), (ends[1], Fraction(t))],
                    f"blend {1 - t:.4f} × {m} level(s) + {t:.4f} × {m + 1}")
    text = f"blur: sigma {sigma:g} = {1 - t:.4f} × {m} + {t:.4f} × {m + 1} levels, {analysis} ⊗↓ / {synthesis} ⊗↑"
    return b.build(text, outputs=[out]), m, t


def run_steps(b: Builder, source: int, step_list, crop=None) -> int:
    """Add ``step_list``'s passes to ``b`` after image ``source``, the last one cropped to ``crop``; returns
    the image the last step writes."""
    for i, (op, f, s) in enumerate(step_list):
        source = b.step(source, op, f, s, crop if i == len(step_list) - 1 else None)
    return source


@lru_cache(maxsize=32)  # batches re-use a plan per image size
def levels_plan(size: tuple[int, int], levels: int, analysis: str = A0, laplacian: bool = False,
                synthesis: str = S0, border: str = "clamp", strategy: str = "cost") -> Plan:
    """Levels 1..m of the analysis pyramid, or with ``laplacian`` the bands L_0..L_{m−1} and G_m
    (L_k = G_k − expand(G_{k+1}), cropped to level k), as one job."""
    if levels < 1:
        raise UsageError("--levels must be at least 1")
    down = steps(one_step(analysis, Op.DOWN))
    sizes = level_sizes(size, levels)
    b = Builder(size, strategy, border)
    g = [0]
    for _ in range(levels):
        g.append(run_steps(b, g[-1], down))
    if not laplacian:
        return b.build(f"levels: {levels} × {analysis} ⊗↓", outputs=g[1:])
    up = steps(one_step(synthesis, Op.UP))
    bands = []
    for k in range(levels):
        expanded = run_steps(b, g[k + 1], up, crop=sizes[k])
        bands.append(b.combine([(g[k], Fraction(1)), (expanded, Fraction(-1))], f"L{k} = G{k} − expand(G{k + 1})"))
    return b.build(f"Laplacian: {levels} × {analysis} ⊗↓, {synthesis} ⊗↑", outputs=bands + [g[-1]])


@lru_cache(maxsize=32)  # batches re-use a plan per image size
def collapse_plan(sizes: tuple[tuple[int, int], ...], synthesis: str = S0, border: str = "clamp",
                  strategy: str = "cost") -> Plan:
    """Rebuild G_0 from L_0..L_{m−1}, G_m (inputs 0..m): G_k = L_k + expand(G_{k+1})."""
    up = steps(one_step(synthesis, Op.UP))
    b = Builder(sizes[0], strategy, border)
    for sz in sizes[1:]:
        b.add_input(sz)
    x = len(sizes) - 1
    for k in range(len(sizes) - 2, -1, -1):
        expanded = run_steps(b, x, up, crop=sizes[k])
        x = b.combine([(k, Fraction(1)), (expanded, Fraction(1))], f"G{k} = L{k} + expand(G{k + 1})")
    return b.build(f"collapse: {len(sizes) - 1} level(s), {synthesis} ⊗↑", outputs=[x])


@lru_cache(maxsize=32)  # batches re-use a plan per image size
def blur_plan(size: tuple[int, int], levels: int, analysis: str = A0, synthesis: str = S0,
              quasi: bool = False, strategy: str = "cost", border: str = "clamp") -> Plan:
    step_list, crops = blur_steps(size, levels, analysis, synthesis, quasi)
    text = f"blur: {levels} level(s), {analysis} ⊗↓ / {synthesis} ⊗↑" + (" + quasi" if quasi else "")
    return plan_steps(step_list, size, crops, text=text, strategy=strategy, border=border)


@lru_cache(maxsize=64)
def mip_axis_weights(analysis: str):
    """The 1-D weights (rows, columns) of a one-step separable ⊗↓ filter, ``((d, w_d), …)`` each, for
    :func:`mip_plan`; UsageError (exit 2) for an analysis that maketx's level sizes cannot use."""
    st = steps(one_step(analysis, Op.DOWN))
    split = algebra.split_step(algebra.step_of(*st[0])) if len(st) == 1 and st[0][2] == 1 else None
    if split is None:
        raise UsageError(f"--analysis {analysis!r}: maketx's level sizes (--round down) need one separable ⊗↓ "
                         "step (box, box4, quadratic, cubic or a separable mask); use --round up for others")
    return tuple(tuple(sorted(axis[0].items())) for axis in split)


# The border a MIP level (maketx's sizes) is built with, for each lookup border: a level averages what it covers
# inside the texture's domain, so clamp and zero (black) build with the filter folded back into the domain by
# reflection, which keeps every row's weights at 1 and every input texel's total at m/n (the mean; derivation
# in docs/design.md, "MIP levels inside the domain"); wrap and mirror build as they read.
LEVEL_BORDER: dict[str, str] = {"clamp": "mirror", "zero": "mirror", "wrap": "wrap", "mirror": "mirror"}


def level_border(border: str) -> str:
    """The border MIP levels of maketx's sizes are built with when lookups read past the edges by ``border``
    (:data:`LEVEL_BORDER`): ``mirror`` for ``clamp`` and ``zero``, the border itself for ``wrap`` and ``mirror``.

    The lookup's border stays the file's ``wrapmodes``; ``--round up`` (the analysis pyramid's padded
    levels) builds with the lookup's border as before.
    """
    return LEVEL_BORDER[border]


def folds_alike(weights, sizes) -> bool:
    """Does clamp fold every read of a MIP chain of ``sizes`` as mirror does? Yes when no read of any level
    reaches more than one texel past an edge (both fold −1 to 0 and n to n − 1): box, box4 and quadratic at
    exact halvings (power-of-two sizes), or the bilinear reads of ``--resize``. Then the chain built with
    the clamp border has the mirror fold's weights, and :func:`mip_plan` keeps its passes as they were."""
    for (h, w), (h2, w2) in zip(sizes[:-1], sizes[1:], strict=True):
        for axis, (n, m) in enumerate(((h, h2), (w, w2))):
            if n != m:
                starts, table = axis_table(weights[axis], n, m)
                if min(starts) < -1 or max(st + len(row) for st, row in zip(starts, table, strict=True)) > n + 1:
                    return False
    return True


@lru_cache(maxsize=32)  # batches re-use a plan per image size
def mip_plan(size: tuple[int, int], analysis: str = catalogue.MIP_ANALYSIS_DEFAULT, border: str = "clamp",
             strategy: str = "cost", resize: bool = False) -> Plan:
    """MIP levels 1..1×1 with maketx's sizes ``max(1, ⌊n/2⌋)``, every level covering the whole texture domain.

    A level that halves both sizes exactly runs the paper's ⊗↓ passes of ``analysis`` (§4). Any other
    level runs one :class:`~pyramid_cli.plan.ResamplePass` per axis that changes: the same filter's
    continuous kernel stretched to the level's ratio (:mod:`pyramid_cli.plan.resample`; at an exact
    halving its weights are the paper's). An axis of one pixel stays as it is.

    ``resize`` (maketx's ``--resize``): level 0 is first resampled up to powers of two, as a bilinear
    lookup reads the source (:func:`pyramid_cli.plan.resample.bilinear_table`); it is then output 0.

    ``border`` is how a lookup reads past the edges (the file's ``wrapmodes``); the levels are built
    with :func:`pyramid_cli.workflows.pyramids.level_border` of it, inside the texture's domain: ``clamp`` and
    ``zero`` build mirrored (every level keeps level 0's mean), ``wrap`` periodically, ``mirror`` mirrored;
    a ``clamp`` chain that :func:`folds_alike` keeps the clamp border, whose weights are then the same.
    """
    weights = mip_axis_weights(analysis)
    down = steps(one_step(analysis, Op.DOWN))
    build = level_border(border)
    if border == "clamp" and folds_alike(weights, mip_sizes((ceil2(size[0]), ceil2(size[1])) if resize else size)):
        build = border  # the same weights: a power-of-two chain keeps its passes (and its outputs) bit for bit
    b = Builder(size, strategy, build)
    outs, current = [], 0
    if resize:
        for axis, n in enumerate(size):
            if ceil2(n) != n:
                current = b.resample(current, axis, *bilinear_table(n, ceil2(n)),
                                     f"level 0: resized to a power of two, {('rows', 'columns')[axis]} "
                                     f"{n}→{ceil2(n)} (bilinear)")
        size = (ceil2(size[0]), ceil2(size[1]))
        if current == 0:  # already powers of two: level 0 is a copy of the input
            current = b.combine([(0, Fraction(1))], "level 0 (already powers of two)")
        outs.append(current)
    sizes = mip_sizes(size)
    for k in range(1, len(sizes)):
        (h, w), (h2, w2) = sizes[k - 1], sizes[k]
        if h == 2 * h2 and w == 2 * w2:
            first = len(b.passes)
            current = run_steps(b, current, down)
            for ps in b.passes[first:]:
                ps.label = f"level {k} {w2}×{h2}: {ps.label} (exact halving: the paper's passes)"
        else:
            for axis, (n, m) in enumerate(((h, h2), (w, w2))):
                if n == m:
                    continue
                name = ("rows", "columns")[axis]
                starts, table = axis_table(weights[axis], n, m)
                ratio = "exact ×2" if n == 2 * m else f"×{n / m:.4g}"
                current = b.resample(current, axis, starts, table,
                                     f"level {k} {w2}×{h2}: {analysis} kernel resampled, {name} {n}→{m} ({ratio})")
        outs.append(current)
    text = f"mipmap: {len(sizes) - 1} level(s) to 1×1, maketx's sizes, {analysis} ⊗↓"
    text += ", level 0 resized to powers of two" if resize else ""
    if build != border:
        text += f", built inside the domain (edges folded by mirror; lookups read {border})"
    return b.build(text, outputs=outs)


def _lattice(text: str, op: Op) -> str:
    return algebra.lattice(algebra.kernel(one_step(text, op)))[0]


LATTICE_EFFECTS = {  # what a mixed pair costs each method; {shift}: ", about 7.5 px after 4 level(s)"
    "blur": "the result shifts by half a fine pixel per level (docs/design.md §4){shift}",
    "blend": "each coarser band shifts by half a fine pixel, which moves the seam{shift}",
    "fill": "the push shifts each coarser level by half a fine pixel, so holes fill from beside where they are "
            "(2–3× the error of a pair on one lattice)",
}


def lattice_mismatch(analysis: str, synthesis: str, levels: int | None = None, method: str = "blur") -> str | None:
    """A warning when analysis and synthesis sit on different lattices (docs/design.md §4), else None.

    Each synthesis step of such a pair lands half a pixel of its level off the analysis's grid, so after
    ``levels`` steps the result sits about (2ᵐ − 1)/2 input pixels off (7.5 at 4 levels; measured on an
    impulse and on a blend's seam). ``method`` ("blur", "fill", "blend") says what that does to the
    result; the message ends with the named synthesis filters on the analysis's lattice.
    """
    down, up = _lattice(analysis, Op.DOWN), _lattice(synthesis, Op.UP)
    if down == up:
        return None
    shift = f", about {(2 ** levels - 1) / 2:g} px after {levels} level(s)" if levels else ""
    text = (f"analysis {analysis} sits on the {down} lattice and synthesis {synthesis} on the {up} one: "
            + LATTICE_EFFECTS[method].format(shift=shift))
    same = [name for name in catalogue.SYNTHESIS_FILTERS if _lattice(name, Op.UP) == down]
    if same:
        names = same[0] if len(same) == 1 else f"{', '.join(same[:-1])} or {same[-1]}"
        text += f"; synthesis {names} shares {analysis}'s lattice"
    return text
