"""Independent checkers used by the tests: written from the paper's formulas, not from the code under test."""

from __future__ import annotations

from fractions import Fraction
from math import floor

import numpy as np


def offset(i: int, n: int) -> int:
    """⌊i − n/2⌋ for a 1-based mask index (paper §3)."""
    return floor(i - n / 2)


def printed(matrix_rows, scale) -> dict[tuple[int, int], Fraction]:
    """A matrix as printed in the paper -> {(dr, dc): weight} by the paper's index formula."""
    ni, nj = len(matrix_rows), len(matrix_rows[0])
    out = {}
    for i in range(1, ni + 1):
        for j in range(1, nj + 1):
            v = Fraction(matrix_rows[i - 1][j - 1]) * Fraction(scale)
            if v:
                out[(offset(i, ni), offset(j, nj))] = v
    return out


def printed_outer(vector, scale) -> dict[tuple[int, int], Fraction]:
    """The paper's separable ``s[v]ᵀ · s[v]`` form."""
    return printed([[a * b for b in vector] for a in vector], Fraction(scale) ** 2)


def apply_kernel(k, g: np.ndarray, out_shape: tuple[int, int]) -> np.ndarray:
    """Apply an algebra.Kernel with clamped input indices (1-based formula R = S·⌈r/P⌉)."""
    (pr, pc), (sr, sc) = k.period, k.stride
    h, w = g.shape[:2]
    out = np.zeros(out_shape + g.shape[2:])
    for r in range(1, out_shape[0] + 1):
        for c in range(1, out_shape[1] + 1):
            R, C = sr * -(-r // pr), sc * -(-c // pc)
            for (dr, dc), v in k.phases[(r % pr, c % pc)].items():
                rr = min(max(R - dr, 1), h)
                cc = min(max(C - dc, 1), w)
                out[r - 1, c - 1] += float(v) * g[rr - 1, cc - 1]
    return out


def extended_chain(step_list, g: np.ndarray, out_shape: tuple[int, int]) -> np.ndarray:
    """Run a chain of ``algebra.Step`` s where every intermediate is computed wherever the
    next step reads it (guard rows included), and only the original input clamps.

    This is the border meaning of an atomic named filter decomposed into steps
    (docs/design.md §1): the test oracle for the paper's decompositions at the borders.
    """
    h, w = g.shape[:2]
    cache: list[dict] = [dict() for _ in step_list]

    def value(level: int, r: int, c: int):
        if level == 0:
            return g[min(max(r, 1), h) - 1, min(max(c, 1), w) - 1]
        memo = cache[level - 1]
        if (r, c) not in memo:
            memo[(r, c)] = sum(float(v) * value(level - 1, ir, ic)
                               for (ir, ic), v in step_list[level - 1].reads(r, c))
        return memo[(r, c)]

    out = np.zeros(out_shape + g.shape[2:])
    for r in range(1, out_shape[0] + 1):
        for c in range(1, out_shape[1] + 1):
            out[r - 1, c - 1] = value(len(step_list), r, c)
    return out


def paper_weights(key: str) -> dict[int, Fraction]:
    """1-D weights of a named analysis mask straight from the paper's formula f[r] = Σ h[i] g[2r − ⌊i − n/2⌋]:
    {d: w_d}, with d = ⌊i − n/2⌋ for the 1-based mask index i; the mask's row sums (all masks are separable)."""
    from pyramid_cli.core import catalogue

    mask = catalogue.mask(key).mask
    n = len(mask)
    weights = {floor(i - n / 2): sum(mask[i - 1], Fraction(0)) for i in range(1, n + 1)}
    return {d: w for d, w in weights.items() if w}


def as_1d(key: str):
    """:func:`paper_weights` as a sorted tuple of (offset, weight)."""
    return tuple(sorted(paper_weights(key).items()))


def reference_blur(g, levels, analysis, synthesis, quasi=False):
    """m reference analysis steps, then m synthesis steps, each cropped to the level's size (written here,
    independently of the library's blur reference, which tests/reference/test_pyramids.py checks against it)."""
    from pyramid_cli.core.geometry import level_sizes
    from pyramid_cli.core.parse import parse
    from pyramid_cli.reference import filters as reference

    sizes = level_sizes(g.shape[:2], levels)
    x = g
    for _ in range(levels):
        x = reference.run(parse(f"{analysis} *v g"), x)
    if quasi:
        x = reference.run(parse("quasi * g"), x)
    for k in range(levels, 0, -1):
        x = reference.run(parse(f"{synthesis} *^ g"), x)[:sizes[k - 1][0], :sizes[k - 1][1]]
    return x
