"""Every named filter exactly as printed in the paper (exact Fractions).

Masks are stored in the paper's zero-padded matrix form; the paper's index
formula (``g[r - floor(i - n/2)]`` with 1-based ``i``) gives each entry its
offset. Nothing here is derived from another filter: decompositions are the
business of :mod:`pyramid_cli.core.algebra`, and the tests check them against these
matrices.

Sections cite Kraus & Strengert, "Pyramid Filters Based on Bilinear
Interpolation", GRAPP 2007, and the project's docs/design.md §2.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from math import comb

Matrix = tuple[tuple[Fraction, ...], ...]
Phase = tuple[int, int]
PHASES: tuple[Phase, ...] = ((1, 1), (1, 0), (0, 1), (0, 0))


def matrix(rows, scale=1) -> Matrix:
    """An exact matrix from integer rows times a rational ``scale``."""
    s = Fraction(scale)
    return tuple(tuple(Fraction(v) * s for v in row) for row in rows)


def outer(col, row, scale=1) -> Matrix:
    """Column vector times row vector (the paper's separable notation)."""
    return matrix([[c * r for r in row] for c in col], scale)


def transpose(m: Matrix) -> Matrix:
    return tuple(zip(*m, strict=False))


@dataclass(frozen=True)
class NamedMask:
    """A single convolution mask, usable with ⊗ (basic) and ⊗↓ (analysis)."""

    key: str
    unicode: str          # canonical notation, e.g. "h_box^↘"
    ascii: str            # shell-friendly spelling, e.g. "box\\"
    mask: Matrix
    section: str
    kind: str             # "basic" or "analysis": where the paper introduces it
    paper_fetches: dict[str, float] = field(default_factory=dict)  # op -> count


@dataclass(frozen=True)
class NamedSynthesis:
    """Four phase masks ``h^{r mod 2, c mod 2}``, usable with ⊗↑ only."""

    key: str
    unicode: str
    ascii: str
    phases: dict[Phase, Matrix]
    section: str
    paper_fetches: dict[str, float] = field(default_factory=dict)


def _gauss(n: int) -> Matrix:
    """Binomial n×n mask, (n-1)/2 Bartletts (§3.3); n odd."""
    b = [comb(n - 1, k) for k in range(n)]
    return outer(b, b, Fraction(1, 4 ** (n - 1)))


_MASKS: dict[str, NamedMask] = {}
_SYNTH: dict[str, NamedSynthesis] = {}


def _mask(m: NamedMask) -> None:
    _MASKS[m.key] = m


def _synth(s: NamedSynthesis) -> None:
    _SYNTH[s.key] = s


# §3.1: h_box^↘ = h_box^{2×2}; the paper prints box↖ with the arrow ↙.
_mask(NamedMask("box", "h_box^↘", "box\\", matrix([[0, 0, 0], [0, 1, 1], [0, 1, 1]], Fraction(1, 4)),
                "§3.1, §4.1", "basic", {"conv": 1, "down": 1}))
_mask(NamedMask("box_nw", "h_box^↖", "box^nw", matrix([[1, 1, 0], [1, 1, 0], [0, 0, 0]], Fraction(1, 4)),
                "§3.1", "basic", {"conv": 1, "down": 1}))
# §3.2
_mask(NamedMask("bartlett", "h_Bartlett", "bartlett", outer([1, 2, 1], [1, 2, 1], Fraction(1, 16)),
                "§3.2", "basic", {"conv": 2, "down": 2}))
# §5.5: the quasi-interpolation prefilter.
_mask(NamedMask("quasi", "h_quasi", "quasi",
                matrix([[-1, -2, -1], [-2, 36, -2], [-1, -2, -1]], Fraction(1, 24)),
                "§5.5", "basic", {"conv": 3}))
# §4.2
_mask(NamedMask("box4", "h_box^{4×4}", "box4", matrix([[1] * 4] * 4, Fraction(1, 16)),
                "§4.2", "analysis", {"down": 2}))
# §4.3
_mask(NamedMask("quadratic", "h_quadratic", "quadratic", outer([1, 3, 3, 1], [1, 3, 3, 1], Fraction(1, 64)),
                "§4.3", "analysis", {"down": 3}))
# §4.3 (end): the 5×5 cubic B-spline analysis filter, docs/design.md §2.
_mask(NamedMask("cubic", "h_cubic", "cubic", outer([1, 4, 6, 4, 1], [1, 4, 6, 4, 1], Fraction(1, 256)),
                "§4.3", "analysis", {"down": 4}))

# §5.1
_ONE = matrix([[0, 0, 0], [0, 1, 0], [0, 0, 0]])
_synth(NamedSynthesis("nearest", "h_nearest", "nearest", {p: _ONE for p in PHASES}, "§5.1", {"up": 1}))
# §5.2
_MID10 = matrix([[0, 0, 0], [0, 1, 0], [0, 1, 0]], Fraction(1, 2))
_synth(NamedSynthesis("midpoint", "h_midpoint", "midpoint", {
    (1, 1): matrix([[0, 0, 0], [0, 1, 1], [0, 1, 1]], Fraction(1, 4)),
    (1, 0): _MID10,
    (0, 1): transpose(_MID10),
    (0, 0): _ONE,
}, "§5.2", {"up": 1}))
# §5.3
_DS10 = matrix([[0, 0, 0], [3, 9, 0], [1, 3, 0]], Fraction(1, 16))
_synth(NamedSynthesis("doosabin", "h_Doo-Sabin", "doosabin", {
    (1, 1): matrix([[0, 0, 0], [0, 9, 3], [0, 3, 1]], Fraction(1, 16)),
    (1, 0): _DS10,
    (0, 1): transpose(_DS10),
    (0, 0): matrix([[1, 3, 0], [3, 9, 0], [0, 0, 0]], Fraction(1, 16)),
}, "§5.3", {"up": 1}))
# §5.4: h_cubic ⊗↑ g ≡ h_box^↘ ⊗ (h_Doo-Sabin ⊗↑ g), worked out by hand to the
# bicubic B-spline subdivision masks ½[1 1] (new) and ⅛[1 6 1] (old); the tests
# derive them from the decomposition.
_C1 = (0, 4, 4)
_C0 = (1, 6, 1)
_synth(NamedSynthesis("cubic", "h_cubic", "cubic", {
    (1, 1): outer(_C1, _C1, Fraction(1, 64)),
    (1, 0): outer(_C1, _C0, Fraction(1, 64)),
    (0, 1): outer(_C0, _C1, Fraction(1, 64)),
    (0, 0): outer(_C0, _C0, Fraction(1, 64)),
}, "§5.4", {"up": 2}))
# §5.5 / docs/design.md §2: tensor product of the four-point scheme on midpoint's
# lattice; odd new index 2k-1 = (-g[k-2] + 9g[k-1] + 9g[k] - g[k+1]) / 16.
_F1 = (0, -1, 9, 9, -1)
_F0 = (0, 0, 16, 0, 0)
_synth(NamedSynthesis("fourpoint", "h_four-point", "fourpoint", {
    (1, 1): outer(_F1, _F1, Fraction(1, 256)),
    (1, 0): outer(_F1, _F0, Fraction(1, 256)),
    (0, 1): outer(_F0, _F1, Fraction(1, 256)),
    (0, 0): outer(_F0, _F0, Fraction(1, 256)),
}, "§5.5", {"up": 4.5}))


def mask(key: str) -> NamedMask:
    """The named mask ``key``; ``gaussN`` exists for every odd N >= 3 (§3.3)."""
    if key in _MASKS:
        return _MASKS[key]
    if key.startswith("gauss") and key[5:].isdigit():
        n = int(key[5:])
        if n >= 3 and n % 2 == 1:
            return NamedMask(key, f"h_Gauss^{{{n}×{n}}}", key, _gauss(n), "§3.3", "basic",
                             {"conv": n - 1, "down": n - 1})
    raise KeyError(key)


def synthesis(key: str) -> NamedSynthesis:
    return _SYNTH[key]


def synthesis_keys() -> list[str]:
    return sorted(_SYNTH)


# ------------------------------------------------------------------ names, roles, defaults
# canonical key -> names a user may write (lower case; '-' and '_' are ignored when matching)
ALIASES: dict[str, list[str]] = {
    "box": ["box", "box2", "box2x2", "boxse", "mean", "average"],
    "box_nw": ["boxnw"],
    "bartlett": ["bartlett", "bartlett3", "tent", "triangle"],
    "quasi": ["quasi", "quasiinterpolation"],
    "box4": ["box4", "box4x4"],
    "quadratic": ["quadratic", "quadratic4"],
    "cubic": ["cubic", "cubic5"],
    "nearest": ["nearest", "nn"],
    "midpoint": ["midpoint", "bilinear"],
    "doosabin": ["doosabin", "chaikin"],
    "fourpoint": ["fourpoint", "4point", "dubuc"],
    "gauss": ["gauss", "gaussian", "binomial"],
}
# Size superscripts a name may carry (h_box^{4×4} is box4), by canonical key.
SIZE_VARIANTS: dict[str, dict[str, str]] = {
    "box": {"2x2": "box", "4x4": "box4"}, "box4": {"4x4": "box4"}, "bartlett": {"3x3": "bartlett"},
    "quadratic": {"4x4": "quadratic"}, "cubic": {"5x5": "cubic"},
}
# Keys usable only as one mask (⊗, ⊗↓) or only with four phase masks (⊗↑); gaussN is a mask too.
MASK_ONLY = frozenset({"box", "box_nw", "bartlett", "quasi", "box4", "quadratic"})
SYNTHESIS_ONLY = frozenset({"nearest", "midpoint", "doosabin", "fourpoint"})
# A lone filter name runs with its own operator: analysis filters reduce, synthesis filters expand.
NATURAL_DOWN = frozenset({"box4", "quadratic"})

# The filters offered for each pyramid role (blur, levels, mipmap), and the paper's Figure 3b pair.
ANALYSIS_FILTERS = ("box", "box4", "quadratic", "cubic")
SYNTHESIS_FILTERS = ("nearest", "midpoint", "doosabin", "cubic", "fourpoint")
DEFAULT_ANALYSIS = "box4"       # the analysis (⊗↓) of blur, levels, laplacian, fill and blend unless told
DEFAULT_SYNTHESIS = "doosabin"  # their synthesis (⊗↑)
MIP_ANALYSIS_DEFAULT = "quadratic"
# fill's defaults (pull-push with membrane sweeps, pyramid_cli.workflows.methods), chosen by measurement against
# oiiotool --fillholes (docs/tutorials/fill-and-blend.md): the biquadratic B-spline pull and Doo-Sabin push (one
# lattice), the weight scale K of level 1 and of the coarser levels (a weight curve per level) and the smoothing
# sweeps at level 1 and at the coarser levels. Gortler's classic pull-push, the former defaults: box4, K = 4 at
# every level, no sweeps.
FILL_ANALYSIS = "quadratic"
FILL_SYNTHESIS = DEFAULT_SYNTHESIS
FILL_SCALE = (16, 2)
FILL_SWEEPS = (1, 4)
