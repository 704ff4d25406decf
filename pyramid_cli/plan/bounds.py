"""Bounds inference: the guard band each intermediate of a named filter stores (DESIGN.md §1, after Halide).

A named filter is atomic: its decomposition must give the reference's numbers at
the borders too, so every intermediate stores every pixel later passes of the same
filter read, and only the filter's input (a boundary) is read through the border mode.
"""

from __future__ import annotations

from fractions import Fraction

from pyramid_cli.core.geometry import base_index
from pyramid_cli.plan.model import Image, Pass


def needed(stage_pass: Pass, rows: tuple[int, int], cols: tuple[int, int], src: int):
    """Source index ranges (1-based, inclusive) read by ``rows × cols`` (1-based, inclusive) of a pass, for one
    source; empty (lo > hi) where no phase present in the rectangle reads it."""
    lo_r = lo_c = 10 ** 9
    hi_r = hi_c = -10 ** 9
    (pr, pc), (sr, sc) = stage_pass.period, stage_pass.stride
    for (phr, phc), taps in stage_pass.phases.items():
        rs = [r for r in _ends(rows, pr) if r % pr == phr]
        cs = [c for c in _ends(cols, pc) if c % pc == phc]
        for t in taps:
            if t.source != src:
                continue
            for r in rs:
                base = base_index(r, pr, sr) - t.offset[0]
                lo_r, hi_r = min(lo_r, _floor(base)), max(hi_r, _ceil(base))
            for c in cs:
                base = base_index(c, pc, sc) - t.offset[1]
                lo_c, hi_c = min(lo_c, _floor(base)), max(hi_c, _ceil(base))
    return (lo_r, hi_r), (lo_c, hi_c)


def _ends(span: tuple[int, int], p: int) -> list[int]:
    lo, hi = span
    return sorted(set(range(lo, min(hi, lo + p - 1) + 1)) | set(range(max(lo, hi - p + 1), hi + 1)))


def _floor(x) -> int:
    return int(Fraction(x).__floor__())


def _ceil(x) -> int:
    return int(Fraction(x).__ceil__())


def _infer_guards(images: list[Image], passes: list[Pass], first: int) -> None:
    """Walk a named filter's passes backwards: each intermediate stores what later passes read."""
    for p in reversed(passes):
        img = images[p.target]
        t, l, b, r = img.guard
        rows, cols = (1 - t, img.size[0] + b), (1 - l, img.size[1] + r)
        for src in p.sources():
            if src < first:
                continue  # the filter's input: a boundary, read clamped
            (lo_r, hi_r), (lo_c, hi_c) = needed(p, rows, cols, src)
            s = images[src]
            s.guard = [max(s.guard[0], 1 - lo_r), max(s.guard[1], 1 - lo_c),
                       max(s.guard[2], hi_r - s.size[0]), max(s.guard[3], hi_c - s.size[1])]
            s.guard = [max(0, g) for g in s.guard]
