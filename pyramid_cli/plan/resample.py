"""Resampling weights for MIP levels that are not exactly half the level above (docs/design.md §5).

A texture lookup stretches every MIP level over the same domain [0, 1]: texel ``j`` of a
level of ``m`` texels sits at ``(j + ½)/m``, and covers ``[j/m, (j+1)/m)``. Where a level
halves exactly (``n = 2m``) the paper's analysis filter ⊗↓ (§4) maps level k onto level
k+1 and is kept. Where it does not (``n`` odd, maketx's sizes ``m = ⌊n/2⌋``), the weights
come from the *same* filter's continuous kernel, stretched to the actual ratio.

Derivation (one axis; the filters of the catalogue are separable):

1. The analysis step's 1-D weights ``w_d`` (``f[r] = Σ_d w_d · g[2r − d]``, 1-based) read
   fine pixel ``2r − d``, whose centre lies ``½ − d`` fine pixels from the coarse pixel's
   centre ``2r − 1`` (edges at integers, the lookup's convention). Spread each weight
   uniformly over that fine pixel: the filter's continuous kernel, in coarse-pixel units
   ``u``, is the step function ``K(u) = 2·w_d`` on ``[−d/2, (1 − d)/2)``. It integrates to
   Σ w_d, and it is the filter's own kernel seen with pixels as areas: box gives the box
   B-spline (area resampling), box4 a box twice as wide, quadratic the tent's staircase.
2. At the ratio ``s = n/m`` (input pixels per output pixel), output ``j`` is centred at
   ``c_j = (j + ½)·s`` (input units) and input pixel ``i`` covers ``[i, i + 1)``, i.e.
   ``u ∈ [(i − c_j)/s, (i + 1 − c_j)/s)``. Its weight is the kernel's integral there:
   ``W[j, i] = ∫ K``. Every weight is rational, computed exactly.
3. At ``s = 2`` the interval of input pixel ``i = 2j + 1 − d`` (0-based, i.e. ``2r − d``)
   is exactly ``[−d/2, (1 − d)/2)``: ``W[j, 2j + 1 − d] = w_d``, the paper's weights
   (tested as Fractions). The lattice is the filter's own: cubic (primal lattice, docs/design.md
   §4) keeps its quarter-output-pixel offset at any ratio.
4. Mean: ``Σ_j W[j, i] = (1/s)·∫_i Σ_j K(u − j)`` over input pixel i. When the even- and
   odd-indexed weights each sum to ½ (every filter of the catalogue) the kernel's unit-spaced
   copies add up to 1 everywhere, so every column of W sums to ``m/n`` and resampling keeps
   the mean, for pixels whose reads stay inside the image. Past the edges the border mode
   decides (:func:`column_sums`): ``wrap`` folds the kernel periodically and ``mirror`` by
   reflection (the lattice of output centres is symmetric under both), so every column
   still sums to ``m/n`` (for mirror: a symmetric kernel); ``clamp`` adds what falls past
   the edge to the edge pixel; ``zero`` drops it (each row then sums to less than 1). So MIP
   levels are built with the mirror fold when lookups clamp or read black
   (:func:`pyramid_cli.workflows.pyramids.level_border`; docs/design.md, "MIP levels inside the domain").
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

from pyramid_cli.core.border import Border, fold_index

Weights1D = tuple[tuple[int, Fraction], ...]  # ((d, w_d), ...) of one axis, f[r] = Σ w_d g[2r − d]


def _pieces(weights: Weights1D) -> list[tuple[Fraction, Fraction, Fraction]]:
    """The continuous kernel as (start, end, density) pieces in coarse-pixel units (docstring step 1)."""
    return [(Fraction(-d, 2), Fraction(1 - d, 2), 2 * Fraction(w)) for d, w in weights if w]


@lru_cache(maxsize=256)
def axis_table(weights: Weights1D, n_in: int, n_out: int) -> tuple[tuple[int, ...], tuple[tuple[Fraction, ...], ...]]:
    """Exact weights resampling ``n_in`` samples to ``n_out`` with the kernel of ``weights``.

    Returns ``(starts, table)``: output ``j`` (0-based) is ``Σₖ table[j][k] · src[starts[j] + k]``,
    source indices possibly outside ``0..n_in−1`` (the border mode folds them). Rows have one width.
    """
    s = Fraction(n_in, n_out)
    pieces = _pieces(weights)
    rows: list[tuple[int, list[Fraction]]] = []
    for j in range(n_out):
        c = (j + Fraction(1, 2)) * s
        acc: dict[int, Fraction] = {}
        for a, b, density in pieces:
            lo, hi = c + a * s, c + b * s  # the piece in input units
            for i in range(lo.__floor__(), hi.__ceil__()):
                overlap = min(hi, Fraction(i + 1)) - max(lo, Fraction(i))
                if overlap > 0:
                    acc[i] = acc.get(i, Fraction(0)) + density * overlap / s
        first, last = min(acc), max(acc)
        rows.append((first, [acc.get(i, Fraction(0)) for i in range(first, last + 1)]))
    width = max(len(w) for _, w in rows)
    return (tuple(start for start, _ in rows),
            tuple(tuple(w + [Fraction(0)] * (width - len(w))) for _, w in rows))


@lru_cache(maxsize=64)
def bilinear_table(n_in: int, n_out: int) -> tuple[tuple[int, ...], tuple[tuple[Fraction, ...], ...]]:
    """Weights that resample ``n_in`` samples to ``n_out`` as a bilinear texture lookup reads them.

    Output ``j``'s centre lies at the input index ``x = (j + ½)·n_in/n_out − ½`` (texel centres on the
    lookup's lattice); it mixes ``src[⌊x⌋]`` and ``src[⌊x⌋ + 1]`` by the fraction of ``x`` (reads past the
    edges fold by the border). maketx's ``--resize`` (up to powers of two) uses it: the resized level 0 is
    what a bilinear lookup of the source returns at the new texel centres. Same layout as :func:`axis_table`.
    """
    starts, rows = [], []
    for j in range(n_out):
        x = (j + Fraction(1, 2)) * Fraction(n_in, n_out) - Fraction(1, 2)
        i = x.__floor__()
        starts.append(i)
        rows.append((1 - (x - i), x - i))
    return tuple(starts), tuple(rows)


def ceil2(n: int) -> int:
    """The next power of two at or above ``n`` (maketx's ``--resize``)."""
    return 1 << max(0, n - 1).bit_length()


def dense(starts, table, n_in: int, border: str) -> list[list[Fraction]]:
    """The (n_out, n_in) matrix of a table with reads folded by ``border`` (zero: dropped)."""
    mode = Border.parse(border)
    out = [[Fraction(0)] * n_in for _ in starts]
    for j, (start, row) in enumerate(zip(starts, table, strict=True)):
        for k, w in enumerate(row):
            i = fold_index(start + k + 1, n_in, mode)
            if i:
                out[j][i - 1] += w
    return out


def column_sums(weights: Weights1D, n_in: int, n_out: int, border: str) -> list[Fraction]:
    """Σ_j W[j, i] for every input pixel i after folding by ``border`` (docstring step 4)."""
    m = dense(*axis_table(weights, n_in, n_out), n_in, border)
    return [sum((row[i] for row in m), Fraction(0)) for i in range(n_in)]


__all__ = ["axis_table", "bilinear_table", "ceil2", "dense", "column_sums", "Weights1D"]
