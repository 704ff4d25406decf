"""Tap fitting: a stage's weights as the fewest bilinear fetches at quarter-texel positions (docs/design.md §5)."""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

from pyramid_cli.core.algebra import Weights
from pyramid_cli.plan.model import Tap

_QUARTERS = {Fraction(0), Fraction(1, 4), Fraction(1, 2), Fraction(3, 4)}


def _bilinear_fit(block: list[list[Fraction]]) -> tuple[Fraction, Fraction] | None:
    """Fractions (a, b) such that a 2×2 block is W·[(1−a)(1−b), (1−a)b; a(1−b), ab], quarter steps only."""
    w = sum(sum(row) for row in block)
    if not w:
        return None
    signs = {v > 0 for row in block for v in row if v}
    if len(signs) > 1:
        return None
    a = (block[1][0] + block[1][1]) / w
    b = (block[0][1] + block[1][1]) / w
    if a not in _QUARTERS and a != 1 or b not in _QUARTERS and b != 1:
        return None
    for i in range(2):
        for j in range(2):
            if block[i][j] != w * (a if i else 1 - a) * (b if j else 1 - b):
                return None
    return a, b


def taps_for(weights: Weights, source: int) -> list[Tap]:
    """Fewest taps found greedily: 2×2 and 1×2 bilinear footprints at quarter positions, else nearest."""
    return [Tap(source, offset, w, linear) for offset, w, linear in _fit(tuple(sorted(weights.items())))]


@lru_cache(maxsize=1024)  # a plan asks for the same few masks again and again (a 5-level blur: 25 fits, 5 masks)
def _fit(items: tuple) -> tuple[tuple[tuple[Fraction, Fraction], Fraction, bool], ...]:
    """:func:`taps_for`'s taps of the weights ``items`` (sorted (offset, weight) pairs) as (offset, weight, linear)."""
    left = dict(items)
    out: list[tuple[tuple[Fraction, Fraction], Fraction, bool]] = []
    while left:
        # Largest footprint first: try every placement covering the smallest remaining offset.
        d0 = min(left)
        best = None
        for (oi, oj) in ((0, 0), (0, -1), (-1, 0), (-1, -1)):
            top = (d0[0] + oi, d0[1] + oj)
            block = [[left.get((top[0] + i, top[1] + j), Fraction(0)) for j in range(2)] for i in range(2)]
            covered = sum(1 for row in block for v in row if v)
            fit = _bilinear_fit(block)
            if fit and (best is None or covered > best[0]):
                best = (covered, top, fit, sum((v for row in block for v in row), Fraction(0)))
        if best is None or best[0] == 1:
            v = left.pop(d0)
            out.append(((Fraction(d0[0]), Fraction(d0[1])), v, False))
            continue
        _, top, (a, b), w = best
        for i in range(2):
            for j in range(2):
                left.pop((top[0] + i, top[1] + j), None)
        offset = (top[0] + a, top[1] + b)
        out.append((offset, w, bool(a % 1 or b % 1)))
    return tuple(out)
