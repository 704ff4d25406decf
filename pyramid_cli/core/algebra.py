"""Exact rational algebra of filter chains: equivalent kernels, continuity, lattice.

Everything here is exact (``fractions.Fraction``) and needs only the standard
library: no floats, no numpy, no GL.

The equivalent operator of any chain is a :class:`Kernel`: output pixel
``(r, c)`` of phase ``(r mod Pr, c mod Pc)`` is ``Σ w[d] · g[R − dr, C − dc]``
with ``R = Sr·⌈r/Pr⌉`` (which is ``r`` for ⊗, ``2ᵐr`` for ⊗↓ᵐ and ``⌊(r+1)/2⌋``
for ⊗↑, the paper's index formulas of §3, §4 and §5). It is found by running the
chain symbolically on an unbounded image of unit impulses, so it holds in the
interior; at the borders the written operators of a chain clamp in between
(docs/design.md §1), which :mod:`pyramid_cli.reference.filters` models.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import cache
from math import floor, lcm

from pyramid_cli.core import catalogue
from pyramid_cli.core.catalogue import Matrix
from pyramid_cli.core.expr import Apply, Expr, Filter, Input, Literal, Op, resolve_mask, resolve_phases, steps
from pyramid_cli.core.geometry import base_index, reduced

Offset = tuple[int, int]
Weights = dict[Offset, Fraction]


def paper_offset(i: int, n: int) -> int:
    """⌊i − n/2⌋: the offset of the paper's 1-based mask index ``i`` (§3)."""
    return floor(Fraction(2 * i - n, 2))


def mask_weights(m: Matrix) -> Weights:
    """A paper-form matrix as {(dr, dc): weight} with ``f[r] = Σ w[d] g[r − d]``."""
    ni, nj = len(m), len(m[0])
    return {(paper_offset(i + 1, ni), paper_offset(j + 1, nj)): v
            for i, row in enumerate(m) for j, v in enumerate(row) if v}


# ---------------------------------------------------------------- one step
@dataclass(frozen=True)
class Step:
    """One written operator: ``filter op ·`` with stride exponent for ⊗↓ᵐ."""

    op: Op
    weights: tuple  # Weights for CONV/DOWN; tuple of (phase, Weights) for UP
    stride: int = 1

    def reads(self, r: int, c: int) -> list[tuple[Offset, Fraction]]:
        """Which input pixels output ``(r, c)`` reads, with weights (index formulas of §3–5)."""
        if self.op is Op.UP:
            w = dict(self.weights)[(r % 2, c % 2)]
            base = ((r + 1) // 2, (c + 1) // 2)
        else:
            w = self.weights
            s = 2 ** self.stride if self.op is Op.DOWN else 1
            base = (s * r, s * c)
        return [((base[0] - dr, base[1] - dc), v) for (dr, dc), v in dict(w).items()]


def _frozen(w: Weights) -> tuple:
    return tuple(sorted(w.items()))


def step_of(op: Op, f: Filter, stride: int = 1) -> Step:
    if op is Op.UP:
        phases = resolve_phases(f)
        return Step(op, tuple(sorted((p, _frozen(mask_weights(m))) for p, m in phases.items())))
    return Step(op, _frozen(mask_weights(resolve_mask(f))), stride)


def chain_steps(expr: Expr) -> list[Step]:
    return [step_of(op, f, s) for op, f, s in steps(expr)]


# ---------------------------------------------------------------- kernels
@dataclass(frozen=True)
class Kernel:
    """The equivalent operator of a chain (see the module docstring)."""

    period: tuple[int, int]
    stride: tuple[int, int]
    phases: dict[tuple[int, int], Weights]

    def base(self, r: int, axis: int) -> int:
        p, s = self.period[axis], self.stride[axis]
        return base_index(r, p, s)

    @property
    def rate(self) -> tuple[Fraction, Fraction]:
        """Input pixels per output pixel, per axis (2 for ⊗↓, ½ for ⊗↑)."""
        return (Fraction(self.stride[0], self.period[0]), Fraction(self.stride[1], self.period[1]))


def _evaluator(stps: list[Step]):
    """value(level, r, c): a pixel after ``level`` steps as input combination, unbounded, memoised."""

    @cache
    def value(level: int, rr: int, cc: int) -> tuple:
        if level == 0:
            return (((rr, cc), Fraction(1)),)
        acc: dict[Offset, Fraction] = {}
        for (ir, ic), w in stps[level - 1].reads(rr, cc):
            for k, v in value(level - 1, ir, ic):
                acc[k] = acc.get(k, 0) + w * v
        return tuple((k, v) for k, v in acc.items() if v)

    return value


def kernel_of_steps(stps: list[Step]) -> Kernel:
    split = axis_kernels(stps)
    if split is not None:  # separable chains: two cheap 1-D evaluations, then outer products
        (pr, sr, rows), (pc, sc, cols) = split
        phases = {(a, b): {(dr, dc): x * y for dr, x in rw.items() for dc, y in cw.items()}
                  for a, rw in rows.items() for b, cw in cols.items()}
        return Kernel((pr, pc), (sr, sc), phases)
    ups = sum(s.op is Op.UP for s in stps)
    downs = sum(s.stride for s in stps if s.op is Op.DOWN)
    p, s = 2 ** ups, 2 ** downs
    # One full output period, far from index 0 so that no sign games matter.
    origin = 8 * p
    value = _evaluator(stps)
    truth = {(r, c): dict(value(len(stps), r, c))
             for r in range(origin + 1, origin + p + 1) for c in range(origin + 1, origin + p + 1)}
    period, stride = [p, p], [s, s]
    for axis in (0, 1):
        while period[axis] > 1 and stride[axis] % 2 == 0:
            trial_p, trial_s = list(period), list(stride)
            trial_p[axis] //= 2
            trial_s[axis] //= 2
            if _phases(truth, trial_p, trial_s) is None:
                break
            period, stride = trial_p, trial_s
    found = _phases(truth, period, stride)
    assert found is not None  # the loop only keeps a (period, stride) that _phases accepted
    return Kernel((period[0], period[1]), (stride[0], stride[1]), found)


def split_step(step: Step) -> tuple[dict, dict] | None:
    """Per-axis 1-D phase weights {phase: {d: w}} of a separable step, or None."""
    phases = dict(step.weights) if step.op is Op.UP else {(0, 0): step.weights}
    rows: dict[int, dict[int, Fraction]] = {}
    cols: dict[int, dict[int, Fraction]] = {}
    for (pr, pc), w in phases.items():
        m, (i0, j0) = as_matrix(dict(w))
        split = separate(m)
        if split is None or not sum(split[1]):
            return None
        col = {i - i0: v for i, v in enumerate(split[0]) if v}
        row = {j - j0: v for j, v in enumerate(split[1]) if v}
        if rows.setdefault(pr, col) != col or cols.setdefault(pc, row) != row:
            return None
    return rows, cols


def _evaluator_1d(axis_steps):
    """value(level, r): pixel r after ``level`` steps as {input index: weight}, memoised across outputs."""

    @cache
    def value(level: int, rr: int) -> tuple:
        if level == 0:
            return ((rr, Fraction(1)),)
        op, phases, m = axis_steps[level - 1]
        if op is Op.UP:
            w, base = phases[rr % 2], (rr + 1) // 2
        else:
            w, base = phases[0], (2 ** m if op is Op.DOWN else 1) * rr
        acc: dict[int, Fraction] = {}
        for d, v in w.items():
            for k, x in value(level - 1, base - d):
                acc[k] = acc.get(k, 0) + v * x
        return tuple((k, x) for k, x in acc.items() if x)

    return value


def axis_kernels(stps: list[Step]):
    """For a chain of separable steps: per axis (period, stride, {phase: {d: w}}); else None."""
    splits = [sp for sp in (split_step(s) for s in stps) if sp is not None]
    if len(splits) != len(stps):
        return None
    out = []
    for axis in (0, 1):
        axis_steps = [(s.op, sp[axis], s.stride) for s, sp in zip(stps, splits, strict=True)]
        p = 2 ** sum(s.op is Op.UP for s in stps)
        st = 2 ** sum(s.stride for s in stps if s.op is Op.DOWN)
        origin = 8 * p
        value = _evaluator_1d(axis_steps)
        truth = {r: dict(value(len(axis_steps), r)) for r in range(origin + 1, origin + p + 1)}

        def phases_1d(period: int, stride: int, truth=truth):
            found: dict[int, dict[int, Fraction]] = {}
            for r, comb in truth.items():
                base = base_index(r, period, stride)
                w = {base - k: v for k, v in comb.items()}
                if found.setdefault(r % period, w) != w:
                    return None
            return found

        while p > 1 and st % 2 == 0 and phases_1d(p // 2, st // 2) is not None:
            p, st = p // 2, st // 2
        out.append((p, st, phases_1d(p, st)))
    return tuple(out)


def _phases(truth, period, stride) -> dict | None:
    """Phase masks for (period, stride), or None if the chain is not of that form."""
    out: dict[tuple[int, int], Weights] = {}
    for (r, c), comb in truth.items():
        br, bc = base_index(r, period[0], stride[0]), base_index(c, period[1], stride[1])
        w = {(br - ir, bc - ic): v for (ir, ic), v in comb.items()}
        key = (r % period[0], c % period[1])
        if out.setdefault(key, w) != w:
            return None
    return out


def kernel(expr: Expr) -> Kernel:
    """The exact equivalent kernel of ``expr`` (interior semantics)."""
    return kernel_of_steps(chain_steps(expr))


# ---------------------------------------------------------------- sizes
def output_size(expr: Expr, size: tuple[int, int]) -> tuple[int, int]:
    """(rows, cols) of the result for an input of ``size`` (docs/design.md §1 sizes)."""
    h, w = size
    for op, _, m in steps(expr):
        if op is Op.DOWN:
            h, w = reduced(h, m), reduced(w, m)
        elif op is Op.UP:
            h, w = 2 * h, 2 * w
    return h, w


# ---------------------------------------------------------------- display
def paper_size(offsets: list[int]) -> int:
    """Smallest paper mask size n whose offsets ⌊i − n/2⌋ cover ``offsets``."""
    lo, hi = min(offsets, default=0), max(offsets, default=0)
    n = 1
    while not (n // 2 >= hi and -(n // 2 - n + 1) >= -lo):
        n += 1
    return n


def anchor(n: int) -> int:
    """0-based index of offset 0 in a paper mask of size n."""
    return -(n // 2 - n + 1)


def as_matrix(w: Weights, shape: tuple[int, int] | None = None) -> tuple[list[list[Fraction]], tuple[int, int]]:
    """Weights laid out as the paper's zero-padded matrix; returns (matrix, anchor)."""
    if shape is None:
        shape = (paper_size([d[0] for d in w]), paper_size([d[1] for d in w]))
    a = (anchor(shape[0]), anchor(shape[1]))
    m = [[Fraction(0)] * shape[1] for _ in range(shape[0])]
    for (dr, dc), v in w.items():
        m[dr + a[0]][dc + a[1]] = v
    return m, a


def display_shape(k: Kernel) -> tuple[int, int]:
    """One padded shape for all phases of a kernel."""
    return (paper_size([d[0] for w in k.phases.values() for d in w]),
            paper_size([d[1] for w in k.phases.values() for d in w]))


def denominator(values) -> int:
    return lcm(*(Fraction(v).denominator for v in values)) if values else 1


def separate(m: list[list[Fraction]]) -> tuple[list[Fraction], list[Fraction]] | None:
    """Exact rank-1 split ``m = col · row``, or None. The row sums to 1 where possible."""
    nz = [(i, j) for i, row in enumerate(m) for j, v in enumerate(row) if v]
    if not nz:
        return None
    i0, j0 = nz[0]
    col = [m[i][j0] for i in range(len(m))]
    row = [m[i0][j] / m[i0][j0] for j in range(len(m[0]))]
    if any(m[i][j] != col[i] * row[j] for i in range(len(m)) for j in range(len(m[0]))):
        return None
    s = sum(row)
    if s:
        row = [v / s for v in row]
        col = [v * s for v in col]
    return col, row


# ---------------------------------------------------------------- continuity
def _polydiv(a: list[Fraction], b: list[Fraction]) -> list[Fraction] | None:
    """Exact quotient a / b, or None if b does not divide a."""
    a = list(a)
    if len(a) < len(b):
        return None
    q = [Fraction(0)] * (len(a) - len(b) + 1)
    for i in range(len(q) - 1, -1, -1):
        q[i] = a[i + len(b) - 1] / b[-1]
        for j, y in enumerate(b):
            a[i + j] -= q[i] * y
    return q if not any(a) else None


# Work bound of the contractivity test: the L-th power of a dilation-M mask has about
# len(b)·M^(L−1) coefficients; a test that would need more stops there (not shown contractive),
# as it stops at max_level (a kernel of dilation 64 would otherwise need gigabytes).
_MAX_POWER_LENGTH = 20_000
_MAX_POWER_WORK = 2_000_000


def _contractive(b: list[Fraction], dilation: int, max_level: int = 8) -> bool:
    """Is the difference scheme with mask b contractive, ‖S_b^L‖∞ < 1 for some L ≤ max_level?

    Computed in integers (b = b_int / D, so the L-th power is p_int / D^L); levels whose power
    would exceed the work bound are not tried (see ``_MAX_POWER_LENGTH``).
    """
    den = lcm(*(Fraction(v).denominator for v in b)) if b else 1
    ints = [int(v * den) for v in b]
    nonzero = sum(1 for v in ints if v)
    power = [1]
    scale = 1
    for level in range(1, max_level + 1):
        spread = dilation ** (level - 1)
        period = dilation ** level
        if (len(power) + (len(ints) - 1) * spread > _MAX_POWER_LENGTH or period > _MAX_POWER_LENGTH
                or len(power) * nonzero > _MAX_POWER_WORK):
            break
        out = [0] * (len(power) + (len(ints) - 1) * spread)
        for j, y in enumerate(ints):
            if y:
                off = j * spread
                for i, x in enumerate(power):
                    if x:
                        out[i + off] += x * y
        power = out
        scale *= den
        norm = max(sum(abs(v) for v in power[i::period]) for i in range(period))
        if norm < scale:
            return True
    return False


def continuity_1d(mask: list[Fraction], dilation: int) -> int:
    """The smoothness class k (C^k, −1 for discontinuous) of a refinement mask.

    ``mask`` is the subdivision mask a(z) of a scheme of dilation M (Σ a = M).
    The scheme is C^k when a(z) = (σ(z)/M)^k · c(z) with σ = 1 + z + … + z^{M−1}
    and the scheme of c converges, i.e. c = σ · b with S_b contractive (Dyn 1992,
    the classical difference-scheme test). Computed, not looked up.
    """
    sigma = [Fraction(1)] * dilation
    c = [Fraction(v) for v in mask]
    k = -1
    for m in range(0, 8):
        b = _polydiv(c, sigma)
        if b is None or not _contractive(b, dilation):
            break
        k = m
        c = [dilation * v for v in b]  # c_{m+1} = M · c_m / σ
    return k


def _subdivision_mask(k: Kernel) -> dict[Offset, Fraction] | None:
    """The 2-D refinement mask a of an analysis (P = 1) or synthesis (S = 1) kernel."""
    (pr, pc), (sr, sc) = k.period, k.stride
    if (pr, pc) == (1, 1):
        # analysis: the powers converge to the refinable function of mask S·w (§4.1)
        return {d: v * sr * sc for d, v in k.phases[(0, 0)].items()}
    if (sr, sc) == (1, 1):
        # synthesis: fine r reads coarse ⌈r/P⌉ − d, i.e. a[r − P⌈r/P⌉ + P·d] = w_φ[d]
        out: dict[Offset, Fraction] = {}
        for (fr, fc), w in k.phases.items():
            r0, c0 = (fr or pr), (fc or pc)
            for (dr, dc), v in w.items():
                e = (r0 - pr * -(-r0 // pr) + pr * dr, c0 - pc * -(-c0 // pc) + pc * dc)
                out[e] = out.get(e, 0) + v
        return out
    return None


def continuity(k: Kernel) -> int | None:
    """C^k class of a separable analysis or synthesis kernel (the lesser axis); None otherwise.

    Plain convolutions (rate 1) and mixed chains have no limit function.
    """
    dil = (max(k.period[0], k.stride[0]), max(k.period[1], k.stride[1]))
    if 1 in dil:
        return None
    entries = _subdivision_mask(k)
    split = separate(as_matrix(entries)[0]) if entries else None
    if split is None:
        return None
    classes = []
    for vec, m in zip(split, dil, strict=False):
        total = sum(vec)
        if not total:
            return None
        classes.append(continuity_1d([v * m / total for v in vec], m))
    return min(classes)


def continuity_name(k: int | None) -> str | None:
    if k is None:
        return None
    return "C^-1" if k < 0 else f"C^{k}"


# ---------------------------------------------------------------- lattice
def lattice(k: Kernel) -> tuple[str, tuple[Fraction | None, Fraction | None]]:
    """Where output samples sit: ``pos(r) = ρ·r + o`` in input pixels, per axis.

    primal: o = 0 (coarse r at fine 2r); dual: o = (1 − ρ)/2 for ρ ≠ 1 (coarse r
    at fine 2r − ½, docs/design.md §4); otherwise shifted by o. Returns the name and
    (o_r, o_c).
    """
    names: list[str] = []
    offs: list[Fraction | None] = []
    for axis in (0, 1):
        rho = k.rate[axis]
        o_all: list[Fraction] = []
        undefined = False
        for (fr, fc), w in k.phases.items():
            phase = (fr, fc)[axis]
            p = k.period[axis]
            r = 8 * p + (phase or p)
            total = sum(w.values())
            if not total:
                undefined = True  # a phase with zero total weight has no centroid
                break
            centroid = sum(v * (k.base(r, axis) - d[axis]) for d, v in w.items()) / total
            o_all.append(centroid - rho * r)
        if undefined:
            names.append("undefined")
            offs.append(None)
            continue
        # phases of a piecewise-constant filter (nearest) differ: take their mean
        o = sum(o_all, Fraction(0)) / len(o_all)
        offs.append(o)
        if o == 0:
            names.append("primal")
        elif rho != 1 and o == (1 - rho) / 2:
            names.append("dual")
        else:
            names.append("shifted")
    name = names[0] if names[0] == names[1] else f"{names[0]}×{names[1]}"
    return name, (offs[0], offs[1])


# ---------------------------------------------------------------- paper counts
def paper_fetches(expr: Expr) -> float | None:
    """The paper's texture-fetch count: the sum over written steps (§3–5)."""
    total = 0.0
    for op, f, _ in steps(expr):
        if isinstance(f, Literal):
            return None
        entry = catalogue.synthesis(f.key) if op is Op.UP else catalogue.mask(f.key)
        count = entry.paper_fetches.get(op.value)
        if count is None:
            return None
        total += count
    return total


__all__ = ["Kernel", "kernel", "continuity", "lattice", "output_size", "paper_fetches", "as_matrix",
           "separate", "Input", "Apply"]
