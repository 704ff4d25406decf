"""The float64 oracle of domain-true MIP levels (maketx's sizes ``max(1, ⌊n/2⌋)``).

Every level covers the whole texture domain: it is resampled from the level above by the analysis
filter's continuous kernel, integrated in float64 from the paper's index formula and the mask's row
sums (at an exact halving that is the filter itself). Independent of the planner's exact tables
(:mod:`pyramid_cli.plan.resample`) that the executors run.
"""

from __future__ import annotations

import numpy as np

from pyramid_cli.core import catalogue
from pyramid_cli.core.border import Border, fold
from pyramid_cli.core.geometry import mip_sizes


def kernel_1d(analysis: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(offsets d, weights w_d) of a named analysis mask, f[r] = Σ w_d g[2r − d], straight from the paper's
    index formula ``d = ⌊i − n/2⌋`` (1-based i) and the mask's row sums; None for expressions."""
    if analysis not in catalogue.ANALYSIS_FILTERS:
        return None
    mask = np.array([[float(v) for v in row] for row in catalogue.mask(analysis).mask])
    n = mask.shape[0]
    return np.floor(np.arange(1, n + 1) - n / 2).astype(int), mask.sum(axis=1)


def resample_matrix(d: np.ndarray, w: np.ndarray, n_in: int, n_out: int, border: str) -> np.ndarray:
    """(n_out, n_in) float64 matrix resampling an axis with the continuous kernel of the weights ``w_d``.

    Independent of the planner's exact tables (:mod:`pyramid_cli.plan.resample`, whose docstring
    derives the kernel): here the kernel's integral ``F(u)`` is a piecewise-linear function through its
    breakpoints, and each texel's weight is ``F`` at the end of its footprint minus ``F`` at its start,
    ``u = (x − (j + ½)·s)/s`` for input position x and ``s = n_in/n_out``; reads past the edges fold by
    ``border`` into the matrix's columns (zero drops them).
    """
    if n_in == n_out == 1:
        return np.ones((1, 1))
    dd = np.arange(d.max(), d.min() - 1, -1)  # every offset, the kernel's pieces left to right
    wd = np.array([w[d == k].sum() for k in dd])
    lo = -dd / 2.0  # piece of weight w_d: [−d/2, (1 − d)/2) in output units, density 2·w_d
    xs = np.concatenate([lo, [lo[-1] + 0.5]])
    cum = np.concatenate([[0.0], np.cumsum(wd)])
    s = n_in / n_out
    reach = int(np.ceil(np.abs(xs).max() * s)) + 2
    i = np.arange(-reach, n_in + reach)
    c = (np.arange(n_out)[:, None] + 0.5) * s
    ext = np.interp((i[None, :] + 1 - c) / s, xs, cum) - np.interp((i[None, :] - c) / s, xs, cum)
    cols = fold(i + 1, n_in, Border.parse(border))
    out = np.zeros((n_out, n_in + 1))
    np.add.at(out.T, cols, ext.T)  # folded column 0 means "outside, reads zero"
    return out[:, 1:]


def bilinear_matrix(n_in: int, n_out: int, border: str) -> np.ndarray:
    """(n_out, n_in) float64 matrix of a bilinear lookup at the texel centres of ``n_out`` samples spread over
    the same domain (independent of :func:`pyramid_cli.plan.resample.bilinear_table`); reads fold by ``border``."""
    x = (np.arange(n_out) + 0.5) * n_in / n_out - 0.5
    i0 = np.floor(x).astype(int)
    out = np.zeros((n_out, n_in + 1))
    for i, w in ((i0, 1 - (x - i0)), (i0 + 1, x - i0)):
        np.add.at(out, (np.arange(n_out), fold(i + 1, n_in, Border.parse(border))), w)
    return out[:, 1:]


# How a level is built for each lookup border: inside the texture's domain (clamp and zero fold the kernel back
# by reflection, which keeps the mean); written here again, apart from the planner's table, for the oracle.
DOMAIN = {"clamp": "mirror", "zero": "mirror", "wrap": "wrap", "mirror": "mirror"}


def mip_reference(pixels: np.ndarray, analysis: str, border: str = "clamp", resize: bool = False,
                  axis_weights=None) -> list[np.ndarray]:
    """Levels 0..1×1 with maketx's sizes, every level resampled from the one above by ``analysis``'s
    continuous kernel (at exact halvings that is the filter itself), in float64; with ``resize``, level 0
    is first resampled up to powers of two by a bilinear lookup.

    ``border`` is the lookup's (the file's ``wrapmodes``); the levels are built inside the texture's domain
    by :data:`DOMAIN`: reads past the edges under ``clamp`` and ``zero`` fold back by reflection, so every
    row of :func:`resample_matrix` sums to 1 and every column to m/n, and each level's mean is level 0's.

    ``analysis`` names a filter of the catalogue, whose 1-D weights come from its mask (:func:`kernel_1d`);
    for an expression, ``axis_weights`` gives its separated row weights ``((d, w_d), …)`` (the planner's
    ``mip_axis_weights``: no other source exists, and the oracle does not import the algebra).
    """
    kern = kernel_1d(analysis)
    if kern is None:
        if axis_weights is None:
            raise ValueError(f"{analysis!r} is not a named analysis filter: pass its axis_weights")
        kern = (np.array([d for d, _ in axis_weights]), np.array([float(v) for _, v in axis_weights]))
    x = np.asarray(pixels, dtype=np.float64)
    border = DOMAIN[border]
    if resize:
        h, w = (1 << max(0, n - 1).bit_length() for n in x.shape[:2])
        x = np.einsum("ji,ik...->jk...", bilinear_matrix(x.shape[0], h, border), x, optimize=True)
        x = np.einsum("lk,jk...->jl...", bilinear_matrix(x.shape[1], w, border), x, optimize=True)
    levels = [x]
    for h, w in mip_sizes(x.shape[:2])[1:]:
        a = resample_matrix(*kern, x.shape[0], h, border)
        b = resample_matrix(*kern, x.shape[1], w, border)
        x = np.einsum("ji,ik...->jk...", a, x, optimize=True)
        x = np.einsum("lk,jk...->jl...", b, x, optimize=True)
        levels.append(x)
    return levels


__all__ = ["DOMAIN", "kernel_1d", "resample_matrix", "bilinear_matrix", "mip_reference"]
