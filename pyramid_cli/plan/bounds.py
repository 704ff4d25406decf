"""Bounds inference: the guard band each intermediate of a named filter stores (docs/design.md §1, after Halide).

A named filter is atomic: its decomposition must give the reference's numbers at
the borders too, so every intermediate stores every pixel later passes of the same
filter read, and only the filter's input (a boundary) is read through the border mode.
"""

from __future__ import annotations

from pyramid_cli.plan.model import Image, Pass, needed


def infer_guards(images: list[Image], passes: list[Pass], first: int) -> None:
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
