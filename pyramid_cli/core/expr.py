"""The expression tree: what a filter chain *is*, apart from how it runs.

An expression denotes a linear operator applied to the input image ``g``:

- :class:`Input` is ``g`` itself;
- :class:`Apply` is one written operator ``h ⊗ x``, ``h ⊗↓ᵐ x`` or ``h ⊗↑ x``,
  repeated ``power`` times (the paper's ``(h)ᵐ ⊗↓ g``, §4.1).

Filters are :class:`Named` (a catalogue entry, atomic: docs/design.md §1) or
:class:`Literal` (a mask the user wrote).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from pyramid_cli.core import catalogue
from pyramid_cli.core.catalogue import Matrix


class Op(Enum):
    CONV = "conv"
    DOWN = "down"
    UP = "up"

    @property
    def unicode(self) -> str:
        return {"conv": "⊗", "down": "⊗↓", "up": "⊗↑"}[self.value]

    @property
    def ascii(self) -> str:
        return {"conv": "*", "down": "*v", "up": "*^"}[self.value]


@dataclass(frozen=True)
class Named:
    key: str
    span: tuple[int, int] = field(default=(0, 0), compare=False)


@dataclass(frozen=True)
class Literal:
    mask: Matrix
    span: tuple[int, int] = field(default=(0, 0), compare=False)


Filter = Named | Literal


@dataclass(frozen=True)
class Input:
    span: tuple[int, int] = field(default=(0, 0), compare=False)


@dataclass(frozen=True)
class Apply:
    op: Op
    filter: Filter
    arg: Expr
    power: int = 1      # (h)^power: that many written steps
    stride: int = 1     # the m of ⊗↓ᵐ: one step of stride 2**m
    span: tuple[int, int] = field(default=(0, 0), compare=False)


Expr = Input | Apply

_SUP = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")


def sup(n: int) -> str:
    return str(n).translate(_SUP)


def steps(expr: Expr) -> list[tuple[Op, Filter, int]]:
    """The written operators in the order they run (innermost first), powers expanded."""
    out: list[tuple[Op, Filter, int]] = []
    while isinstance(expr, Apply):
        out[:0] = [(expr.op, expr.filter, expr.stride)] * expr.power
        expr = expr.arg
    return out


def kind(expr: Expr) -> str:
    """convolution, analysis, synthesis or mixed: which operators the chain uses."""
    ops = {op for op, _, _ in steps(expr)}
    if Op.DOWN in ops and Op.UP in ops:
        return "mixed"
    if Op.DOWN in ops:
        return "analysis"
    if Op.UP in ops:
        return "synthesis"
    return "convolution"


def resolve_mask(f: Filter) -> Matrix:
    """The paper-form mask of a filter used with ⊗ or ⊗↓."""
    return f.mask if isinstance(f, Literal) else catalogue.mask(f.key).mask


def resolve_phases(f: Filter) -> dict[catalogue.Phase, Matrix]:
    """The four phase masks of a filter used with ⊗↑."""
    assert isinstance(f, Named), "⊗↑ takes a named synthesis filter (the parser refuses a written mask)"
    return catalogue.synthesis(f.key).phases


def _literal(m: Matrix, style: str) -> str:
    from math import lcm

    den = lcm(*(v.denominator for row in m for v in row))
    rows = "; ".join(" ".join(str(int(v * den)) for v in row) for row in m)
    body = f"[{rows}]"
    return body if den == 1 else f"1/{den} {body}"


def filter_text(f: Filter, op: Op, style: str = "unicode") -> str:
    if isinstance(f, Literal):
        return _literal(f.mask, style)
    entry = catalogue.synthesis(f.key) if op is Op.UP else catalogue.mask(f.key)
    return entry.unicode if style == "unicode" else entry.ascii


def to_text(expr: Expr, style: str = "unicode") -> str:
    """Canonical text; ``style`` is "unicode" (the paper's notation) or "ascii"."""
    if isinstance(expr, Input):
        return "g"
    op = expr.op.unicode if style == "unicode" else expr.op.ascii
    if expr.stride > 1:
        op += sup(expr.stride) if style == "unicode" else f"^{expr.stride}"
    name = filter_text(expr.filter, expr.op, style)
    if expr.power > 1:
        name = f"({name})" + (sup(expr.power) if style == "unicode" else f"^{expr.power}")
    inner = to_text(expr.arg, style)
    if isinstance(expr.arg, Apply):
        inner = f"({inner})"
    return f"{name} {op} {inner}"
