"""The float64 oracle of the pyramid methods, written from the papers' equations (not from the plans).

Pull-push (M. Kraus, "The Pull-Push Algorithm Revisited", GRAPP 2009, restating Gortler et al.,
"The Lumigraph", SIGGRAPH 1996): the pull phase computes, level by level,
``w_{k+1} = min(1, K·Σ h̃ w_k)`` and the weighted mean colour ``x_{k+1} = Σ h̃ w_k x_k / Σ h̃ w_k``;
the push phase composites each level over the expanded coarser one,
``x_k ← w_k·x_k + (1 − w_k)·expand(x_{k+1})``, and at every level k ≥ 1 ``sweeps`` times
``x_k ← w_k·x_k + (1 − w_k)·B(x_k)`` with B the 3×3 Bartlett mask (damped Jacobi sweeps of the
membrane equation in the holes). Here it is written in straight colours ``x``
(not premultiplied ones as the plans carry), with ``h̃`` the analysis filter and expand the
synthesis filter evaluated by :mod:`pyramid_cli.reference.filters` (the 2007 paper's index formulas).

Blending (Burt & Adelson, "A Multiresolution Spline With Application to Image Mosaics", 1983):
``LS_l = GR_l·LA_l + (1 − GR_l)·LB_l`` per level of the Laplacian pyramids of A and B and the
Gaussian pyramid of the region mask R, and the blend is the sum of the expanded LS_l.
"""

from __future__ import annotations

import numpy as np

from pyramid_cli.core import catalogue
from pyramid_cli.core.border import Border
from pyramid_cli.core.expr import Apply, Input, Named, Op
from pyramid_cli.core.geometry import mip_levels
from pyramid_cli.reference import filters
from pyramid_cli.reference.pyramids import collapse_reference, expand_to, laplacian_reference, levels_reference

K = 4  # the classic weight scale: a coarse pixel covers 2×2 fine ones


def _down(x: np.ndarray, analysis: str, border: str) -> np.ndarray:
    return levels_reference(x, 1, analysis, border)[1]


def _bartlett(x: np.ndarray, border: str) -> np.ndarray:
    return filters.run(Apply(Op.CONV, Named("bartlett"), Input()), x, Border.parse(border))


def fill(colour: np.ndarray, weight: np.ndarray, levels: int | None = None,
         analysis: str = catalogue.FILL_ANALYSIS, synthesis: str = catalogue.FILL_SYNTHESIS,
         border: str = "clamp", scale: int | tuple[int, int] = catalogue.FILL_SCALE,
         sweeps: int | tuple[int, int] = catalogue.FILL_SWEEPS) -> np.ndarray:
    """Pull-push of straight colours ``colour`` with weights ``weight`` (same shape, in [0, 1]); float64.

    ``scale`` is the weight scale K (``w_{k+1} = min(1, K·Σ h̃ w_k)``) and ``sweeps`` the smoothing
    sweeps, each one number or a pair (level 1, every coarser level; no sweep at level 0 or the coarsest).
    Pixels with weight 0 may hold anything finite: they never enter a sum.
    """
    scales, sweep_counts = (tuple(v) if isinstance(v, (tuple, list)) else (v, v) for v in (scale, sweeps))
    x = [np.asarray(colour, dtype=np.float64)]
    w = [np.asarray(weight, dtype=np.float64)]
    m = mip_levels(x[0].shape[:2]) if levels is None else levels
    for _ in range(m):  # pull
        sw = _down(w[-1], analysis, border)                 # Σ h̃ w_k
        swx = _down(w[-1] * x[-1], analysis, border)        # Σ h̃ w_k x_k
        with np.errstate(divide="ignore", invalid="ignore"):
            x.append(np.where(sw > 0, swx / np.where(sw > 0, sw, 1), 0.0))
        w.append(np.minimum(1.0, scales[min(len(w) - 1, 1)] * sw))
    out = x[m]  # the coarsest level: every pixel with a positive weight holds its mean colour
    for k in range(m - 1, -1, -1):  # push
        expanded = expand_to(out, synthesis, x[k].shape[:2], border)
        out = w[k] * x[k] + (1 - w[k]) * expanded
        for _ in range(sweep_counts[min(k, 2) - 1] if k > 0 else 0):
            out = w[k] * x[k] + (1 - w[k]) * _bartlett(out, border)
    return out


def blend(a: np.ndarray, b: np.ndarray, mask: np.ndarray, levels: int,
          analysis: str = catalogue.DEFAULT_ANALYSIS, synthesis: str = catalogue.DEFAULT_SYNTHESIS,
          border: str = "clamp") -> np.ndarray:
    """Burt & Adelson's multiresolution spline of ``a`` and ``b`` along ``mask`` (all the same shape); float64."""
    if levels == 0:
        m = np.asarray(mask, dtype=np.float64)
        return m * a + (1 - m) * b
    la = laplacian_reference(a, levels, analysis, synthesis, border)
    lb = laplacian_reference(b, levels, analysis, synthesis, border)
    gr = levels_reference(mask, levels, analysis, border)
    ls = [g * x + (1 - g) * y for g, x, y in zip(gr, la, lb, strict=True)]
    return collapse_reference(ls, synthesis, border)


__all__ = ["fill", "blend", "K"]
