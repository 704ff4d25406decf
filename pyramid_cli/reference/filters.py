"""The oracle: the paper's index formulas in numpy, float64, written literally.

docs/design.md §1. For a mask ``h`` of ``n_i × n_j`` entries (1-based ``i, j``):

- ⊗  (§3):   ``f[r,c] = Σ h[i,j] g[r − ⌊i − n_i/2⌋, c − ⌊j − n_j/2⌋]``, size n;
- ⊗↓ᵐ (§4): ``f[r,c] = Σ h[i,j] g[2ᵐr − ⌊i − n_i/2⌋, 2ᵐc − …]``, size ⌈n/2ᵐ⌉;
- ⊗↑ (§5):  ``f[r,c] = Σ h^{r mod 2, c mod 2}[i,j] g[⌊(r+1)/2⌋ − ⌊i − n_i/2⌋, …]``, size 2n.

Indices of ``g`` outside ``1..n`` go through the border mode (clamp by default).
Every written operator reads the clamped result of the one before it (a
written operator is a boundary); a named filter is applied whole, with its
printed mask (atomic). This module deliberately imports neither ``algebra``
nor ``plan``, so that it can catch their mistakes. It is slow on purpose.
"""

from __future__ import annotations

from math import floor

import numpy as np

from pyramid_cli.core.border import Border, fold
from pyramid_cli.core.catalogue import Matrix
from pyramid_cli.core.expr import Apply, Expr, Input, Op, resolve_mask, resolve_phases


def _offset(i: int, n: int) -> int:
    """⌊i − n/2⌋ for the paper's 1-based mask index ``i``."""
    return floor(i - n / 2)


def _gather(g: np.ndarray, rows: np.ndarray, cols: np.ndarray, border: Border) -> np.ndarray:
    """``g[rows, cols]`` for 1-based index vectors, through the border mode."""
    nr, nc = g.shape[:2]
    fr, fc = fold(rows, nr, border), fold(cols, nc, border)
    # Index 0 means "zero outside": pad g with a zero row and column in front.
    padded = np.zeros((nr + 1, nc + 1) + g.shape[2:], dtype=g.dtype)
    padded[1:, 1:] = g
    return padded[fr[:, None], fc[None, :]]


def _weighted_sum(h: Matrix, g: np.ndarray, base_r: np.ndarray, base_c: np.ndarray,
                  border: Border) -> np.ndarray:
    """Σ_ij h[i,j] g[base_r − ⌊i − n_i/2⌋, base_c − ⌊j − n_j/2⌋]."""
    ni, nj = len(h), len(h[0])
    f = np.zeros((len(base_r), len(base_c)) + g.shape[2:], dtype=np.float64)
    for i in range(1, ni + 1):
        for j in range(1, nj + 1):
            w = h[i - 1][j - 1]
            if w:
                f += float(w) * _gather(g, base_r - _offset(i, ni), base_c - _offset(j, nj), border)
    return f


def convolve(h: Matrix, g: np.ndarray, border: Border = Border.CLAMP) -> np.ndarray:
    """``h ⊗ g`` (§3)."""
    r = np.arange(1, g.shape[0] + 1)
    c = np.arange(1, g.shape[1] + 1)
    return _weighted_sum(h, g, r, c, border)


def analyse(h: Matrix, g: np.ndarray, m: int = 1, border: Border = Border.CLAMP) -> np.ndarray:
    """``h ⊗↓ᵐ g`` (§4): one step of stride 2ᵐ, output ⌈n/2ᵐ⌉ per axis."""
    s = 2 ** m
    r = np.arange(1, -(-g.shape[0] // s) + 1)
    c = np.arange(1, -(-g.shape[1] // s) + 1)
    return _weighted_sum(h, g, s * r, s * c, border)


def synthesise(phases: dict[tuple[int, int], Matrix], g: np.ndarray,
               border: Border = Border.CLAMP) -> np.ndarray:
    """``h ⊗↑ g`` (§5): four phase masks keyed by (r mod 2, c mod 2), output 2n."""
    nr, nc = 2 * g.shape[0], 2 * g.shape[1]
    f = np.zeros((nr, nc) + g.shape[2:], dtype=np.float64)
    for pr in (0, 1):
        for pc in (0, 1):
            r = np.arange(1, nr + 1)
            c = np.arange(1, nc + 1)
            r, c = r[r % 2 == pr], c[c % 2 == pc]
            part = _weighted_sum(phases[(pr, pc)], g, (r + 1) // 2, (c + 1) // 2, border)
            f[np.ix_(r - 1, c - 1)] = part
    return f


def run(expr: Expr, g: np.ndarray, border: Border = Border.CLAMP) -> np.ndarray:
    """Evaluate ``expr`` on image ``g`` (H, W) or (H, W, C), in float64."""
    if isinstance(expr, Input):
        return np.asarray(g, dtype=np.float64)
    assert isinstance(expr, Apply)
    x = run(expr.arg, g, border)
    for _ in range(expr.power):
        if expr.op is Op.CONV:
            x = convolve(resolve_mask(expr.filter), x, border)
        elif expr.op is Op.DOWN:
            x = analyse(resolve_mask(expr.filter), x, expr.stride, border)
        else:
            x = synthesise(resolve_phases(expr.filter), x, border)
    return x
