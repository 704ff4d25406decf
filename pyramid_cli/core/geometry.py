"""The index geometry every stage shares (docs/design.md §1), in one place.

Output pixel ``r`` (1-based) of a step with period ``P`` and stride ``S`` reads
around the source base index ``R = S·⌈r/P⌉`` (``r`` for ⊗, ``2ᵐr`` for ⊗↓ᵐ,
``⌊(r+1)/2⌋`` for ⊗↑, whose period is 2). A step maps ``n`` pixels to
``⌈n·P/S⌉``: ``n`` for ⊗, ``⌈n/2ᵐ⌉`` for ⊗↓ᵐ, ``2n`` for ⊗↑. The functions work on
Python ints and on numpy integer arrays alike (they use only ``//`` and ``-``).

The reference (:mod:`pyramid_cli.reference.filters`) keeps its own literal copies of these
formulas on purpose: it is the oracle that catches mistakes here.
"""

from __future__ import annotations

from typing import overload

from pyramid_cli.core.errors import DataError


def ceil_div(a, b):
    """⌈a/b⌉ for integers (b > 0), negative ``a`` included."""
    return -(-a // b)


def base_index(r, period: int, stride: int):
    """``R = S·⌈r/P⌉``: the source index output pixel ``r`` maps to (any integer ``r``)."""
    return stride * ceil_div(r, period)


def step_size(n: int, period: int, stride: int) -> int:
    """Pixels out of a step with ``period`` and ``stride`` from ``n`` in: ⌈n·P/S⌉."""
    return ceil_div(n * period, stride)


def reduced(n: int, m: int = 1) -> int:
    """⌈n/2ᵐ⌉: the size after one ⊗↓ᵐ step (odd sizes round up; the clamped border pads them)."""
    return ceil_div(n, 2 ** m)


@overload
def halved(size: tuple[int, int]) -> tuple[int, int]: ...


@overload
def halved(size: tuple[int, ...]) -> tuple[int, ...]: ...


def halved(size: tuple[int, ...]) -> tuple[int, ...]:
    """Each dimension ⌈n/2⌉: the size of the next pyramid level (one ⊗↓ step; odd sizes round up)."""
    return tuple(reduced(n) for n in size)


def level_sizes(size: tuple[int, int], levels: int) -> list[tuple[int, int]]:
    """Sizes of pyramid levels 0..m: each :func:`halved` of the one before."""
    h, w = size
    out = [(h, w)]
    for _ in range(levels):
        out.append(halved(out[-1]))
    return out


def mip_levels(size: tuple[int, int]) -> int:
    """Reductions by ⌈n/2⌉ until 1×1."""
    n = 0
    while max(size) > 1:
        size = halved(size)
        n += 1
    return n


def mip_sizes(size: tuple[int, int], rounding: str = "down") -> list[tuple[int, int]]:
    """MIP level sizes (rows, columns) down to 1×1: ``max(1, ⌊n/2⌋)`` ("down", maketx's and OpenEXR's)
    or ``⌈n/2⌉`` ("up", :func:`halved`)."""
    h, w = size
    out = [(h, w)]
    while out[-1][0] > 1 or out[-1][1] > 1:
        h, w = out[-1]
        out.append((max(1, h // 2), max(1, w // 2)) if rounding == "down" else halved((h, w)))
    return out


def check_size(width: int, height: int, limit: int, *, where: str = "") -> None:
    """Refuse an image larger than ``limit`` pixels on a side (:class:`DataError`, exit 5)."""
    if width > limit or height > limit:
        prefix = f"{where}: " if where else ""
        raise DataError(f"{prefix}image size {width}x{height} exceeds the limit of {limit}x{limit} pixels")


__all__ = ["ceil_div", "base_index", "step_size", "reduced", "halved", "level_sizes", "mip_levels", "mip_sizes",
           "check_size"]
