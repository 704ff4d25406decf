"""Code generation for the CPU executor: a pass shape as the Python source of one numba kernel.

Meaning (the contract of :mod:`pyramid_cli.exec.emulate`): a tap with offset ``t`` of a pass
of period ``P`` and stride ``S`` reads the source at logical index ``S·⌈r/P⌉ − t``; a
fraction ``α`` of that index mixes the two neighbouring texels ``(1 − α)·read(i) +
α·read(i + 1)`` per axis, and ``read`` folds an integer index through the source's
border mode over its stored extent (clamp, mirror, wrap, zero; :mod:`pyramid_cli.core.border`).
For clamp this equals the emulator's clamped bilinear read: outside the extent both
neighbours are the edge texel. A tap is therefore expanded into at most four texel reads
with exact rational weights (summed over taps reading the same texel), written into the
kernel as float32 literals (:func:`kernel_source`); the loops are plain strided loops over
rows and columns that LLVM vectorises. A kernel serves float32 and float16 sources alike (the
storage is an argument), so a plan loads one kernel per distinct pass shape, whatever its inputs
store; every resampling pass shares one table-driven kernel (:func:`resample_source`), every
pointwise pass another (:func:`pointwise_source`).

Every generator takes the working type (:data:`WORK_TYPES`): float32, the default, whose text is
the one every float32 run loads, or float64 (literals, scratch rows, accumulators and signatures
at that width), a separate text and so a separate cache entry, written only when a float64 run
asks for it.

This module only writes text: numba is imported by the generated sources, compiled in
:mod:`pyramid_cli.exec.cpu.compile`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from fractions import Fraction
from math import floor

import numpy as np

from pyramid_cli.plan.model import POINTWISE_OPS
from pyramid_cli.plan.shapes import PassShape

KERNEL_VERSION = 5           # bump when the generated text changes meaning: new files, new cache entries
VARIANTS = (4, 1, None)   # channel counts with an unrolled copy of the strided loops (None: any C)
# ... and of a strided loop of one column phase (the analysis passes ⊗↓), where RGB's copy costs little to compile
# (0.2 s, against 1.2 s in a synthesis pass's four phases) and is what most pictures run: the kernel of an 8K RGB
# Deep Zoom's levels took 0.33 → 0.13 CPU-s (2026-11-28, perf)
ONE_PHASE_VARIANTS = (4, 3, 1, None)
WORK_TYPES = ("float32", "float64")   # the working types a kernel is generated for (numba's and numpy's names)


def source_digest(source: str) -> str:
    """The name a kernel source is cached under (numba's cache and the ahead-of-time modules): the first 24 hex
    digits of its SHA-256."""
    return hashlib.sha256(source.encode()).hexdigest()[:24]


def work_type(dtype=np.float32) -> str:
    """The working type name of ``dtype`` (float32 or float64; ValueError for anything else)."""
    name = np.dtype(dtype).name
    if name not in WORK_TYPES:
        raise ValueError(f"kernels compute in float32 or float64, not {name}")
    return name


# ------------------------------------------------------------------ kernel text
@dataclass(frozen=True)
class Term:
    """One texel read of a phase: source ``slot`` at row ``S·m + dr``, column ``S·n + dc`` (base-relative)."""

    slot: int
    dr: int
    dc: int
    weight: Fraction


def _axis_points(position: Fraction) -> list[tuple[int, Fraction]]:
    """Texels (integer offset, weight) a bilinear read at ``position`` mixes along one axis."""
    i = floor(position)
    a = position - i
    return [(i, 1 - a), (i + 1, a)] if a else [(i, Fraction(1))]


def phase_terms(taps) -> list[Term]:
    """The taps of one phase (``ShapeTap``: reads index ``R − t``) as texel reads with exact weights."""
    acc: dict[tuple[int, int, int], Fraction] = {}
    for t in taps:
        for dr, wr in _axis_points(-Fraction(t.offset[0])):
            for dc, wc in _axis_points(-Fraction(t.offset[1])):
                key = (t.slot, dr, dc)
                acc[key] = acc.get(key, Fraction(0)) + Fraction(t.weight) * wr * wc
    return [Term(s, dr, dc, w) for (s, dr, dc), w in sorted(acc.items()) if w]


def _literal(x: Fraction, t: str) -> str:
    """``x`` rounded to the working type ``t``, as a Python float literal."""
    return repr(float(np.dtype(t).type(float(x))))


def _name(slot: int, d: int) -> str:
    return f"r{slot}_{'m' if d < 0 else 'p'}{abs(d)}"


def factor(mats: list[dict[tuple[int, int], Fraction]]):
    """``u, [v_j]`` with ``mats[j][dr, dc] = u[dr]·v_j[dc]`` for every j (one vertical sum serves every
    column phase), or None when the texel weights of these phases do not factor so."""
    drs = sorted({dr for m in mats for dr, _ in m})
    u: list[Fraction] | None = None
    pivot = 0
    vs: list[dict[int, Fraction]] = []
    for m in mats:
        v: dict[int, Fraction] = {}
        for dc in sorted({dc for _, dc in m}):
            col = [m.get((dr, dc), Fraction(0)) for dr in drs]
            if u is None:
                pivot = next(i for i, x in enumerate(col) if x)
                u = [x / col[pivot] for x in col]
            scale = col[pivot]
            if any(x != scale * y for x, y in zip(col, u, strict=True)):
                return None
            if scale:
                v[dc] = scale
        vs.append(v)
    if u is None:
        return None
    total = sum(u)  # vertical weights summing to 1 where they can (tidier literals)
    if total:
        u = [x / total for x in u]
        vs = [{dc: w * total for dc, w in v.items()} for v in vs]
    return {dr: x for dr, x in zip(drs, u, strict=True) if x}, vs


def kernel_source(s: PassShape, dtype=np.float32) -> str:
    """Python source of the numba kernel of one pass shape, for float32 and float16 sources alike.

    ``dtype`` is the working type (:func:`work_type`): float32, or float64, where ``out``, the
    sources ``s{k}``, ``lut``, the weights and the scratch rows are float64 instead (the text is
    otherwise the same; a float64 run stores no half sources, its ``h{k}`` are placeholders).

    Arrays are flat per row: ``out`` is (rows, columns·C), every source likewise, ``C`` the
    channel count. Each source slot k arrives three times, ``s{k}`` (float32), ``h{k}`` (uint16: float16
    bit patterns, or 16-bit codes) and ``e{k}`` (uint8: 8-bit codes): bit k of ``half`` says the pixels
    are ``h{k}``, bit 16 + k that they are ``e{k}``, neither that they are ``s{k}`` (the others are 1×1
    placeholders). A uint16 or uint8 row is converted once through ``lut`` (65536 float32 values) into a
    scratch row before any tap reads it. So one compiled kernel serves every storage of the sources (a
    half or 8-bit input's first pass and the float32 passes after it), with the same arithmetic on the
    same values.

    The kernel computes the output groups ``m ∈ [m0, m1)`` of rows (the ``P`` rows sharing one
    base row ``S·m``) and, per column phase ``j``, the column groups
    ``[lo_j, hi_j)``: output row ``P·m + i + yoff`` (``i = 1..P``), column ``P·n + j + xoff``;
    source slot k row ``S·m + dr + ro_k``, column ``S·n + dc + co_k``. Every index it touches
    must lie inside the arrays: the caller guarantees it (interior or window).

    Per row phase and source, texel weights that factor as ``u[dr]·v[dc]`` (every separable
    filter of the catalogue) are read as one vertical sum over the row span (a contiguous,
    vectorised loop) and then a horizontal one; others are summed texel by texel. Loops
    over columns of stride or period 1 run over the flat row (vectorised for any C); the
    others have copies for C = 4 and 1 (:data:`VARIANTS`) with the channel loop unrolled, and for C = 3 too where
    they have one column phase (:data:`ONE_PHASE_VARIANTS`).
    """
    t = work_type(dtype)
    (pr, pc), (sr, sc) = s.period, s.stride
    table = {ph: phase_terms(taps) for ph, taps in s.phases}
    slots = range(s.n_sources)
    params = ["out"] + [f"{a}{k}" for k in slots for a in "she"] + ["lut", "half", "C"]
    params += ["m0", "m1", "yoff", "xoff"] + [f"{e}{j}" for j in range(1, pc + 1) for e in ("lo", "hi")]
    params += [f"{e}{k}" for k in slots for e in ("ro", "co")]
    weights: dict[str, str] = {}
    consts: set[int] = set()
    scaled: set[int] = set()
    tmps: set[int] = set()
    by_row: set[int] = set()   # slots read row by row (each with a ring of converted half rows)
    unit = pc == 1 and sc == 1

    def unsigned(v: int) -> str:  # unsigned index arithmetic: no negative-index wraparound, loops vectorise
        consts.add(v)
        return f"U{v}"

    def times_c(v: int, cc: int | None) -> str:
        if cc is not None:
            return unsigned(v * cc)
        scaled.add(v)
        return f"D{v}"

    def wsum(pairs: list[tuple[Fraction, str]]) -> str:
        """Σ w·read with the reads of one weight added first: one multiply per distinct weight."""
        groups: dict[Fraction, list[str]] = {}
        for w, read in pairs:
            groups.setdefault(w, []).append(read)
        parts = [weighted(w, reads[0] if len(reads) == 1 else f"({' + '.join(reads)})") for w, reads in groups.items()]
        return " + ".join(parts) or "ZERO"

    def weighted(w: Fraction, read: str) -> str:
        if w == 1:
            return read
        name = weights.setdefault(_literal(w, t), f"W{len(weights)}")
        return f"{name} * {read}"

    def loop(hterms: dict, phases: list[int], lo: str, hi: str, variants: tuple) -> list[str]:
        """Column groups [lo, hi) writing column phases ``phases``; hterms[j]: (array, slot, dc, w)."""
        used = [t for j in phases for t in hterms[j]]
        low = {k: min(t[2] for t in used if t[1] == k) for k in {t[1] for t in used}}
        out = [f"            n0 = {lo}", f"            n1 = {hi}", "            if n1 > n0:"]
        ind = "                "
        if unit:
            out.append(f"{ind}fo = np.uint64((n0 + 1 + xoff) * C)")
            out += [f"{ind}f{k} = np.uint64((n0 + co{k} + {d}) * C)" for k, d in sorted(low.items())]
            out.append(f"{ind}for g in range(np.uint64((n1 - n0) * C)):")
            parts = [(w, _read(arr, f"f{k} + g + {times_c(dc - low[k], None)}")) for arr, k, dc, w in hterms[1]]
            out.append(f"{ind}    o[fo + g] = {wsum(parts)}")
            return out
        out.append(f"{ind}x0 = np.uint64({pc} * n0 + {phases[0]} + xoff)")
        out += [f"{ind}b{k} = np.uint64({sc} * n0 + co{k} + {d})" for k, d in sorted(low.items())]
        for v, cc in enumerate(variants):
            head = "else:" if cc is None and v else f"if C == {cc}:" if cc is not None else None
            pad = ind + ("    " if head else "")
            if head:
                out.append(ind + (head if v == 0 or cc is None else "el" + head))
            width = unsigned(cc) if cc is not None else "CU"
            out.append(f"{pad}for n in range(np.uint64(n1 - n0)):")
            out.append(f"{pad}    x = (x0 + {unsigned(pc)} * n) * {width}")
            out += [f"{pad}    c{k} = (b{k} + {unsigned(sc)} * n) * {width}" for k in sorted(low)]
            if cc is None:
                out.append(f"{pad}    for c in range({width}):")
                for j in phases:
                    target = "x + c" if j == phases[0] else f"x + {times_c(j - phases[0], cc)} + c"
                    parts = [(w, _read(arr, f"c{k} + {times_c(dc - low[k], cc)} + c"))
                             for arr, k, dc, w in hterms[j]]
                    out.append(f"{pad}        o[{target}] = {wsum(parts)}")
                continue
            # channels unrolled, every load before any store: the arrays may alias as far as LLVM
            # knows, so a store between loads would keep the SLP vectoriser from packing them
            names: dict[tuple[str, int, int], int] = {}
            for j in phases:
                for arr, k, dc, _ in hterms[j]:
                    if (arr, k, dc) not in names:
                        names[(arr, k, dc)] = n = len(names)
                        for c in range(cc):
                            read = _read(arr, f"c{k} + {unsigned((dc - low[k]) * cc + c)}")
                            out.append(f"{pad}    v{n}_{c} = {read}")
            for j in phases:
                for c in range(cc):
                    target = f"x + {unsigned((j - phases[0]) * cc + c)}"
                    parts = [(w, f"v{names[(arr, k, dc)]}_{c}") for arr, k, dc, w in hterms[j]]
                    out.append(f"{pad}    o[{target}] = {wsum(parts)}")
        return out

    body = []
    for i in range(1, pr + 1):
        mats = {j: table.get((i % pr, j % pc)) or [] for j in range(1, pc + 1)}
        hterms: dict[int, list] = {j: [] for j in mats}
        rows: set[tuple[int, int]] = set()
        vertical: list[str] = []
        for k in slots:
            per = [{(t.dr, t.dc): t.weight for t in mats[j] if t.slot == k} for j in mats]
            if not any(per):
                continue
            f = factor(per)
            if f is None:  # texel by texel
                for j, m in zip(mats, per, strict=True):
                    for (dr, dc), w in sorted(m.items()):
                        rows.add((k, dr))
                        hterms[j].append((_name(k, dr), k, dc, w))
                continue
            u, vs = f
            rows |= {(k, dr) for dr in u}
            if len(u) == 1 and next(iter(u.values())) == 1:  # one row: read it directly
                arr = _name(k, next(iter(u)))
            else:
                arr = f"t{k}"
                tmps.add(k)
                dcs = [dc for v in vs for dc in v]
                vertical += ["            if nB > nA:",
                             f"                fa = np.uint64((nA * {sc} + co{k} + {min(dcs)}) * C)",
                             f"                fb = np.uint64(((nB - 1) * {sc} + co{k} + {max(dcs)} + 1) * C)",
                             "                for g in range(fa, fb):",
                             f"                    t{k}[g] = " + wsum([
                                 (w, _read(_name(k, dr), "g")) for dr, w in sorted(u.items())])]
            for j, v in zip(mats, vs, strict=True):
                hterms[j] += [(arr, k, dc, w) for dc, w in sorted(v.items())]
        body += [f"        y = {pr} * m + {i} + yoff", "        if y >= 0 and y < H:", "            o = out[y]"]
        for k, dr in sorted(rows):
            # a half source row is converted through the table once per call into a ring of scratch rows
            # (row q lives in scratch row q mod NB, NB the rows one group reads: none evicts another in use)
            name = _name(k, dr)
            by_row.add(k)
            body += [f"            rr = {sr} * m + {dr} + ro{k}"]
            for keyword, bit, codes in (("if", "H", "h"), ("elif", "E", "e")):  # uint16 rows, uint8 rows
                body += [f"            {keyword} {bit}{k}:",
                         f"                {name} = cb{k}[half_row({codes}{k}, rr, cb{k}, tag{k}, lut)]"]
            body += ["            else:", f"                {name} = s{k}[rr]"]
        if vertical:
            body += ["            nA = 1 << 62", "            nB = -(1 << 62)"]
            for j in range(1, pc + 1):
                body += [f"            if hi{j} > lo{j}:", f"                nA = min(nA, lo{j})",
                         f"                nB = max(nB, hi{j})"]
            body += vertical
        if pc > 1:  # every column phase in one loop where they cover the same groups (the interior)
            same = " and ".join(f"lo{j} == lo1 and hi{j} == hi1" for j in range(2, pc + 1))
            body.append(f"            if {same}:")
            body += _indent(loop(hterms, list(range(1, pc + 1)), "lo1", "hi1", VARIANTS))
            body.append("            else:")  # the border windows: each phase on its own
            for j in range(1, pc + 1):
                body += _indent(loop(hterms, [j], f"lo{j}", f"hi{j}", (None,)))
        else:
            body += loop(hterms, [1], "lo1", "hi1", ONE_PHASE_VARIANTS)
    decl = ["H = out.shape[0]", "CU = np.uint64(C)", f"ZERO = np.{t}(0.0)"]
    decl += [f"{w} = np.{t}({v})" for v, w in weights.items()]
    decl += [f"U{v} = np.uint64({v})" for v in sorted(consts)]
    decl += [f"D{v} = np.uint64({v}) * CU" for v in sorted(scaled)]
    decl += [f"t{k} = np.empty(max(s{k}.shape[1], h{k}.shape[1], e{k}.shape[1]), np.{t})" for k in sorted(tmps)]
    decl += [f"H{k} = (half >> {k}) & 1" for k in slots]
    decl += [f"E{k} = (half >> {16 + k}) & 1" for k in slots]
    for k in sorted(by_row):
        drs = [t.dr for ts in table.values() for t in ts if t.slot == k]
        decl += [f"cb{k} = np.empty(({max(drs) - min(drs) + 1}, max(h{k}.shape[1], e{k}.shape[1])), np.{t})",
                 f"tag{k} = np.full(cb{k}.shape[0], -1, np.int64)"]
    lines = [
        f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit",
        f"# shape: period {s.period}, stride {s.stride}, {s.n_sources} source(s)" + _typed(t),
        "import numpy as np",
        "from numba import njit",
        "",
        "",
        HALF_ROW,
        '@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")',
        f"def kernel({', '.join(params)}):",
    ] + [f"    {d}" for d in decl] + ["    for m in range(m0, m1):"] + body
    return "\n".join(lines) + "\n"


# A half (or 16-bit, or 8-bit code) source row through the table into a ring of scratch rows, once per call: row
# rr lives in scratch row rr mod NB (NB the rows one output group reads, so none evicts another in use); returns
# that scratch row.
HALF_ROW = """@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")
def half_row(h, rr, cb, tag, lut):
    q = rr % cb.shape[0]
    if tag[q] != rr:
        hr = h[rr]
        cr = cb[q]
        for g in range(hr.shape[0]):
            cr[g] = lut[hr[g]]
        tag[q] = rr
    return q

"""


def _typed(t: str) -> str:
    """The header's note of a working type other than float32 (float32's text stays as it always was)."""
    return "" if t == "float32" else f", working type {t}"


def _indent(lines: list[str]) -> list[str]:
    return ["    " + ln for ln in lines]


def _read(array: str, index: str) -> str:
    return f"{array}[{index}]"


# ------------------------------------------------------------------ resampling kernel (ResamplePass)
RESAMPLE_SOURCE = """
@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")
def kernel(out, src, idx, w, C, j0, j1, axis):
    L = idx.shape[1]
    if axis == 0:
        # output row j = sum_k w[j, k] * source row idx[j, k]: a contiguous, vectorised loop over the row
        for j in range(j0, j1):
            o = out[j]
            o[:] = 0.0
            for k in range(L):
                wk = w[j, k]
                if wk != 0.0:
                    s = src[idx[j, k]]
                    for g in range(o.shape[0]):
                        o[g] += wk * s[g]
        return
    # output column j of every row r in [j0, j1) = sum_k w[j, k] * source column idx[j, k]
    n = idx.shape[0]
    acc = np.empty(C, np.float32)
    for r in range(j0, j1):
        o = out[r]
        s = src[r]
        for j in range(n):
            acc[:] = 0.0
            for k in range(L):
                wk = w[j, k]
                base = idx[j, k] * C
                for c in range(C):
                    acc[c] += wk * s[base + c]
            for c in range(C):
                o[j * C + c] = acc[c]
"""
RESAMPLE_SIGNATURE = ("void(float32[:, ::1], float32[:, ::1], int64[:, ::1], float32[:, ::1], int64, int64, int64, "
                      "int64)")


def resample_signature(dtype=np.float32) -> str:
    """:data:`RESAMPLE_SIGNATURE` at the working type ``dtype`` (out, source and weights of that type)."""
    return RESAMPLE_SIGNATURE.replace("float32", work_type(dtype))


def resample_source(dtype=np.float32) -> str:
    """Python source of the table-driven numba kernel of every :class:`ResamplePass` (``axis`` is an argument).

    One kernel serves every table and both axes (a 1001→500 axis has 500 different rows of weights:
    they are data, not code). Indices arrive folded by the border mode; a "zero" read has weight 0.
    ``dtype`` is the working type (:func:`work_type`) of the output, the source, the weights and the sums.
    """
    t = work_type(dtype)
    return (f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit\n"
            f"# ResamplePass along either axis{_typed(t)}\nimport numpy as np\nfrom numba import njit\n\n"
            + RESAMPLE_SOURCE.replace("np.float32", f"np.{t}"))


# ------------------------------------------------------------------ pointwise kernel
# The formulas of plan.model.POINTWISE_OPS over flat float32 arrays (a, b, c the operands, K the param).
POINTWISE_EXPR = {
    "mul": "a[i] * b[i]",
    "pull_colour": "a[i] * (min(ONE, K * b[i]) / b[i]) if b[i] > ZERO else ZERO",
    "pull_weight": "min(ONE, K * a[i])",
    "divide": "a[i] / b[i] if b[i] > ZERO else ZERO",
    "over": "a[i] + (ONE - b[i]) * c[i]",
    "blend": "c[i] * a[i] + (ONE - c[i]) * b[i]",
}
POINTWISE_CODES = {op: n for n, op in enumerate(POINTWISE_OPS)}   # the ``op`` argument of the kernel


def pointwise_source(dtype=np.float32) -> str:
    """Python source of the numba kernel of every pointwise op (:class:`~pyramid_cli.plan.model.PointwisePass`):
    ``kernel(out, a, b, c, K, op, i0, i1)`` computes the flat elements ``[i0, i1)`` of op number ``op``
    (:data:`POINTWISE_CODES`) with parameter ``K``, in the working type ``dtype`` (:func:`work_type`, float32
    by default) throughout; unused operands are placeholders. One loop per op over unsigned indices, so each
    stays a plain loop that LLVM vectorises."""
    t = work_type(dtype)
    lines = [
        f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit",
        "# every pointwise op" + _typed(t),
        "import numpy as np",
        "from numba import njit",
        "",
        "",
        '@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")',
        "def kernel(out, a, b, c, K, op, i0, i1):",
        f"    ONE = np.{t}(1.0)",
        f"    ZERO = np.{t}(0.0)",
    ]
    for op, code in POINTWISE_CODES.items():
        # unsigned indices: a signed one makes numba guard every read against negative-index wraparound, and
        # the loop stays scalar (4× slower: the fill's `over` passes were a third of its time)
        lines += [f"    {'if' if code == 0 else 'elif'} op == {code}:  # {op}",
                  "        for i in range(np.uint64(i0), np.uint64(i1)):",
                  f"            out[i] = {POINTWISE_EXPR[op]}"]
    return "\n".join(lines) + "\n"


ENCODE8_SIGNATURE = "void(uint8[::1], float32[::1], uint32[::1], uint8[::1], float32[::1], int64, int64)"


def encode8_source() -> str:
    """Python source of the numba kernel that encodes float32 values to 8-bit codes by table, in one pass (the image
    I/O layer's exact sRGB encoding, :func:`pyramid_cli.imageio.colour.srgb8`, whose tables it is given):
    ``kernel(out, x, bits, codes, thresholds, i0, i1)`` sets the flat elements ``[i0, i1)`` of ``out`` to
    ``codes[b] + (x >= thresholds[b])``, ``b`` the top 16 bits of ``x`` (``bits``, the same values as uint32:
    sign, exponent and 7 mantissa bits; a bucket never spans more than one next code), and a NaN to 0. numpy's
    table lookups take six passes over the values, this one (3× faster)."""
    return "\n".join([
        f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit",
        "# 8-bit codes by table",
        "import numpy as np",
        "from numba import njit",
        "",
        "",
        '@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")',
        "def kernel(out, x, bits, codes, thresholds, i0, i1):",
        "    for i in range(np.uint64(i0), np.uint64(i1)):",
        "        v = x[i]",
        "        b = bits[i] >> np.uint32(16)",
        "        c = codes[b] + np.uint8(v >= thresholds[b])",
        "        if v != v:",
        "            c = np.uint8(0)",
        "        out[i] = c",
    ]) + "\n"


def signature(n_sources: int, pc: int, dtype=np.float32) -> str:
    """The numba signature of :func:`kernel_source`'s kernel for a shape of ``n_sources`` slots and column period
    ``pc``: each slot as float32, as uint16 (float16 bit patterns, 16-bit codes) and as uint8 (8-bit codes), then
    the float32 table the integer ones are read through (float64 for the float arrays and the output where
    ``dtype``, the working type, is float64)."""
    t = work_type(dtype)
    arrays = [f"{t}[:, ::1]"] + [f"{t}[:, ::1]", "uint16[:, ::1]", "uint8[:, ::1]"] * n_sources + [f"{t}[::1]"]
    ints = 6 + 2 * pc + 2 * n_sources
    return "void(" + ", ".join(arrays + ["int64"] * ints) + ")"


POINTWISE_SIGNATURE = "void(float32[::1], float32[::1], float32[::1], float32[::1], float32, int64, int64, int64)"


def pointwise_signature(dtype=np.float32) -> str:
    """:data:`POINTWISE_SIGNATURE` at the working type ``dtype`` (every array and ``K`` of that type)."""
    return POINTWISE_SIGNATURE.replace("float32", work_type(dtype))


__all__ = ["ENCODE8_SIGNATURE", "KERNEL_VERSION", "POINTWISE_CODES", "POINTWISE_EXPR", "POINTWISE_SIGNATURE",
           "ONE_PHASE_VARIANTS", "RESAMPLE_SIGNATURE", "RESAMPLE_SOURCE", "VARIANTS", "WORK_TYPES", "Term",
           "encode8_source", "factor", "kernel_source", "phase_terms", "pointwise_signature", "pointwise_source",
           "resample_signature", "resample_source", "signature", "source_digest", "work_type"]
