"""The float64 oracle of the pyramid workflows: blur, levels, Laplacian bands and their collapse.

Each runs the paper's index formulas (:mod:`pyramid_cli.reference.filters`) level by level, cropping
every synthesis to its level's size, as the paper's Figure 3 draws it. Independent of the plans that
:mod:`pyramid_cli.workflows.pyramids` builds for the same workflows: this package imports only
:mod:`pyramid_cli.core`, and neither the algebra nor the planner it checks.
"""

from __future__ import annotations

import numpy as np

from pyramid_cli.core.border import Border
from pyramid_cli.core.catalogue import DEFAULT_ANALYSIS, DEFAULT_SYNTHESIS
from pyramid_cli.core.expr import Apply, Expr, Input, Named, Op
from pyramid_cli.core.geometry import level_sizes
from pyramid_cli.core.parse import one_step
from pyramid_cli.reference import filters

A0, S0 = DEFAULT_ANALYSIS, DEFAULT_SYNTHESIS


def _run(expr: Expr, x, border: str):
    return filters.run(expr, x, Border.parse(border))


def expand_to(x, synthesis: str, size: tuple[int, int], border: str):
    """One synthesis step (⊗↑) of ``x``, cropped to ``size`` (rows, columns): the next finer level."""
    return _run(one_step(synthesis, Op.UP), x, border)[:size[0], :size[1]]


def blur_reference(pixels, levels: int, analysis: str = A0, synthesis: str = S0,
                   quasi: bool = False, border: str = "clamp"):
    """The blur by the numpy reference, level by level, cropping each synthesis to its level's size."""
    sizes = level_sizes(pixels.shape[:2], levels)
    x = levels_reference(pixels, levels, analysis, border)[-1]
    if quasi:
        x = _run(Apply(Op.CONV, Named("quasi"), Input()), x, border)
    for k in range(levels, 0, -1):
        x = expand_to(x, synthesis, sizes[k - 1], border)
    return x


def blur_blend_reference(pixels, levels: int, t: float, analysis: str = A0, synthesis: str = S0,
                         border: str = "clamp"):
    """(1 − t) × the ``levels``-level blur + t × the (levels+1)-level one: ``blur --sigma`` by the reference,
    with ``(levels, t)`` from :func:`pyramid_cli.core.sigma.sigma_blend` (the oracle does not compute sigmas)."""
    low = blur_reference(pixels, levels, analysis, synthesis, border=border) if levels else pixels
    return (1 - t) * low + t * blur_reference(pixels, levels + 1, analysis, synthesis, border=border)


def levels_reference(pixels, levels: int, analysis: str = A0, border: str = "clamp") -> list:
    """Levels 0..m of the analysis pyramid by the reference (level 0 is the input, as float64)."""
    out = [np.asarray(pixels, dtype=np.float64)]
    down = one_step(analysis, Op.DOWN)
    for _ in range(levels):
        out.append(_run(down, out[-1], border))
    return out


def laplacian_reference(pixels, levels: int, analysis: str = A0, synthesis: str = S0,
                        border: str = "clamp") -> list:
    """L_0..L_{m−1}, G_m by the reference (``levels_plan`` with ``laplacian``)."""
    g = levels_reference(pixels, levels, analysis, border)
    return [g[k] - expand_to(g[k + 1], synthesis, g[k].shape[:2], border) for k in range(levels)] + [g[-1]]


def collapse_reference(bands: list, synthesis: str = S0, border: str = "clamp"):
    """G_0 from L_0..L_{m−1}, G_m by the reference (``collapse_plan``)."""
    x = np.asarray(bands[-1], dtype=np.float64)
    for band in reversed(bands[:-1]):
        x = np.asarray(band, dtype=np.float64) + expand_to(x, synthesis, band.shape[:2], border)
    return x


__all__ = ["expand_to", "blur_reference", "blur_blend_reference", "levels_reference", "laplacian_reference",
           "collapse_reference"]
