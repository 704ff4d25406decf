"""The compiled CPU executor: a :class:`~pyramid_cli.plan.Plan` as generated numba kernels.

Where there is no GPU, the GL executor runs on Mesa's llvmpipe and pays for upload,
read-back and power-of-two textures (DESIGN.md §6). This executor runs the same passes
on the CPU without any of that: every pass of a plan becomes one numba function
generated from the pass's taps (:func:`kernel_source`), so the paper's bilinear taps
(§3–§5) are unrolled into the texel reads they stand for, with their weights as float32
literals, and the loops are plain strided loops over rows and columns that LLVM
vectorises.

Meaning (the contract of :mod:`pyramid_cli.exec.emulate`): a tap with offset ``t`` of a pass
of period ``P`` and stride ``S`` reads the source at logical index ``S·⌈r/P⌉ − t``; a
fraction ``α`` of that index mixes the two neighbouring texels ``(1 − α)·read(i) +
α·read(i + 1)`` per axis, and ``read`` folds an integer index through the source's
border mode over its stored extent (clamp, mirror, wrap, zero; :mod:`pyramid_cli.core.border`).
For clamp this equals the emulator's clamped bilinear read: outside the extent both
neighbours are the edge texel. A tap is therefore expanded into at most four texel reads
with exact rational weights (summed over taps reading the same texel).

Borders without copies: a pass's output is split into an *interior*, whose reads all fall
inside every source's stored extent and which the kernel reads directly (no bounds checks,
no padded copy of the source), and the border strips around it (a few rows and columns).
For each strip the executor gathers the small window of source texels it reads, folded
through the border mode, and runs the same kernel on that window. The interior is split
into bands of rows run by a thread pool (the kernels release the GIL).

Compiled once per pass shape per machine: a kernel is keyed by the pass's canonical
:class:`~pyramid_cli.exec.gl.shaders.PassShape` (taps with image indices replaced by
source slots, the key of the GL program cache) and the sources' storage (float32, or
float16 inputs read through a 65536-entry table, so a half image is never copied to
float32 whole). Its source is written to the cache directory (:func:`cache_dir`) and
compiled with ``cache=True``, so a later process loads the machine code from numba's
cache beside it instead of compiling again.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from fractions import Fraction
from math import floor
from pathlib import Path

import numpy as np

from pyramid_cli.core import signals
from pyramid_cli.core.border import Border, fold
from pyramid_cli.core.errors import BackendError
from pyramid_cli.exec.gl import shaders as generate
from pyramid_cli.plan import Plan, PointwisePass, ResamplePass

INSTALL_HINT = "install numba: pip install numba (or pip install -e . in a checkout)"
CACHE_ENV = "PYRAMID_CACHE_DIR"
KERNEL_VERSION = 3           # bump when the generated text changes meaning: new files, new cache entries
SMALL = 1 << 20              # output floats below which a pass runs on the calling thread
TINY = 1 << 14               # output floats up to which a pass runs as one call on one gathered window
OUT_DTYPES = (np.dtype(np.float32), np.dtype(np.float16))
VARIANTS = (4, 1, None)   # channel counts with an unrolled copy of the strided loops (None: any C)


def available() -> tuple[bool, str]:
    """Can the CPU executor run here? ``(True, "numba X.Y")`` or ``(False, reason with the fix)``."""
    try:
        import numba
    except Exception as e:  # noqa: BLE001 - ImportError, or a broken llvmlite
        reason = " ".join(str(e).split()) or type(e).__name__
        return False, f"numba cannot be imported ({reason}); {INSTALL_HINT}"
    return True, f"numba {numba.__version__}"


def cache_dir() -> Path:
    """Where generated kernel sources and numba's compiled code live.

    ``$PYRAMID_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/bilinear-pyramid/cpu``, else
    ``~/.cache/bilinear-pyramid/cpu`` (the XDG base directory convention).
    """
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "bilinear-pyramid" / "cpu"


def default_threads() -> int:
    """The cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


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


def _f32(x: Fraction) -> str:
    return repr(float(np.float32(float(x))))


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


def kernel_source(s: generate.PassShape, half: tuple[bool, ...]) -> str:
    """Python source of the numba kernel of one pass shape; ``half[k]``: source slot k is float16 (as uint16).

    Arrays are flat per row: ``out`` is (rows, columns·C), every source likewise, ``C`` the
    channel count. The kernel computes the output groups ``m ∈ [m0, m1)`` of rows (the ``P``
    rows sharing one base row ``S·m``) and, per column phase ``j``, the column groups
    ``[lo_j, hi_j)``: output row ``P·m + i + yoff`` (``i = 1..P``), column ``P·n + j + xoff``;
    source slot k row ``S·m + dr + ro_k``, column ``S·n + dc + co_k``. Every index it touches
    must lie inside the arrays: the caller guarantees it (interior or window).

    Per row phase and source, texel weights that factor as ``u[dr]·v[dc]`` (every separable
    filter of the catalogue) are read as one vertical sum over the row span (a contiguous,
    vectorised loop) and then a horizontal one; others are summed texel by texel. Loops
    over columns of stride or period 1 run over the flat row (vectorised for any C); the
    others have copies for C = 4 and 1 (:data:`VARIANTS`) with the channel loop unrolled.
    """
    (pr, pc), (sr, sc) = s.period, s.stride
    table = {ph: phase_terms(taps) for ph, taps in s.phases}
    slots = range(s.n_sources)
    params = ["out"] + [f"s{k}" for k in slots] + (["lut"] if any(half) else []) + ["C"]
    params += ["m0", "m1", "yoff", "xoff"] + [f"{e}{j}" for j in range(1, pc + 1) for e in ("lo", "hi")]
    params += [f"{e}{k}" for k in slots for e in ("ro", "co")]
    weights: dict[str, str] = {}
    consts: set[int] = set()
    scaled: set[int] = set()
    tmps: set[int] = set()
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
        name = weights.setdefault(_f32(w), f"W{len(weights)}")
        return f"{name} * {read}"

    def loop(hterms: dict, phases: list[int], lo: str, hi: str, variants: tuple) -> list[str]:
        """Column groups [lo, hi) writing column phases ``phases``; hterms[j]: (array, slot, dc, w, half)."""
        used = [t for j in phases for t in hterms[j]]
        low = {k: min(t[2] for t in used if t[1] == k) for k in {t[1] for t in used}}
        out = [f"            n0 = {lo}", f"            n1 = {hi}", "            if n1 > n0:"]
        ind = "                "
        if unit:
            out.append(f"{ind}fo = np.uint64((n0 + 1 + xoff) * C)")
            out += [f"{ind}f{k} = np.uint64((n0 + co{k} + {d}) * C)" for k, d in sorted(low.items())]
            out.append(f"{ind}for g in range(np.uint64((n1 - n0) * C)):")
            parts = [(w, _read(arr, f"f{k} + g + {times_c(dc - low[k], None)}", h)) for arr, k, dc, w, h in hterms[1]]
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
                    parts = [(w, _read(arr, f"c{k} + {times_c(dc - low[k], cc)} + c", h))
                             for arr, k, dc, w, h in hterms[j]]
                    out.append(f"{pad}        o[{target}] = {wsum(parts)}")
                continue
            # channels unrolled, every load before any store: the arrays may alias as far as LLVM
            # knows, so a store between loads would keep the SLP vectoriser from packing them
            names: dict[tuple[str, int, int], int] = {}
            for j in phases:
                for arr, k, dc, _, h in hterms[j]:
                    if (arr, k, dc) not in names:
                        names[(arr, k, dc)] = n = len(names)
                        for c in range(cc):
                            read = _read(arr, f"c{k} + {unsigned((dc - low[k]) * cc + c)}", h)
                            out.append(f"{pad}    v{n}_{c} = {read}")
            for j in phases:
                for c in range(cc):
                    target = f"x + {unsigned((j - phases[0]) * cc + c)}"
                    parts = [(w, f"v{names[(arr, k, dc)]}_{c}") for arr, k, dc, w, _ in hterms[j]]
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
                        hterms[j].append((_name(k, dr), k, dc, w, half[k]))
                continue
            u, vs = f
            rows |= {(k, dr) for dr in u}
            if len(u) == 1 and next(iter(u.values())) == 1:  # one row: read it directly
                arr, h = _name(k, next(iter(u))), half[k]
            else:
                arr, h = f"t{k}", False
                tmps.add(k)
                dcs = [dc for v in vs for dc in v]
                vertical += ["            if nB > nA:",
                             f"                fa = np.uint64((nA * {sc} + co{k} + {min(dcs)}) * C)",
                             f"                fb = np.uint64(((nB - 1) * {sc} + co{k} + {max(dcs)} + 1) * C)",
                             "                for g in range(fa, fb):",
                             f"                    t{k}[g] = " + wsum([
                                 (w, _read(_name(k, dr), "g", half[k])) for dr, w in sorted(u.items())])]
            for j, v in zip(mats, vs, strict=True):
                hterms[j] += [(arr, k, dc, w, h) for dc, w in sorted(v.items())]
        body += [f"        y = {pr} * m + {i} + yoff", "        if y >= 0 and y < H:", "            o = out[y]"]
        body += [f"            {_name(k, dr)} = s{k}[{sr} * m + {dr} + ro{k}]" for k, dr in sorted(rows)]
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
            body += loop(hterms, [1], "lo1", "hi1", VARIANTS)
    decl = ["H = out.shape[0]", "CU = np.uint64(C)", "ZERO = np.float32(0.0)"]
    decl += [f"{w} = np.float32({v})" for v, w in weights.items()]
    decl += [f"U{v} = np.uint64({v})" for v in sorted(consts)]
    decl += [f"D{v} = np.uint64({v}) * CU" for v in sorted(scaled)]
    decl += [f"t{k} = np.empty(s{k}.shape[1], np.float32)" for k in sorted(tmps)]
    lines = [
        f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit",
        f"# shape: period {s.period}, stride {s.stride}, {s.n_sources} source(s), half {half}",
        "import numpy as np",
        "from numba import njit",
        "",
        "",
        '@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")',
        f"def kernel({', '.join(params)}):",
    ] + [f"    {d}" for d in decl] + ["    for m in range(m0, m1):"] + body
    return "\n".join(lines) + "\n"


def _indent(lines: list[str]) -> list[str]:
    return ["    " + ln for ln in lines]


def _read(array: str, index: str, half: bool) -> str:
    read = f"{array}[{index}]"
    return f"lut[{read}]" if half else read


# ------------------------------------------------------------------ resampling kernels (ResamplePass)
RESAMPLE_SOURCE = {
    # axis 0: output row j = Σ_k w[j, k] · source row idx[j, k]; a contiguous, vectorised loop over the row
    0: """
@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")
def kernel(out, src, idx, w, C, j0, j1):
    L = idx.shape[1]
    for j in range(j0, j1):
        o = out[j]
        o[:] = 0.0
        for k in range(L):
            wk = w[j, k]
            if wk != 0.0:
                s = src[idx[j, k]]
                for g in range(o.shape[0]):
                    o[g] += wk * s[g]
""",
    # axis 1: output column j of every row r in [j0, j1) = Σ_k w[j, k] · source column idx[j, k]
    1: """
@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")
def kernel(out, src, idx, w, C, j0, j1):
    L = idx.shape[1]
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
""",
}
RESAMPLE_SIGNATURE = "void(float32[:, ::1], float32[:, ::1], int64[:, ::1], float32[:, ::1], int64, int64, int64)"


def resample_source(axis: int) -> str:
    """Python source of the table-driven numba kernel of a :class:`ResamplePass` along ``axis``.

    One kernel per axis serves every table (a 1001→500 axis has 500 different rows of weights:
    they are data, not code). Indices arrive folded by the border mode; a "zero" read has weight 0.
    """
    return (f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit\n"
            f"# ResamplePass along axis {axis}\nimport numpy as np\nfrom numba import njit\n\n"
            + RESAMPLE_SOURCE[axis])


# ------------------------------------------------------------------ pointwise kernels
# The formulas of plan.model.POINTWISE_OPS over flat float32 arrays (a, b, c the operands, K the param).
POINTWISE_EXPR = {
    "mul": "a[i] * b[i]",
    "pull_colour": "a[i] * (min(ONE, K * b[i]) / b[i]) if b[i] > ZERO else ZERO",
    "pull_weight": "min(ONE, K * a[i])",
    "divide": "a[i] / b[i] if b[i] > ZERO else ZERO",
    "over": "a[i] + (ONE - b[i]) * c[i]",
    "blend": "c[i] * a[i] + (ONE - c[i]) * b[i]",
}


def pointwise_source(op: str, param: Fraction) -> str:
    """Python source of the numba kernel of one pointwise op (:class:`~pyramid_cli.plan.model.PointwisePass`):
    ``kernel(out, a[, b[, c]], i0, i1)`` computes the flat elements ``[i0, i1)``, float32 throughout."""
    from pyramid_cli.plan import POINTWISE_OPS

    names = "abc"[:POINTWISE_OPS[op][0]]
    return "\n".join([
        f"# generated by pyramid_cli.exec.cpu (kernel version {KERNEL_VERSION}); do not edit",
        f"# pointwise {op}, K = {param}",
        "import numpy as np",
        "from numba import njit",
        "",
        "",
        '@njit(nogil=True, cache=True, boundscheck=False, error_model="numpy")',
        f"def kernel(out, {', '.join(names)}, i0, i1):",
        "    ONE = np.float32(1.0)",
        "    ZERO = np.float32(0.0)",
        f"    K = np.float32({_f32(param)})",
        "    for i in range(i0, i1):",
        f"        out[i] = {POINTWISE_EXPR[op]}",
    ]) + "\n"


# ------------------------------------------------------------------ compiled kernels
def _signature(n_sources: int, half: tuple[bool, ...], pc: int) -> str:
    arrays = ["float32[:, ::1]"] + ["uint16[:, ::1]" if h else "float32[:, ::1]" for h in half]
    if any(half):
        arrays.append("float32[::1]")
    ints = 5 + 2 * pc + 2 * n_sources
    return "void(" + ", ".join(arrays + ["int64"] * ints) + ")"


_LOCK = threading.Lock()
_MODULES: dict[str, object] = {}   # file digest → compiled dispatcher, shared by executors of a process
BLAS_PROBE = "scipy.linalg.cython_blas"


def _compile_vectorised(fn, sig: str) -> None:
    """``fn.compile(sig)`` with LLVM's SLP vectoriser on (numba leaves it off by default).

    The unrolled channel loops are straight-line code that only the SLP vectoriser packs
    into SIMD registers: measured 3× faster on the RGBA synthesis loop. numba reads the
    flag when it builds the pass managers of each compile, so it is set for this compile
    only (under the module lock) and restored; a kernel loaded from the disk cache keeps
    the machine code it was compiled to.
    """
    from numba.core import config

    saved = config.SLP_VECTORIZE
    config.SLP_VECTORIZE = 1
    try:
        _compile(fn, sig)
    finally:
        config.SLP_VECTORIZE = saved


def _compile(fn, sig: str) -> None:
    """``fn.compile(sig)``; a disk cache that cannot be written (a full disk, a file-size limit) costs the
    cache, not the run: numba adds the overload before it saves it, so the retry without a cache finds it."""
    try:
        fn.compile(sig)
    except OSError:
        from numba.core.caching import NullCache

        fn._cache = NullCache()
        fn.compile(sig)


def _skip_blas_probe() -> None:
    """Import numba's array math without its BLAS probe, which imports SciPy's linalg (~0.2 s).

    numba checks for BLAS once per process, when its array-math registry loads at the first
    compile or cache load; with SciPy installed that import costs more than loading every
    kernel of a plan. The kernels use no BLAS. The probe is skipped only while nothing has
    imported SciPy's linalg or numba's array math yet; afterwards SciPy imports as usual (and
    numba's ``np.dot`` family still finds it when first typed).
    """
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules or BLAS_PROBE in sys.modules:
        return
    sys.modules[BLAS_PROBE] = None  # type: ignore[assignment] - makes the probe's import fail fast
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        if BLAS_PROBE in sys.modules and sys.modules[BLAS_PROBE] is None:
            del sys.modules[BLAS_PROBE]


def _write_source(folder: Path, digest: str, source: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"k_{digest}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
        tmp.write_text(source, encoding="utf-8")
        os.replace(tmp, path)  # never a half-written file, even with processes racing
    return path


def _fallback_cache() -> Path:
    """A per-user folder under the temporary directory, for when the cache folder cannot be written."""
    import tempfile

    uid = os.getuid() if hasattr(os, "getuid") else "user"
    return Path(tempfile.gettempdir()) / f"bilinear-pyramid-cpu-{uid}"


def _load(source: str, folder: Path):
    """The ``kernel`` of ``source``, written once to ``folder`` (atomically) and imported from there."""
    digest = hashlib.sha256(source.encode()).hexdigest()[:24]
    with _LOCK:
        hit = _MODULES.get(digest)
        if hit is not None:
            return hit
        _skip_blas_probe()
        try:
            path = _write_source(folder, digest, source)
        except OSError:  # a read-only or broken cache folder: compile from a private one
            path = _write_source(_fallback_cache(), digest, source)
        name = f"_pyramid_cpu_k_{digest}"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        _MODULES[digest] = module.kernel
        return module.kernel


@dataclass
class _Kernel:
    fn: object       # the numba dispatcher, compiled for one signature
    shape: generate.PassShape
    terms: dict      # phase → list[Term]
    extents: list    # per slot: (dr_min, dr_max, dc_min, dc_max)


# ------------------------------------------------------------------ folding
def _fold(index: np.ndarray, n: int, border: str) -> np.ndarray:
    """0-based stored indices folded into ``0..n−1`` by the border mode; −1 reads zero."""
    return fold(index + 1, n, Border.parse(border)) - 1


def _window(src: np.ndarray, rows: tuple[int, int], cols: tuple[int, int], border: str) -> np.ndarray:
    """Texels ``rows[0]..rows[1]`` × ``cols[0]..cols[1]`` (inclusive, 0-based stored, possibly outside) of ``src``."""
    ri = _fold(np.arange(rows[0], rows[1] + 1), src.shape[0], border)
    ci = _fold(np.arange(cols[0], cols[1] + 1), src.shape[1], border)
    win = src[np.ix_(np.maximum(ri, 0), np.maximum(ci, 0))]
    if border == "zero":
        win[ri < 0] = 0
        win[:, ci < 0] = 0
    return win


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


class CPUExecutor:
    """Runs plans as generated numba kernels on the CPU (paper §3–§5 passes, DESIGN.md §5).

    Parameters
    ----------
    threads : int, optional
        Worker threads for the large passes; default: the cores this process may use.
        ``1`` runs everything on the calling thread.
    cache : str or Path, optional
        Folder of generated kernel sources and numba's compiled code; default :func:`cache_dir`.

    Attributes
    ----------
    compiles : int
        Kernels compiled by this executor (cache misses: neither in this process nor on disk).
    cache_loads : int
        Kernels loaded from the disk cache (compiled by an earlier process).

    The executor has the public surface of :class:`~pyramid_cli.exec.gl.GLExecutor` where it
    makes sense: :meth:`run`, :meth:`run_outputs`, :meth:`prepare`, :meth:`close`, and it is
    a context manager. It holds no image memory between runs.
    """

    strategy = "fused"  # one pass per written step: each pass streams its whole target through memory

    def __init__(self, threads: int | None = None, cache: str | Path | None = None):
        ok, why = available()
        if not ok:
            raise BackendError(why)
        self.threads = max(1, int(threads)) if threads else default_threads()
        self.cache = Path(cache) if cache is not None else cache_dir()
        self.compiles = 0
        self.cache_loads = 0
        self._kernels: dict[tuple, _Kernel] = {}
        self._pool: ThreadPoolExecutor | None = None
        self._lut: np.ndarray | None = None

    # ------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Stop the worker threads (the executor can be used again afterwards)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        self._pool = None

    def __enter__(self) -> CPUExecutor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def name(self) -> str:
        """What runs the plans, for messages: ``cpu (numba …, N threads)``."""
        import numba

        return f"cpu (numba {numba.__version__}, {self.threads} thread(s))"

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """How many of ``plan``'s kernels are neither loaded in this process nor compiled on disk yet
        (what a first run on a machine compiles: about a second each)."""
        half_inputs = set(plan.inputs) if np.dtype(dtype) == np.float16 else set()
        missing = set()
        for ps in plan.passes:
            if isinstance(ps, ResamplePass):
                if ("resample", ps.axis) in self._kernels:
                    continue
                digest = hashlib.sha256(resample_source(ps.axis).encode()).hexdigest()[:24]
                if not any((self.cache / "__pycache__").glob(f"k_{digest}.kernel-*.nbi")):
                    missing.add(digest)
                continue
            if isinstance(ps, PointwisePass):
                digest = hashlib.sha256(pointwise_source(ps.op, ps.param).encode()).hexdigest()[:24]
                if not (digest in _MODULES and _MODULES[digest].signatures) and not any(
                        (self.cache / "__pycache__").glob(f"k_{digest}.kernel-*.nbi")):
                    missing.add(digest)
                continue
            s = generate.shape(ps)
            half = tuple(src in half_inputs for src in generate.sources(ps))
            if (s, half) in self._kernels:
                continue
            digest = hashlib.sha256(kernel_source(s, half).encode()).hexdigest()[:24]
            if digest in _MODULES and _MODULES[digest].signatures:
                continue
            if not any((self.cache / "__pycache__").glob(f"k_{digest}.kernel-*.nbi")):
                missing.add(digest)
        return len(missing)

    def info(self) -> dict:
        """What runs the plans: numba's version, threads and the cache folder."""
        import numba

        return {"renderer": f"numba {numba.__version__} ({self.threads} thread(s))", "threads": self.threads,
                "cache": str(self.cache)}

    # ------------------------------------------------------------ kernels
    def kernel(self, ps, half: tuple[bool, ...] | None = None) -> _Kernel:
        """The compiled kernel of a pass's shape (``half[k]``: source slot k stored as float16)."""
        s = generate.shape(ps)
        half = tuple(half) if half is not None else (False,) * s.n_sources
        key = (s, half)
        k = self._kernels.get(key)
        if k is None:
            k = self._kernels[key] = self._build(s, half)
        return k

    def _ready(self, fn, sig: str, compile_=_compile) -> None:
        """Compile ``fn`` for ``sig`` once (or load it from the disk cache), counting which it was.

        A signal waits for the compile to end (:func:`signals.deferred`): raised inside numba's
        compiler it would leave it broken, and its clean-up would print tracebacks.
        """
        with _LOCK, signals.deferred():
            if not fn.signatures:
                hits = sum(fn.stats.cache_hits.values())
                compile_(fn, sig)
                if sum(fn.stats.cache_hits.values()) > hits:
                    self.cache_loads += 1
                else:
                    self.compiles += 1

    def _build(self, s: generate.PassShape, half: tuple[bool, ...]) -> _Kernel:
        fn = _load(kernel_source(s, half), self.cache)
        sig = _signature(s.n_sources, half, s.period[1])
        self._ready(fn, sig, _compile_vectorised)
        terms = {ph: phase_terms(taps) for ph, taps in s.phases}
        extents = []
        for k in range(s.n_sources):
            mine = [t for ts in terms.values() for t in ts if t.slot == k]
            extents.append((min(t.dr for t in mine), max(t.dr for t in mine),
                            min(t.dc for t in mine), max(t.dc for t in mine)) if mine else (0, 0, 0, 0))
        return _Kernel(fn, s, terms, extents)

    def prepare(self, plan: Plan, dtype=np.float32) -> None:
        """Compile (or load from the disk cache) the kernels of ``plan`` before running it.

        ``dtype`` is the inputs' storage (float32, or float16 for half files).
        """
        half_inputs = set(plan.inputs) if np.dtype(dtype) == np.float16 else set()
        for ps in plan.passes:
            if isinstance(ps, ResamplePass):
                self.resample_kernel(ps.axis)
                continue
            if isinstance(ps, PointwisePass):
                self.pointwise_kernel(ps)
                continue
            self.kernel(ps, tuple(src in half_inputs for src in generate.sources(ps)))

    # ------------------------------------------------------------ resampling
    def resample_kernel(self, axis: int):
        """The compiled table-driven kernel of a :class:`ResamplePass` along ``axis`` (cached like the others)."""
        key = ("resample", axis)
        k = self._kernels.get(key)
        if k is None:
            fn = _load(resample_source(axis), self.cache)
            self._ready(fn, RESAMPLE_SIGNATURE)
            k = self._kernels[key] = fn
        return k

    def _resample(self, plan: Plan, ps: ResamplePass, src: np.ndarray) -> np.ndarray:
        """One :class:`ResamplePass` on a stored (H, W, C) float32 source; bands of output rows on the pool."""
        from pyramid_cli.exec.emulate import resample_table

        fn = self.resample_kernel(ps.axis)
        h, w, channels = src.shape
        idx, weights = resample_table(ps, plan.images[ps.source], np.float32)
        size = plan.images[ps.target].size
        out = np.empty(size + (channels,), dtype=np.float32)
        flat_out, flat_src = out.reshape(size[0], -1), src.reshape(h, -1)
        args = (flat_out, flat_src, np.ascontiguousarray(idx), np.ascontiguousarray(weights), channels)
        n = size[0]  # both kernels split their work by output rows
        if self.threads == 1 or out.size < SMALL or n < 2:
            fn(*args, 0, n)
            return out
        parts = min(n, self.threads * 2)
        bounds = [n * i // parts for i in range(parts + 1)]
        pool = self._workers()
        for f in [pool.submit(fn, *args, a, b) for a, b in zip(bounds, bounds[1:], strict=False) if a < b]:
            f.result()
        return out

    # ------------------------------------------------------------ running
    def run(self, plan: Plan, image) -> np.ndarray:
        """Execute ``plan`` on ``image`` (H, W) or (H, W, C); the logical pixels of the last output, float32."""
        return self.run_outputs(plan, image)[-1]

    def run_outputs(self, plan: Plan, images, dtype=np.float32) -> list[np.ndarray]:
        """Execute ``plan`` with one image per ``plan.inputs``; the logical pixels of every ``plan.outputs``.

        Parameters
        ----------
        plan : Plan
            Any plan (paper §3–§5 filters, written chains, pyramids, every border mode).
        images : ndarray or list of ndarray
            (H, W) or (H, W, C) arrays, any C, one per ``plan.inputs``; float32 or float16
            (read as is), anything else converted to float32.
        dtype : float32 or float16
            Output type; float16 is rounded to nearest even from the float32 result.

        Returns
        -------
        list of ndarray
            One per ``plan.outputs``, (H, W) for 2-D inputs, else (H, W, C).
        """
        dtype = np.dtype(dtype)
        if dtype not in OUT_DTYPES:
            raise ValueError(f"outputs are float32 or float16, not {dtype}")
        arrays = _inputs(plan, images)
        flat = arrays[0].ndim == 2
        arrays = [a[:, :, None] if flat else a for a in arrays]
        channels = arrays[0].shape[2]
        stored: dict[int, np.ndarray] = {}
        for k, a in zip(plan.inputs, arrays, strict=True):
            stored[k] = np.ascontiguousarray(a.view(np.uint16) if a.dtype == np.float16 else a)
        half = {k for k, a in zip(plan.inputs, arrays, strict=True) if a.dtype == np.float16}
        last_read = {}
        for i, ps in enumerate(plan.passes):
            for s in ps.sources():
                last_read[s] = i
        keep = set(plan.outputs)
        for i, ps in enumerate(plan.passes):
            if isinstance(ps, ResamplePass):
                src = stored[ps.source]
                if ps.source in half:
                    src = self._half_lut()[src]
                stored[ps.target] = self._resample(plan, ps, np.ascontiguousarray(src))
                if last_read[ps.source] == i and ps.source not in keep:
                    del stored[ps.source]
                continue
            srcs = generate.sources(ps)
            target = plan.images[ps.target]
            out = np.empty(target.stored + (channels,), dtype=np.float32)
            if isinstance(ps, PointwisePass):
                self._run_pointwise(ps, out, [self._float(stored[s]) if s in half else stored[s] for s in srcs])
            else:
                kern = self.kernel(ps, tuple(s in half for s in srcs))
                self._run_pass(plan, ps, kern, out, [stored[s] for s in srcs], srcs)
            stored[ps.target] = out
            for s in srcs:
                if last_read[s] == i and s not in keep:
                    del stored[s]
        results = []
        for k in plan.outputs:
            im = plan.images[k]
            t, le = im.guard[0], im.guard[1]
            a = stored[k]
            if k in half:
                a = a.view(np.float16)
            a = a[t:t + im.size[0], le:le + im.size[1]]
            if flat:
                a = a[:, :, 0]
            if k in plan.inputs:  # an input read back as given (level 0 of a pyramid): a copy
                a = np.array(a, dtype=np.float32)
            results.append(a.astype(dtype) if dtype != a.dtype else np.ascontiguousarray(a))
        return results

    def pointwise_kernel(self, ps: PointwisePass):
        """The compiled kernel of a pointwise pass's op and parameter (:func:`pointwise_source`)."""
        key = ("pointwise", ps.op, ps.param)
        fn = self._kernels.get(key)
        if fn is None:
            fn = _load(pointwise_source(ps.op, ps.param), self.cache)
            self._ready(fn, "void(" + ", ".join(["float32[::1]"] * (len(ps.srcs) + 1) + ["int64"] * 2) + ")")
            self._kernels[key] = fn
        return fn

    def _run_pointwise(self, ps: PointwisePass, out: np.ndarray, srcs: list[np.ndarray]) -> None:
        """Every element of ``out`` by the op, in bands on the thread pool when large."""
        fn = self.pointwise_kernel(ps)
        flat = out.reshape(-1)
        args = [np.ascontiguousarray(a, dtype=np.float32).reshape(-1) for a in srcs]
        n = flat.size
        if self.threads == 1 or n < SMALL:
            fn(flat, *args, 0, n)
            return
        parts = self.threads * 2
        bounds = [n * i // parts for i in range(parts + 1)]
        futures = [self._workers().submit(fn, flat, *args, a, b) for a, b in zip(bounds, bounds[1:], strict=False)]
        for f in futures:
            f.result()

    def _float(self, a: np.ndarray) -> np.ndarray:
        """A float16 input (stored as uint16) as float32, through the table."""
        return self._half_lut()[a]

    def _run_pass(self, plan: Plan, ps, kern: _Kernel, out: np.ndarray, srcs: list[np.ndarray],
                  indices: list[int]) -> None:
        (pr, pc), (sr, sc) = ps.period, ps.stride
        H, W = out.shape[:2]
        target = plan.images[ps.target]
        yoff, xoff = target.guard[0] - pr - 1, target.guard[1] - pc - 1
        imgs = [plan.images[s] for s in indices]
        offs = [(im.guard[0] - 1, im.guard[1] - 1) for im in imgs]
        # output groups: rows P·m + i + yoff (i = 1..P) inside 0..H−1; columns per phase j
        m_first, m_last = _ceil_div(-pr - yoff, pr), (H - 2 - yoff) // pr
        cols = [(_ceil_div(-(j + xoff), pc), (W - 1 - j - xoff) // pc + 1) for j in range(1, pc + 1)]
        # interior: every read of every source inside its stored extent
        i_lo, i_hi, c_lo, c_hi = m_first, m_last + 1, -(1 << 60), 1 << 60
        for (dr0, dr1, dc0, dc1), (ro, co), a in zip(kern.extents, offs, srcs, strict=True):
            i_lo = max(i_lo, _ceil_div(-(dr0 + ro), sr))
            i_hi = min(i_hi, (a.shape[0] - 1 - dr1 - ro) // sr + 1)
            c_lo = max(c_lo, _ceil_div(-(dc0 + co), sc))
            c_hi = min(c_hi, (a.shape[1] - 1 - dc1 - co) // sc + 1)
        # the interior covers the same column groups in every phase (the kernel's fused loop)
        c_lo, c_hi = max([c_lo] + [lo for lo, _ in cols]), min([c_hi] + [hi for _, hi in cols])
        inner = [(c_lo, c_hi)] * pc
        if i_lo >= i_hi or c_lo >= c_hi or out.size <= TINY:  # one window: fewer calls beat fewer copies
            self._window_call(kern, out, srcs, imgs, offs, (m_first, m_last + 1), cols, ps, yoff, xoff)
            return
        self._window_call(kern, out, srcs, imgs, offs, (m_first, i_lo), cols, ps, yoff, xoff)
        self._window_call(kern, out, srcs, imgs, offs, (i_hi, m_last + 1), cols, ps, yoff, xoff)
        left = [(lo, a) for (lo, _), (a, _) in zip(cols, inner, strict=True)]
        right = [(b, hi) for (_, hi), (_, b) in zip(cols, inner, strict=True)]
        self._window_call(kern, out, srcs, imgs, offs, (i_lo, i_hi), left, ps, yoff, xoff)
        self._window_call(kern, out, srcs, imgs, offs, (i_lo, i_hi), right, ps, yoff, xoff)
        self._call(kern, out, srcs, (i_lo, i_hi), inner, offs, yoff, xoff, parallel=True)

    def _window_call(self, kern: _Kernel, out, srcs, imgs, offs, rows: tuple[int, int], cols, ps, yoff, xoff):
        """Groups ``rows`` × ``cols`` through windows of each source gathered with its border mode."""
        if rows[0] >= rows[1] or all(lo >= hi for lo, hi in cols):
            return
        sr, sc = ps.stride
        col_used = [(lo, hi) for lo, hi in cols if lo < hi]
        n_lo, n_hi = min(lo for lo, _ in col_used), max(hi for _, hi in col_used) - 1
        wins, woffs = [], []
        for (dr0, dr1, dc0, dc1), (ro, co), a, im in zip(kern.extents, offs, srcs, imgs, strict=True):
            r0, r1 = sr * rows[0] + dr0 + ro, sr * (rows[1] - 1) + dr1 + ro
            c0, c1 = sc * n_lo + dc0 + co, sc * n_hi + dc1 + co
            wins.append(_window(a, (r0, r1), (c0, c1), im.border))
            woffs.append((ro - r0, co - c0))
        self._call(kern, out, wins, rows, cols, woffs, yoff, xoff, parallel=False)

    def _call(self, kern: _Kernel, out, srcs, rows, cols, offs, yoff, xoff, parallel: bool) -> None:
        extra = [self._half_lut()] if any(a.dtype == np.uint16 for a in srcs) else []
        extra.append(out.shape[2])
        out = out.reshape(out.shape[0], -1)
        srcs = [a.reshape(a.shape[0], -1) for a in srcs]
        tail = [yoff, xoff] + [v for lo_hi in cols for v in lo_hi] + [v for o in offs for v in o]
        m0, m1 = rows
        floats = (m1 - m0) * kern.shape.period[0] * out.shape[1]  # out is (rows, columns·C) here
        if not parallel or self.threads == 1 or floats < SMALL:
            kern.fn(out, *srcs, *extra, m0, m1, *tail)
            return
        n = min(m1 - m0, self.threads * 2)
        bounds = [m0 + (m1 - m0) * i // n for i in range(n + 1)]
        pool = self._workers()
        futures = [pool.submit(kern.fn, out, *srcs, *extra, a, b, *tail)
                   for a, b in zip(bounds, bounds[1:], strict=False) if a < b]
        for f in futures:
            f.result()

    def _workers(self) -> ThreadPoolExecutor:
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="pyramid-cpu")
        return self._pool

    def _half_lut(self) -> np.ndarray:
        if self._lut is None:
            self._lut = np.arange(1 << 16, dtype=np.uint16).view(np.float16).astype(np.float32)
        return self._lut


def _inputs(plan: Plan, images) -> list[np.ndarray]:
    from pyramid_cli.exec.emulate import plan_inputs

    return plan_inputs(plan, images)


__all__ = ["CPUExecutor", "available", "cache_dir", "default_threads", "kernel_source", "phase_terms", "Term",
           "CACHE_ENV", "INSTALL_HINT"]
