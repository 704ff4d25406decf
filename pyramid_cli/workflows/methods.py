"""The pyramid methods built on the paper's filters: pull-push hole filling and multiresolution blending.

Each is planned as ONE :class:`~pyramid_cli.plan.Plan` with several inputs and outputs per
level: the paper's analysis (⊗↓, §4) and synthesis (⊗↑, §5) filters as written steps, and the
nonlinear per-pixel steps as :class:`~pyramid_cli.plan.model.PointwisePass` es, so every plan
executor (emulator, CPU, GL) runs the whole method without read-back between levels. The
float64 oracle, written from the papers' equations and not from these plans, is
:mod:`pyramid_cli.reference.methods`.

**Pull-push** (Gortler et al., "The Lumigraph", SIGGRAPH 1996; on the GPU, Strengert, Kraus & Ertl,
"Pyramid Methods in GPU-Based Image Processing", VMV 2006; normalised in M. Kraus, "The Pull-Push
Algorithm Revisited", GRAPP 2009, https://www.scitepress.org/papers/2009/17726/17726.pdf). Level 0 holds
premultiplied colours ``p₀ = w₀·c`` and weights ``w₀ ∈ [0, 1]``. With ``A`` the analysis filter
(normalised: its weights sum to 1), ``S`` the synthesis filter, ``K_k`` the weight scale of level k (a
coarse pixel covers 2×2 fine ones: Gortler's pull filter ``h̃ = [½ 1 ½]²`` sums to 4, the classic ``K``)
and ``R_k`` the smoothing sweeps of level k:

- pull, k = 0 … m−1:  ``W = A(w_k)``, ``P = A(p_k)``, ``w_{k+1} = min(1, K_{k+1}·W)``,
  ``p_{k+1} = P · w_{k+1} / W`` (0 where W = 0): the weighted mean colour ``P/W`` carried with
  the clamped weight (``pull_weight``, ``pull_colour``);
- the coarsest level: ``c̄_m = p_m / w_m`` (``divide``);
- push, k = m−1 … 0: ``c̄_k = p_k + (1 − w_k)·S(c̄_{k+1})`` (``over``): each level composited
  over the expanded, already complete coarser one by its own weight; then, at levels 1 … m−1,
  ``R_k`` times ``c̄_k ← p_k + (1 − w_k)·B(c̄_k)`` with ``B`` the 3×3 Bartlett mask (a ``bartlett ⊗``
  pass and ``over``): damped Jacobi sweeps of the membrane (Laplace) equation in the holes with the
  known part held, so the push hands each finer level a continuation of the known pixels closer to the
  harmonic one instead of their blurred mean: the coarse-to-fine relaxation of multigrid surface
  interpolation (Terzopoulos, "Image Analysis Using Multigrid Relaxation Methods", IEEE PAMI 8(2), 1986),
  started from the pull-push pyramid. ``R = 0`` and one ``K`` at every level is the classic pull-push.

``K`` and ``R`` are given for level 1 and for every coarser level (``(K_1, K_≥2)``, ``(R_1, R_≥2)``): a
weight curve per level. A known pixel of weight 1 comes out as ``p₀ + 0·S(…) = c`` exactly: level 0 is
never swept. The defaults (quadratic ⊗↓, Doo-Sabin ⊗↑, ``K`` = (16, 2), ``R`` = (1, 4)) were chosen by
measurement against ``oiiotool --fillholes`` (``bench/fill_cases.py``, docs/tutorials/fill-and-blend.md);
the former defaults (box4 ⊗↓, ``K`` = 4, ``R`` = 0) stay reachable through the options.

**Blending** (Burt & Adelson,
"A Multiresolution Spline With Application to Image Mosaics", ACM ToG 2(4), 1983):
``LS_k = GM_k·LA_k + (1 − GM_k)·LB_k`` for the Laplacian bands of A and B and the Gaussian
(analysis) pyramid GM of the mask, then the collapse ``S_k = LS_k + expand(S_{k+1})``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from fractions import Fraction
from functools import lru_cache

import numpy as np

from pyramid_cli.core import catalogue
from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.core.expr import Op, steps
from pyramid_cli.core.geometry import level_sizes, mip_levels, reduced
from pyramid_cli.core.options import MAX_SWEEPS, MAX_WEIGHT_SCALE
from pyramid_cli.core.parse import one_step
from pyramid_cli.plan.lower import Builder
from pyramid_cli.plan.model import Plan
from pyramid_cli.workflows.pyramids import run_steps

PULL_SCALE = 4           # the classic K: a coarse pixel covers 2×2 fine ones (Gortler's h̃ = [½ 1 ½]² sums to 4)
FILL_SCALE = catalogue.FILL_SCALE          # the default K and …
FILL_SWEEPS = catalogue.FILL_SWEEPS        # … smoothing sweeps, (level 1, coarser levels), by measurement
FILL_ANALYSIS = catalogue.FILL_ANALYSIS    # the biquadratic B-spline ⊗↓ (§4.3) and …
FILL_SYNTHESIS = catalogue.FILL_SYNTHESIS  # … the Doo-Sabin (biquadratic B-spline) ⊗↑, one lattice
SWEEP_FILTER = "bartlett"  # B of a sweep: the 3×3 binomial mask (§3.2)
HOLES = ("alpha", "mask", "nan")
OUTPUT_BAND = 1 << 18    # floats per band of rows fill_output writes at a time (a band stays in cache)


# ------------------------------------------------------------------ plans
@lru_cache(maxsize=32)  # batches re-use a plan per image size
def fill_plan(size: tuple[int, int], levels: int | None = None, analysis: str = FILL_ANALYSIS,
              synthesis: str = FILL_SYNTHESIS, premultiplied: bool = True, border: str = "clamp",
              strategy: str = "cost", scale: tuple[int, int] = FILL_SCALE,
              sweeps: tuple[int, int] = FILL_SWEEPS) -> Plan:
    """Pull-push as one job. Inputs: 0 the colours (premultiplied by the weights when
    ``premultiplied``, else multiplied in the plan), 1 the weights (the same channel count: every
    pass is per channel). Output: the filled colours ``c̄₀``.

    ``levels`` pull steps (default: down to 1×1, :func:`pyramid_cli.core.geometry.mip_levels`);
    ``scale`` the weight scale ``K`` of level 1 and of every coarser level; ``sweeps`` the smoothing
    sweeps at level 1 and at every coarser level but the coarsest.
    """
    scale, sweeps = fill_options(scale, sweeps)
    m = mip_levels(size) if levels is None else levels
    down = steps(one_step(analysis, Op.DOWN))
    up = steps(one_step(synthesis, Op.UP))
    smooth = steps(one_step(SWEEP_FILTER, Op.CONV))
    sizes = level_sizes(size, m)
    b = Builder(size, strategy, border)
    w = [b.add_input(size)]
    p = [0 if premultiplied else b.pointwise("mul", [0, w[0]], "p0 = c·w")]
    for k in range(m):
        big_w = run_steps(b, w[k], down)
        big_p = run_steps(b, p[k], down)
        kk = scale[min(k, 1)]
        w.append(b.pointwise("pull_weight", [big_w], f"w{k + 1} = min(1, {kk}·A(w{k}))", kk))
        p.append(b.pointwise("pull_colour", [big_p, big_w], f"p{k + 1} = A(p{k})·w{k + 1}/A(w{k})", kk))
    c = b.pointwise("divide", [p[m], w[m]], f"c{m} = p{m}/w{m}")
    for k in range(m - 1, -1, -1):
        expanded = run_steps(b, c, up, crop=sizes[k])
        c = b.pointwise("over", [p[k], w[k], expanded], f"c{k} = p{k} + (1 − w{k})·S(c{k + 1})")
        for i in range(sweeps[min(k, 2) - 1] if k > 0 else 0):
            c = b.pointwise("over", [p[k], w[k], run_steps(b, c, smooth)], f"c{k} = p{k} + (1 − w{k})·B(c{k}), "
                            f"sweep {i + 1}")
    return b.build(f"fill: pull-push, {m} level(s), {analysis} ⊗↓ / {synthesis} ⊗↑, K = {scale[0]}/{scale[1]}, "
                   f"sweeps {sweeps[0]}/{sweeps[1]}", outputs=[c])


def fill_options(scale: int | tuple[int, int], sweeps: int | tuple[int, int]) -> tuple[tuple[int, int], ...]:
    """The weight scales and sweep counts as (level 1, coarser levels) pairs (one number: both), checked.

    Raises
    ------
    UsageError
        A weight scale outside 1 … :data:`~pyramid_cli.core.options.MAX_WEIGHT_SCALE`, sweeps outside
        0 … :data:`~pyramid_cli.core.options.MAX_SWEEPS`, or more than two of either.
    """
    pairs = []
    for name, value, lo, hi in (("weight scale", scale, 1, MAX_WEIGHT_SCALE), ("sweeps", sweeps, 0, MAX_SWEEPS)):
        v = tuple(value) if isinstance(value, (tuple, list)) else (value, value)
        v = v * 2 if len(v) == 1 else v
        if len(v) != 2 or not all(isinstance(x, (int, np.integer)) and lo <= x <= hi for x in v):
            raise UsageError(f"the {name} must be one integer from {lo} to {hi}, or two (level 1, coarser levels), "
                             f"not {value!r}")
        first, coarser = (int(x) for x in v)
        pairs.append((first, coarser))
    return tuple(pairs)


@lru_cache(maxsize=32)
def blend_plan(size: tuple[int, int], levels: int, analysis: str = catalogue.DEFAULT_ANALYSIS,
               synthesis: str = catalogue.DEFAULT_SYNTHESIS, border: str = "clamp", strategy: str = "cost") -> Plan:
    """Multiresolution blending as one job. Inputs: 0 image A, 1 image B, 2 the mask (the same
    channel count). Output: the collapsed blend."""
    if levels < 0:
        raise UsageError("--levels must be at least 0")
    down = steps(one_step(analysis, Op.DOWN))
    up = steps(one_step(synthesis, Op.UP))
    sizes = level_sizes(size, levels)
    b = Builder(size, strategy, border)
    b_in, m_in = b.add_input(size), b.add_input(size)
    ga, gb, gm = [0], [b_in], [m_in]
    for _ in range(levels):
        ga.append(run_steps(b, ga[-1], down))
        gb.append(run_steps(b, gb[-1], down))
        gm.append(run_steps(b, gm[-1], down))
    bands = []
    for k in range(levels):
        la = b.combine([(ga[k], Fraction(1)), (run_steps(b, ga[k + 1], up, crop=sizes[k]), Fraction(-1))],
                       f"LA{k} = GA{k} − expand(GA{k + 1})")
        lb = b.combine([(gb[k], Fraction(1)), (run_steps(b, gb[k + 1], up, crop=sizes[k]), Fraction(-1))],
                       f"LB{k} = GB{k} − expand(GB{k + 1})")
        bands.append(b.pointwise("blend", [la, lb, gm[k]], f"LS{k} = GM{k}·LA{k} + (1 − GM{k})·LB{k}"))
    x = b.pointwise("blend", [ga[levels], gb[levels], gm[levels]], f"S{levels} = blend of GA{levels}, GB{levels}")
    for k in range(levels - 1, -1, -1):
        expanded = run_steps(b, x, up, crop=sizes[k])
        x = b.combine([(bands[k], Fraction(1)), (expanded, Fraction(1))], f"S{k} = LS{k} + expand(S{k + 1})")
    return b.build(f"blend: {levels} level(s), {analysis} ⊗↓ / {synthesis} ⊗↑", outputs=[x])


BLEND_COARSEST = 16  # the default blend stops before its coarsest level's shorter side drops below this


def blend_levels(size: tuple[int, int]) -> int:
    """The default ``--levels`` of a blend: as many as the size allows while the coarsest level keeps at
    least :data:`BLEND_COARSEST` pixels on its shorter side (at least one level where the image has two
    pixels). Deeper bands are wider than the image: their blend mixes the two images' mean colours across
    the whole frame (a tint far from the seam) instead of joining them along it."""
    n, short = 0, min(size)
    while short >= 2 * BLEND_COARSEST:
        short = reduced(short)
        n += 1
    return max(n, min(1, mip_levels(size)))


# ------------------------------------------------------------------ inputs and outputs
def fill_inputs(pixels: np.ndarray, holes: str = "alpha", mask: np.ndarray | None = None,
                alpha_channel: int | None = None, where: str = "", warn: Callable[[str], None] | None = None
                ) -> tuple[np.ndarray, np.ndarray, bool]:
    """(colours, weights, premultiplied) for :func:`fill_plan` from an image (H, W) or (H, W, C).

    ``holes``: ``"alpha"`` weights are the alpha channel (``alpha_channel``, default the last of
    2 or 4 channels; the colours are the other channels, already premultiplied); ``"mask"``
    weights are ``mask`` (one channel, or one per colour channel; :func:`mask_weights`);
    ``"nan"`` a pixel is known where all its channels are finite. Weights come back with the
    colours' channel count (every pass is per channel).

    Raises
    ------
    DataError
        No pixel has a positive weight (nothing to fill from), NaN/Inf in the mask or in a known pixel.
    UsageError
        No alpha channel, or a mask of another size or channel count.
    """
    prefix = f"{where}: " if where else ""
    a = np.asarray(pixels)
    a3 = a[:, :, None] if a.ndim == 2 else a
    if holes == "alpha":
        ch = alpha_channel if alpha_channel is not None else (a3.shape[2] - 1 if a3.shape[2] in (2, 4) else None)
        if ch is None or not 0 <= ch < a3.shape[2] or a3.shape[2] < 2:
            raise UsageError(f"{prefix}--holes alpha needs an alpha channel ({a3.shape[2]} channel(s)); "
                             "use --mask or --holes nan")
        # np.take, not a3[:, :, list]: the same copy, about 2.5× faster at 4K
        colour = np.ascontiguousarray(np.take(a3, [c for c in range(a3.shape[2]) if c != ch], axis=2),
                                      dtype=np.float32)
        weight = np.clip(a3[:, :, ch:ch + 1], 0, 1, dtype=np.float32)
        premultiplied = True
    elif holes == "mask":
        if mask is None:
            raise UsageError(f"{prefix}--holes mask needs a mask image")
        colour = np.ascontiguousarray(a3, dtype=np.float32)
        weight = mask_weights(mask, a3, where, warn, "the image is")
        premultiplied = False
        if not np.all(np.isfinite(colour[np.broadcast_to(weight > 0, colour.shape)])):
            raise DataError(f"{prefix}NaN/Inf in a known pixel; use --holes nan to treat them as holes")
    elif holes == "nan":
        known = np.all(np.isfinite(a3), axis=2, keepdims=True)
        colour = np.where(known, a3, np.float32(0)).astype(np.float32)
        weight = known.astype(np.float32)
        premultiplied = True
    else:
        raise UsageError(f"holes must be one of {', '.join(HOLES)}, not {holes!r}")
    if not np.any(weight > 0):
        raise DataError(f"{prefix}no known pixel to fill from (every weight is 0)")
    if weight.shape[2] != colour.shape[2]:  # every pass is per channel: one weight per colour channel
        weight = np.repeat(weight, colour.shape[2], axis=2)
    return colour, np.ascontiguousarray(weight, dtype=np.float32), premultiplied


def fill_output(filled: np.ndarray, pixels: np.ndarray, holes: str = "alpha",
                alpha_channel: int | None = None, keep_alpha: bool = False) -> np.ndarray:
    """The filled colours in the input's layout: an alpha channel (``holes`` alpha) is put back as 1
    (opaque, as ``oiiotool --fillholes`` writes it), or with ``keep_alpha`` as the input's alpha beside
    the filled straight (unassociated) colours; a 2-D input comes back 2-D."""
    a = np.asarray(pixels)
    f3 = filled[:, :, None] if filled.ndim == 2 else filled
    if holes == "alpha":
        channels = a.shape[2]
        ch = alpha_channel if alpha_channel is not None else channels - 1
        out: np.ndarray = np.empty(f3.shape[:2] + (channels,), dtype=np.float32)
        colours = [c for c in range(channels) if c != ch]
        rows = max(1, OUTPUT_BAND // max(1, out.shape[1] * channels))
        for r in range(0, out.shape[0], rows):  # in bands: each band's colours and alpha written while cached
            out[r:r + rows, :, colours] = f3[r:r + rows]
            out[r:r + rows, :, ch] = a[r:r + rows, :, ch] if keep_alpha else 1
        return out
    return f3[:, :, 0] if a.ndim == 2 else f3


def mask_weights(mask: np.ndarray, image: np.ndarray, where: str = "", warn: Callable[[str], None] | None = None,
                 image_is: str = "the image is", nan_hint: str = "numpy.nan_to_num(mask) reads them as 0"
                 ) -> np.ndarray:
    """A mask as weights for ``image``: float32 H×W×1 or H×W×C (one channel, or one per channel of the image).

    NaN/Inf are kept, as in an image under ``--nan keep``, and spread through the filter: ``warn``
    (default :func:`warnings.warn`) says how many, with ``nan_hint`` (the CLI's: ``--nan zero`` or
    ``--nan fail``). Values outside [0, 1] (a matte's filter overshoot, say) are clipped, and ``warn`` is
    told how many and their range. ``where`` (the mask's path) starts every message.

    Raises
    ------
    UsageError
        Another size, or a channel count that is neither one nor the image's (naming both).
    """
    prefix = f"{where}: " if where else ""
    say = warn or (lambda text: warnings.warn(text, UserWarning, stacklevel=3))
    m = np.asarray(mask, dtype=np.float32)
    m = m[:, :, None] if m.ndim == 2 else m
    a = image[:, :, None] if image.ndim == 2 else image
    if m.shape[:2] != a.shape[:2] or m.shape[2] not in (1, a.shape[2]):
        raise UsageError(f"{prefix}the mask is {m.shape[1]}x{m.shape[0]} with {m.shape[2]} channel(s); {image_is} "
                         f"{a.shape[1]}x{a.shape[0]} with {a.shape[2]}: one channel or one per channel")
    bad = int(m.size - np.count_nonzero(np.isfinite(m)))
    if bad:
        say(f"{prefix}{bad} NaN/Inf value(s) kept in the mask; they spread through the filter ({nan_hint})")
    outside = int(np.count_nonzero((m < 0) | (m > 1)))
    if outside:
        say(f"{prefix}{outside} mask value(s) outside [0, 1] (from {float(np.nanmin(m)):g} to "
            f"{float(np.nanmax(m)):g}) clipped to [0, 1]")
        m = np.clip(m, 0, 1)
    return np.ascontiguousarray(m, dtype=np.float32)


def mask_channels(mask: np.ndarray, image: np.ndarray, where: str = "",
                  warn: Callable[[str], None] | None = None, nan_hint: str | None = None) -> np.ndarray:
    """The blend mask with the image's channel count (one channel is repeated), as float32 in [0, 1]
    (:func:`mask_weights`: NaN/Inf kept with a warning, values outside [0, 1] clipped with one)."""
    a = image[:, :, None] if image.ndim == 2 else image
    m = mask_weights(mask, a, where, warn, "the images are", *([nan_hint] if nan_hint else []))
    m = np.ascontiguousarray(np.broadcast_to(m, a.shape), dtype=np.float32)
    return m[:, :, 0] if image.ndim == 2 else m


__all__ = ["fill_plan", "blend_plan", "blend_levels", "fill_inputs", "fill_output", "mask_weights", "mask_channels",
           "fill_options", "PULL_SCALE", "FILL_SCALE", "FILL_SWEEPS", "FILL_ANALYSIS", "FILL_SYNTHESIS",
           "SWEEP_FILTER", "HOLES", "BLEND_COARSEST"]
