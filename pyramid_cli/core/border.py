"""Border modes and their one name table (docs/design.md §1: clamp is the default).

Each mode maps a 1-based index, possibly outside ``1..n``, to a 1-based index
inside, or to ``0`` meaning "zero outside" (the convention for masks treated as
images).
"""

from __future__ import annotations

from enum import Enum


class Border(Enum):
    CLAMP = "clamp"     # GL CLAMP_TO_EDGE, Halide repeat_edge
    MIRROR = "mirror"   # GL MIRRORED_REPEAT, Halide mirror_image: 1 2 3 | 3 2 1
    WRAP = "wrap"       # GL REPEAT, Halide repeat_image
    ZERO = "zero"       # GL CLAMP_TO_BORDER with 0, Halide constant_exterior

    @classmethod
    def parse(cls, name: str) -> Border:
        return cls(name.lower())


BORDER_NAMES = [b.value for b in Border]


def fold_index(i: int, n: int, border: Border) -> int:
    """One 1-based index folded into ``1..n``; 0 means "outside, reads zero"."""
    if border is Border.CLAMP:
        return min(max(i, 1), n)
    if border is Border.WRAP:
        return (i - 1) % n + 1
    if border is Border.MIRROR:
        k = (i - 1) % (2 * n)
        return (k if k < n else 2 * n - 1 - k) + 1
    return i if 1 <= i <= n else 0


def fold(index, n: int, border: Border):
    """:func:`fold_index` for a numpy array of 1-based indices."""
    import numpy as np

    index = np.asarray(index, dtype=np.int64)
    if border is Border.CLAMP:
        return np.clip(index, 1, n)
    if border is Border.WRAP:
        return (index - 1) % n + 1
    if border is Border.MIRROR:
        k = (index - 1) % (2 * n)
        return np.where(k < n, k, 2 * n - 1 - k) + 1
    return np.where((index >= 1) & (index <= n), index, 0)
