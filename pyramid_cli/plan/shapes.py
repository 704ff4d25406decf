"""A pass's canonical shape: what an executor compiles once and reuses (the key of its program or kernel cache).

A pass of a :class:`~pyramid_cli.plan.model.Plan` becomes a :class:`PassShape`: everything a
generated program needs except sizes and guard bands (the executors pass those at run time),
so one compiled program serves every image size and every plan that has a pass of the same
shape. Image indices are replaced by *slots* (the pass's sorted sources), so two passes that
read different images the same way have one shape. The GL executor writes a shape's taps
into a fragment shader (:mod:`pyramid_cli.exec.gl.shaders`); the CPU executor into a numba
kernel (:mod:`pyramid_cli.exec.cpu.codegen`). A :class:`~pyramid_cli.plan.model.PointwisePass`
becomes a :class:`PointwiseShape`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import overload

from pyramid_cli.plan.model import Image, Pass, PointwisePass


@dataclass(frozen=True)
class ShapeTap:
    """One tap of a shape: source ``slot`` (index into the pass's sorted sources) read at ``R − offset``."""

    slot: int                          # index into the pass's sorted sources
    offset: tuple[Fraction, Fraction]  # (rows, columns), reads source index R − t
    weight: Fraction

    @property
    def exact_texel(self) -> bool:
        """Integral offset: one texel, read with texelFetch (equals bilinear there)."""
        return all(o.denominator == 1 for o in self.offset)


@dataclass(frozen=True)
class PassShape:
    """The canonical description of a pass, the key of the program cache."""

    period: tuple[int, int]
    stride: tuple[int, int]
    n_sources: int
    phases: tuple[tuple[tuple[int, int], tuple[ShapeTap, ...]], ...]  # sorted by phase
    borders: tuple[str, ...] = ()  # per slot: how reads past the source's extent fold (empty: all clamp)

    def border(self, slot: int) -> str:
        """The border mode of source ``slot`` (``"clamp"`` when the shape records none)."""
        return self.borders[slot] if self.borders else "clamp"


@dataclass(frozen=True)
class PointwiseShape:
    """The program-cache key of a pointwise pass: its op, operand count and parameter."""

    op: str
    n_sources: int
    param: Fraction


def sources(ps: Pass | PointwisePass) -> list[int]:
    """The pass's source images in slot order (slot k is texture unit k); a pointwise pass's
    operands in their order."""
    if isinstance(ps, PointwisePass):
        return list(ps.srcs)
    return sorted(ps.sources())


def _pair(v: Sequence[int]) -> tuple[int, int]:
    """A (rows, columns) pair as a tuple of two (the hashable form a shape keeps)."""
    r, c = v
    return (r, c)


def pointwise_shape(ps: PointwisePass) -> PointwiseShape:
    """The shape of a pointwise pass: its op, operand count and parameter."""
    return PointwiseShape(ps.op, len(ps.srcs), Fraction(ps.param))


@overload
def shape(ps: Pass, images: list[Image] | None = None) -> PassShape: ...


@overload
def shape(ps: PointwisePass, images: list[Image] | None = None) -> PointwiseShape: ...


@overload
def shape(ps: Pass | PointwisePass, images: list[Image] | None = None) -> PassShape | PointwiseShape: ...


def shape(ps: Pass | PointwisePass, images: list[Image] | None = None) -> PassShape | PointwiseShape:
    """Canonical shape of ``ps``: its taps with image indices replaced by slots.

    With the plan's ``images``, the shape also records each source's border mode
    (a non-clamp border folds reads in the shader); without, every source clamps.
    A pointwise pass gives its :class:`PointwiseShape`.
    """
    if isinstance(ps, PointwisePass):
        return pointwise_shape(ps)
    slot = {src: k for k, src in enumerate(sources(ps))}
    phases = tuple(sorted(
        (_pair(ph), tuple(ShapeTap(slot[t.source], (Fraction(t.offset[0]), Fraction(t.offset[1])),
                                   Fraction(t.weight)) for t in taps))
        for ph, taps in ps.phases.items()))
    borders = tuple(images[src].border for src in sources(ps)) if images is not None else ()
    if all(b == "clamp" for b in borders):
        borders = ()
    return PassShape(_pair(ps.period), _pair(ps.stride), len(slot), phases, borders)


__all__ = ["PassShape", "PointwiseShape", "ShapeTap", "pointwise_shape", "shape", "sources"]
