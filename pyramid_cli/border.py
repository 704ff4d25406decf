"""Border modes and their one name table (DESIGN.md §1: clamp is the default).

Each mode maps a 1-based index, possibly outside ``1..n``, to a 1-based index
inside, or to ``0`` meaning "zero outside" (the convention for masks treated as
images).
"""

from __future__ import annotations

from enum import Enum

import numpy as np


class Border(Enum):
    CLAMP = "clamp"     # GL CLAMP_TO_EDGE, Halide repeat_edge
    MIRROR = "mirror"   # GL MIRRORED_REPEAT, Halide mirror_image: 1 2 3 | 3 2 1
    WRAP = "wrap"       # GL REPEAT, Halide repeat_image
    ZERO = "zero"       # GL CLAMP_TO_BORDER with 0, Halide constant_exterior

    @classmethod
    def parse(cls, name: str) -> Border:
        return cls(name.lower())


BORDER_NAMES = [b.value for b in Border]


def fold(index: np.ndarray, n: int, border: Border) -> np.ndarray:
    """Map 1-based indices into ``1..n``; 0 marks "outside, reads zero"."""
    index = np.asarray(index, dtype=np.int64)
    if border is Border.CLAMP:
        return np.clip(index, 1, n)
    if border is Border.WRAP:
        return (index - 1) % n + 1
    if border is Border.MIRROR:
        k = (index - 1) % (2 * n)
        return np.where(k < n, k, 2 * n - 1 - k) + 1
    return np.where((index >= 1) & (index <= n), index, 0)
