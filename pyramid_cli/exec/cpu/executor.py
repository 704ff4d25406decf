"""The compiled CPU executor: a :class:`~pyramid_cli.plan.model.Plan` as generated numba kernels.

Where there is no GPU, the GL executor runs on Mesa's llvmpipe and pays for upload,
read-back and power-of-two textures (docs/design.md §6). This executor runs the same passes
on the CPU without any of that: every pass of a plan becomes one numba function
generated from the pass's taps (:mod:`pyramid_cli.exec.cpu.codegen`), so the paper's
bilinear taps (§3–§5) are unrolled into the texel reads they stand for, compiled once
per machine (:mod:`pyramid_cli.exec.cpu.compile`).

Borders without copies: a pass's output is split into an *interior*, whose reads all fall
inside every source's stored extent and which the kernel reads directly (no bounds checks,
no padded copy of the source), and the border strips around it (a few rows and columns).
For each strip the executor gathers the small window of source texels it reads, folded
through the border mode, and runs the same kernel on that window. The interior is split
into bands of rows run by a thread pool (the kernels release the GIL).

Kernels are keyed by the pass's canonical :class:`~pyramid_cli.plan.shapes.PassShape`
(taps with image indices replaced by source slots, the key of the GL program cache too)
alone: the sources' storage (float32, or float16 inputs converted row by row through a
65536-entry table, so a half image is never copied to float32 whole) is an argument of the
kernel, so a plan with a half input loads no more kernels than the same plan on float32.
Every resampling pass shares one kernel, and every pointwise pass another.

float64: :meth:`CPUExecutor.run_outputs` with ``dtype=float64`` computes in float64 throughout (inputs,
intermediates, weights, sums) on the same kernels generated at that width
(:func:`~pyramid_cli.exec.cpu.codegen.work_type`), cached beside the float32 ones under their own digests and
compiled or loaded only when a float64 run first needs them: a float32 run loads exactly the float32 kernels.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from pyramid_cli.core.errors import BackendError
from pyramid_cli.core.machine import usable_cores
from pyramid_cli.exec.cpu import aot
from pyramid_cli.exec.cpu.codegen import (
    ENCODE8_SIGNATURE,
    POINTWISE_CODES,
    encode8_source,
    kernel_source,
    phase_terms,
    pointwise_signature,
    pointwise_source,
    resample_signature,
    resample_source,
    signature,
)
from pyramid_cli.exec.cpu.compile import (
    cache_dir,
    compile_plain,
    compile_vectorised,
    ensure_compiled,
    installed,
    jit_kernels,
    load,
    loaded,
    on_disk,
    source_digest,
    write_source,
)
from pyramid_cli.exec.emulate import plan_inputs, resample_table
from pyramid_cli.exec.gather import window
from pyramid_cli.plan.model import Pass, Plan, PointwisePass, ResamplePass
from pyramid_cli.plan.shapes import PassShape, shape, sources

SMALL = 1 << 20              # output floats below which a pass runs on the calling thread
TINY = 1 << 14               # output floats up to which a pass runs as one call on one gathered window
OUT_DTYPES = (np.dtype(np.float32), np.dtype(np.float16), np.dtype(np.float64))


def default_threads() -> int:
    """The cores this process may use: its affinity, within its cgroups' CPU quota
    (:func:`pyramid_cli.core.machine.usable_cores`)."""
    return usable_cores()


@dataclass
class Kernel:
    """A compiled kernel of one pass shape, with what its caller needs to place its reads."""


    fn: Callable[..., None]  # the numba dispatcher, compiled for one signature
    shape: PassShape
    terms: dict      # phase → list[Term]
    extents: list    # per slot: (dr_min, dr_max, dc_min, dc_max)
    digest: str      # of its source: the file it is cached under


def _calls(fn: Callable[..., None], calls: list[list]) -> None:
    """``fn`` on each argument list in turn (the border strips of a pass, one task on the pool)."""
    for args in calls:
        fn(*args)


_TABLES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _codes_table(codes: np.ndarray) -> np.ndarray:
    """``codes`` as float32, padded to the 65536 entries a uint16 index may reach (once per table object)."""
    hit = _TABLES.get(id(codes))
    if hit is not None and hit[0] is codes:
        return hit[1]
    table = np.zeros(1 << 16, np.float32)
    table[:len(codes)] = np.asarray(codes, np.float32)
    if len(_TABLES) > 8:
        _TABLES.clear()
    _TABLES[id(codes)] = (codes, table)
    return table


def _ceil_div(a: int, b: int) -> int:
    return -(-a // b)


class CPUExecutor:
    """Runs plans as generated numba kernels on the CPU (paper §3–§5 passes, docs/design.md §5).

    Parameters
    ----------
    threads : int, optional
        Worker threads for the large passes; default: the cores this process may use.
        ``1`` runs everything on the calling thread.
    cache : str or Path, optional
        Folder of generated kernel sources and numba's compiled code; default
        :func:`~pyramid_cli.exec.cpu.compile.cache_dir`.

    Attributes
    ----------
    compiles : int
        Kernels compiled by this executor (cache misses: neither in this process nor on disk).
    cache_loads : int
        Kernels loaded from the disk cache (compiled by an earlier process).

    It is an :class:`~pyramid_cli.exec.base.Executor`, with the public surface of
    :class:`~pyramid_cli.exec.gl.GLExecutor` where it makes sense: :meth:`run`, :meth:`run_outputs`,
    :meth:`prepare`, :meth:`close`, and it is a context manager. It holds no image memory between runs.
    """

    backend = "cpu"
    strategy = "fused"  # one pass per written step: each pass streams its whole target through memory
    work_dtype = np.dtype(np.float32)
    max_texture_size = None  # no limit on an image's sides
    host_textures = False    # no textures: it holds the pictures and nothing else
    writes_into = True       # run_outputs(..., out=)

    @staticmethod
    def texture_bytes(extent: tuple[int, int]) -> int:
        """No textures beside the pictures: 0."""
        return 0

    def __init__(self, threads: int | None = None, cache: str | Path | None = None):
        ok, why = installed()
        if not ok:
            raise BackendError(why)
        self.threads = max(1, int(threads)) if threads else default_threads()
        self.cache = Path(cache) if cache is not None else cache_dir()
        self.compiles = 0
        self.cache_loads = 0
        self._kernels: dict = {}   # pass shape (or "resample", "pointwise") → compiled kernel
        self._by_pass: dict[tuple[int, str], tuple] = {}   # (id(pass), working type) → (pass, Kernel)
        self._pool: ThreadPoolExecutor | None = None
        self._lut: np.ndarray | None = None
        self._table: np.ndarray | None = None  # a run's table of codes (run_outputs' ``codes``), 65536 entries
        self._jit: dict[str, str] = {}  # digest → numba signature of the kernels run through numba (not ahead of time)
        self.building = 0  # kernels handed to a builder process at close() (:mod:`pyramid_cli.exec.cpu.aot`)

    # ------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Stop the worker threads (the executor can be used again afterwards), and have the kernels that ran
        through numba built ahead of time for the next process (:func:`pyramid_cli.exec.cpu.aot.spawn`)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
        self._pool = None
        if self._jit:
            sources = jit_kernels()
            todo = [(d, sources[d], sig) for d, sig in self._jit.items() if d in sources]
            self.building += aot.spawn(self.cache, todo)
            self._jit.clear()

    def __enter__(self) -> CPUExecutor:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def name(self) -> str:
        """What runs the plans, for messages: ``cpu (numba …, N threads)``."""
        return f"cpu (numba {numba_version()}, {self.threads} thread(s))"

    def kernel_digests(self, plan: Plan, dtype=np.float32) -> set[str]:
        """The distinct compiled kernels ``plan`` runs on, by the digest of their source: what a first run in a
        process loads from the disk cache (or compiles), whatever the inputs store (float32 or float16); the
        float64 kernels where ``dtype`` is float64 (a float64 run)."""
        t = _work(dtype)
        digests = set()
        for ps in plan.passes:
            hit = self._by_pass.get((id(ps), t))
            digests.add(hit[1].digest if hit is not None and hit[0] is ps else kernel_digest(ps, t))
        return digests

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """How many of ``plan``'s kernels are neither loaded in this process nor compiled on disk yet (numba's cache or
        ahead of time: what a first run on a machine compiles, about a second each). ``dtype``: float64 counts the
        float64 kernels of a float64 run; float32 and float16 (the inputs' storage) the float32 ones."""
        return sum(1 for d in self.kernel_digests(plan, dtype)
                   if not loaded(d) and not on_disk(self.cache, d) and not aot.ready(self.cache, d))

    def info(self) -> dict:
        """What runs the plans: numba's version, threads and the cache folder."""
        return {"renderer": f"numba {numba_version()} ({self.threads} thread(s))", "threads": self.threads,
                "cache": str(self.cache)}

    # ------------------------------------------------------------ kernels
    def kernel(self, ps: Pass, dtype=np.float32) -> Kernel:
        """The compiled kernel of a pass's shape (for float32 and float16 sources alike; at float64 where
        ``dtype``, the working type, is float64)."""
        t = _work(dtype)
        hit = self._by_pass.get((id(ps), t))
        if hit is not None and hit[0] is ps:  # the shape of a pass run before (exact Fractions: not free)
            return hit[1]
        s = shape(ps)
        k = self._kernels.get((s, t))
        if k is None:
            k = self._kernels[(s, t)] = self._build(s, t)
        if len(self._by_pass) > 4096:
            self._by_pass.clear()
        self._by_pass[(id(ps), t)] = (ps, k)  # the pass is held, so its id is not reused while the entry lives
        return k

    def _ready(self, fn, sig: str, digest: str, compile_=compile_plain) -> None:
        """Compile ``fn`` for ``sig`` once (or load it from the disk cache), counting which it was; a kernel run
        through numba is noted for its ahead-of-time build (:meth:`close`)."""
        if hasattr(fn, "signatures"):
            self._jit[digest] = sig
        done = ensure_compiled(fn, sig, compile_)
        if done == "loaded":
            self.cache_loads += 1
        elif done == "compiled":
            self.compiles += 1

    def _build(self, s: PassShape, t: str = "float32") -> Kernel:
        source = _pass_source(s, t)
        fn = load(source, self.cache)
        self._ready(fn, signature(s.n_sources, s.period[1], t), source_digest(source), compile_vectorised)
        terms = {ph: phase_terms(taps) for ph, taps in s.phases}
        extents = []
        for k in range(s.n_sources):
            mine = [t for ts in terms.values() for t in ts if t.slot == k]
            extents.append((min(t.dr for t in mine), max(t.dr for t in mine),
                            min(t.dc for t in mine), max(t.dc for t in mine)) if mine else (0, 0, 0, 0))
        return Kernel(fn, s, terms, extents, source_digest(source))

    def prepare(self, plan: Plan, dtype=np.float32) -> None:
        """Compile (or load from the disk cache) the kernels of ``plan`` before running it.

        ``dtype`` is the inputs' storage (float32, or float16 for half files; the same kernels serve both), or
        float64 for a float64 run (its own kernels).
        """
        t = _work(dtype)
        for ps in plan.passes:
            if isinstance(ps, ResamplePass):
                self.resample_kernel(t)
            elif isinstance(ps, PointwisePass):
                self.pointwise_kernel(t)
            else:
                self.kernel(ps, t)

    # ------------------------------------------------------------ resampling
    def resample_kernel(self, dtype=np.float32) -> Callable[..., None]:
        """The compiled table-driven kernel of every :class:`ResamplePass`, either axis (cached like the others),
        at the working type ``dtype`` (float32 or float64)."""
        key = ("resample", _work(dtype))
        k = self._kernels.get(key)
        if k is None:
            source = resample_source(key[1])
            fn = load(source, self.cache)
            self._ready(fn, resample_signature(key[1]), source_digest(source))
            k = self._kernels[key] = fn
        return k

    def _resample(self, plan: Plan, ps: ResamplePass, src: np.ndarray) -> np.ndarray:
        """One :class:`ResamplePass` on a stored (H, W, C) float32 (or float64) source; bands of output rows on
        the pool."""
        fn = self.resample_kernel(src.dtype)
        h, w, channels = src.shape
        idx, weights = resample_table(ps, plan.images[ps.source], src.dtype)
        size = plan.images[ps.target].size
        out = np.empty(size + (channels,), dtype=src.dtype)
        flat_out, flat_src = out.reshape(size[0], -1), src.reshape(h, -1)
        args = (flat_out, flat_src, np.ascontiguousarray(idx), np.ascontiguousarray(weights), channels)
        n = size[0]  # both kernels split their work by output rows
        if self.threads == 1 or out.size < SMALL or n < 2:
            fn(*args, 0, n, ps.axis)
            return out
        parts = min(n, self.threads * 2)
        bounds = [n * i // parts for i in range(parts + 1)]
        pool = self._workers()
        for f in [pool.submit(fn, *args, a, b, ps.axis) for a, b in zip(bounds, bounds[1:], strict=False) if a < b]:
            f.result()
        return out

    # ------------------------------------------------------------ running
    def run(self, plan: Plan, image) -> np.ndarray:
        """Execute ``plan`` on ``image`` (H, W) or (H, W, C); the logical pixels of the last output, float32."""
        return self.run_outputs(plan, image)[-1]

    def run_outputs(self, plan: Plan, images, dtype=np.float32, codes: np.ndarray | None = None,
                    out: np.ndarray | None = None) -> list[np.ndarray]:
        """Execute ``plan`` with one image per ``plan.inputs``; the logical pixels of every ``plan.outputs``.

        Parameters
        ----------
        plan : Plan
            Any plan (paper §3–§5 filters, written chains, pyramids, every border mode).
        images : ndarray or list of ndarray
            (H, W) or (H, W, C) arrays, any C, one per ``plan.inputs``; float32 or float16
            (read as is), anything else converted to float32; every one converted to float64 for a
            float64 run.
        dtype : float32, float16 or float64
            Output type; float16 is rounded to nearest even from the float32 result. float64 computes
            in float64 throughout, on the float64 kernels.
        codes : ndarray, optional
            The float32 value of every code (256 or 65536 of them): uint8 and uint16 inputs are then codes, read
            through it wherever a pass reads them (exactly as if ``codes[input]`` were given; the table takes the
            place of the float16 one, so 8-bit rows need not be decoded to floats first). ``codes[0]`` must be 0
            (a zero border reads code 0, as it reads the float16 0); float32 runs only.
        out : ndarray, optional
            The last output's pixels are written into it (its shape, ``dtype``): by the last pass itself where
            the output is a pass's whole target and ``out`` is C-contiguous, else copied there. The tile
            scheduler's bands are made so in their place in the image's buffer (:mod:`pyramid_cli.exec.tiles`).

        Returns
        -------
        list of ndarray
            One per ``plan.outputs``, (H, W) for 2-D inputs, else (H, W, C); the last is ``out`` where given.
        """
        dtype = np.dtype(dtype)
        if dtype not in OUT_DTYPES:
            raise ValueError(f"outputs are float32, float16 or float64, not {dtype}")
        if codes is not None:
            if dtype == np.float64:
                raise ValueError("codes are read in float32 runs only")
            if codes[0] != 0:
                raise ValueError("a table of codes reads 0 for code 0 (the zero border's)")
            self._table = _codes_table(codes)  # read where float16 bit patterns are read through theirs
        try:
            results = self._run_outputs(plan, images, dtype, out)
        finally:
            self._table = None
        if out is not None and results[-1] is not out:
            out[...] = results[-1]
            results[-1] = out
        return results

    def _run_outputs(self, plan: Plan, images, dtype, into: np.ndarray | None = None) -> list[np.ndarray]:
        wt = np.dtype(_work(dtype))  # the working type
        arrays = plan_inputs(plan, images, np.float64 if wt == np.float64 else None,
                             codes=self._table is not None)
        flat = arrays[0].ndim == 2
        arrays = [a[:, :, None] if flat else a for a in arrays]
        channels = arrays[0].shape[2]
        stored: dict[int, np.ndarray] = {}
        for k, a in zip(plan.inputs, arrays, strict=True):
            stored[k] = np.ascontiguousarray(a.view(np.uint16) if a.dtype == np.float16 else a)
        half = {k for k, a in zip(plan.inputs, arrays, strict=True) if a.dtype != wt}  # read through the table
        released = plan.releases()
        spare: dict[tuple, list[np.ndarray]] = {}  # this run's dead intermediates, by shape, for later targets
        written = None  # the output made in ``into``

        def retire(k: int) -> None:
            a = stored.pop(k)
            if k not in plan.inputs and a.dtype == wt and a is not into:
                spare.setdefault(a.shape, []).append(a)

        for i, ps in enumerate(plan.passes):
            if isinstance(ps, ResamplePass):
                src = stored[ps.source]
                if ps.source in half:
                    src = self._half_lut()[src]
                stored[ps.target] = self._resample(plan, ps, np.ascontiguousarray(src))
                for s in released[i]:
                    retire(s)
                continue
            srcs = sources(ps)
            target = plan.images[ps.target]
            # a dead intermediate of the same shape (the blur's way up reuses its way down): fresh memory costs
            # a page fault per page at its first write, about as much as the pass's own stores
            shape_ = target.stored + (channels,)
            free = spare.get(shape_)
            if (into is not None and ps.target == plan.outputs[-1] and into.shape == shape_
                    and into.dtype == wt == dtype and not any(target.guard) and into.flags.c_contiguous):
                out, written = into, ps.target  # the caller's array: no copy of the output after
            else:
                out = free.pop() if free else np.empty(shape_, dtype=wt)
            if isinstance(ps, PointwisePass):
                self._run_pointwise(ps, out, [self._float(stored[s]) if s in half else stored[s] for s in srcs])
            else:
                kern = self.kernel(ps, wt)
                self._run_pass(plan, ps, kern, out, [stored[s] for s in srcs], srcs)
            stored[ps.target] = out
            for s in released[i]:
                retire(s)
        results = []
        for k in plan.outputs:
            if k == written and into is not None:
                results.append(into)
                continue
            im = plan.images[k]
            t, le = im.guard[0], im.guard[1]
            a = stored[k]
            if k in half:
                a = self._half_lut()[a] if self._table is not None else a.view(np.float16)
            a = a[t:t + im.size[0], le:le + im.size[1]]
            if flat:
                a = a[:, :, 0]
            if k in plan.inputs:  # an input read back as given (level 0 of a pyramid): a copy
                a = np.array(a, dtype=wt)
            results.append(a.astype(dtype) if dtype != a.dtype else np.ascontiguousarray(a))
        return results

    def pointwise_kernel(self, dtype=np.float32) -> Callable[..., None]:
        """The compiled kernel of every pointwise op (:func:`pointwise_source`: the op and its parameter are
        arguments), at the working type ``dtype`` (float32 or float64)."""
        key = ("pointwise", _work(dtype))
        fn = self._kernels.get(key)
        if fn is None:
            source = pointwise_source(key[1])
            fn = load(source, self.cache)
            self._ready(fn, pointwise_signature(key[1]), source_digest(source))
            self._kernels[key] = fn
        return fn

    def encode8(self) -> Callable[..., None]:
        """The compiled 8-bit encoding by table (:func:`encode8_source`), loaded once: what image I/O's exact sRGB
        encoding runs on in a run with a CPU executor (:func:`pyramid_cli.imageio.colour.use_srgb8_loop`)."""
        key = ("encode8", "float32")
        fn = self._kernels.get(key)
        if fn is None:
            source = encode8_source()
            fn = load(source, self.cache)
            self._ready(fn, ENCODE8_SIGNATURE, source_digest(source))
            self._kernels[key] = fn
        return fn

    def _run_pointwise(self, ps: PointwisePass, out: np.ndarray, srcs: list[np.ndarray]) -> None:
        """Every element of ``out`` by the op, in bands on the thread pool when large."""
        wt = out.dtype
        fn = self.pointwise_kernel(wt)
        flat = out.reshape(-1)
        operands = [np.ascontiguousarray(a, dtype=wt).reshape(-1) for a in srcs]
        operands += [_NO_FLOAT_1D[wt]] * (3 - len(operands))  # operands the op does not read
        args = [*operands, wt.type(float(ps.param)), POINTWISE_CODES[ps.op]]
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

    def _run_pass(self, plan: Plan, ps, kern: Kernel, out: np.ndarray, srcs: list[np.ndarray],
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
        # the interior first, on the pool: its threads take the first touch of the fresh output's pages (the
        # kernel zeroes them on first write); a border strip first would fault every page of a column strip on one
        # thread. The strips' windows are gathered here meanwhile, and the strips computed in one more task behind
        # the interior's: computed here, they took a core from the interior (a warm 4K blur lost its gain); as a
        # task each, they cost more in hand-overs than they saved (a 16K Deep Zoom's 32-row bands: 0.3 CPU-s).
        left = [(lo, a) for (lo, _), (a, _) in zip(cols, inner, strict=True)]
        right = [(b, hi) for (_, hi), (_, b) in zip(cols, inner, strict=True)]
        pending = self._call(kern, out, srcs, (i_lo, i_hi), inner, offs, yoff, xoff, parallel=True)
        try:
            strips = [self._window_args(kern, out, srcs, imgs, offs, rows, strip, ps, yoff, xoff)
                      for rows, strip in (((m_first, i_lo), cols), ((i_hi, m_last + 1), cols), ((i_lo, i_hi), left),
                                          ((i_lo, i_hi), right))]
            strips = [a for a in strips if a is not None]
            if pending:
                pending.append(self._workers().submit(_calls, kern.fn, strips))
            else:
                _calls(kern.fn, strips)
        finally:
            wait(pending)  # nothing still writes ``out`` when this returns, whatever was raised
        for f in pending:
            f.result()

    def _window_call(self, kern: Kernel, out, srcs, imgs, offs, rows: tuple[int, int], cols, ps, yoff, xoff):
        """Groups ``rows`` × ``cols`` through windows of each source gathered with its border mode."""
        args = self._window_args(kern, out, srcs, imgs, offs, rows, cols, ps, yoff, xoff)
        if args is not None:
            kern.fn(*args)

    def _window_args(self, kern: Kernel, out, srcs, imgs, offs, rows: tuple[int, int], cols, ps, yoff, xoff):
        """The kernel's arguments for :meth:`_window_call` (the windows gathered), or None for no groups."""
        if rows[0] >= rows[1] or all(lo >= hi for lo, hi in cols):
            return None
        sr, sc = ps.stride
        col_used = [(lo, hi) for lo, hi in cols if lo < hi]
        n_lo, n_hi = min(lo for lo, _ in col_used), max(hi for _, hi in col_used) - 1
        wins, woffs = [], []
        for (dr0, dr1, dc0, dc1), (ro, co), a, im in zip(kern.extents, offs, srcs, imgs, strict=True):
            r0, r1 = sr * rows[0] + dr0 + ro, sr * (rows[1] - 1) + dr1 + ro
            c0, c1 = sc * n_lo + dc0 + co, sc * n_hi + dc1 + co
            wins.append(window(a, (r0, r1), (c0, c1), im.border))
            woffs.append((ro - r0, co - c0))
        head, tail = self._args(out, wins, cols, woffs, yoff, xoff)
        return [*head, rows[0], rows[1], *tail]

    def _args(self, out, srcs, cols, offs, yoff, xoff) -> tuple[list, list]:
        """A kernel's arguments (see :func:`kernel_source`) before and after the output groups ``m0, m1``."""
        # bit k: slot k is uint16 (float16 bits or codes), bit 16 + k: uint8 codes (float32 runs only)
        half = sum(1 << k if a.dtype == np.uint16 else 1 << (16 + k) for k, a in enumerate(srcs) if a.dtype.kind == "u")
        none = _NO_FLOAT[out.dtype]
        extra = [self._half_lut() if half else _NO_FLOAT_1D[out.dtype], half, out.shape[2]]
        out = out.reshape(out.shape[0], -1)
        flat = [a.reshape(a.shape[0], -1) for a in srcs]
        srcs = [v for a in flat for v in ((none, a, _NO_U8) if a.dtype == np.uint16 else (none, _NO_U16, a)
                                          if a.dtype == np.uint8 else (a, _NO_U16, _NO_U8))]
        tail = [yoff, xoff] + [v for lo_hi in cols for v in lo_hi] + [v for o in offs for v in o]
        return [out, *srcs, *extra], tail

    def _call(self, kern: Kernel, out, srcs, rows, cols, offs, yoff, xoff, parallel: bool) -> list[Future]:
        """The kernel over output groups ``rows`` × ``cols``: here, or where ``parallel`` and the work is large
        enough, in bands of rows on the pool, returning their futures for the caller to wait on."""
        head, tail = self._args(out, srcs, cols, offs, yoff, xoff)
        m0, m1 = rows
        floats = (m1 - m0) * kern.shape.period[0] * head[0].shape[1]  # head[0]: out as (rows, columns·C)
        if not parallel or self.threads == 1 or floats < SMALL:
            kern.fn(*head, m0, m1, *tail)
            return []
        n = min(m1 - m0, self.threads * 2)
        bounds = [m0 + (m1 - m0) * i // n for i in range(n + 1)]
        pool = self._workers()
        return [pool.submit(kern.fn, *head, a, b, *tail) for a, b in zip(bounds, bounds[1:], strict=False) if a < b]

    def _workers(self) -> ThreadPoolExecutor:
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="pyramid-cpu")
        return self._pool

    def _half_lut(self) -> np.ndarray:
        """What uint16 inputs are read through: float16 bit patterns, or the run's table of codes."""
        if self._table is not None:
            return self._table
        if self._lut is None:
            self._lut = np.arange(1 << 16, dtype=np.uint16).view(np.float16).astype(np.float32)
        return self._lut


# placeholders for the arguments a call does not use (a source's other storage, an op's missing operands), keyed
# by dtype (not its ``.name``: numpy computes that in Python, a few µs a call, and the band engine makes thousands)
_NO_FLOAT = {np.dtype(t): np.zeros((1, 1), t) for t in ("float32", "float64")}
_NO_U16 = np.zeros((1, 1), np.uint16)
_NO_U8 = np.zeros((1, 1), np.uint8)
_NO_FLOAT_1D = {np.dtype(t): np.zeros(1, t) for t in ("float32", "float64")}


def build_ahead(plan: Plan, cache: str | Path | None = None) -> int:
    """Have the float32 kernels of ``plan`` (float16 inputs run on them too) and the 8-bit encoding loop
    (:meth:`CPUExecutor.encode8`, which every 8-bit sRGB output of a CPU run calls) built ahead of time for later
    processes where they are not yet (:func:`pyramid_cli.exec.cpu.aot.spawn`), without importing numba here: ``auto``
    ran this job on GL, partly because the CPU executor would first have imported numba; next time it weighs the
    CPU executor without that, and runs it without numba. Returns how many kernels a builder was started for."""
    folder = Path(cache) if cache is not None else cache_dir()
    if aot.folder(folder) is None:
        return 0
    kernels: dict[str, tuple[str, str]] = {}
    for source, sig in [*(_kernel_text(ps, "float32") for ps in plan.passes), (encode8_source(), ENCODE8_SIGNATURE)]:
        digest = source_digest(source)
        if digest not in kernels and not aot.ready(folder, digest):
            kernels[digest] = (source, sig)
    try:
        todo = [(d, str(write_source(folder, d, src)), sig) for d, (src, sig) in kernels.items()]
    except OSError:
        return 0
    return aot.spawn(folder, todo)


@lru_cache(maxsize=1)
def numba_version() -> str:
    """numba's version, where it is not imported (ahead-of-time kernels run without it) from the version file in
    its package folder (under 2 ms), else from its installed metadata (``importlib.metadata`` took 25–30 ms here:
    its import and a scan of every installed distribution)."""
    mod = sys.modules.get("numba")
    if mod is not None:
        return mod.__version__
    import importlib.util
    import re

    spec = importlib.util.find_spec("numba")  # finds the package without importing it
    if spec is None:
        return "?"
    try:
        text = Path(spec.origin or "").with_name("_version.py").read_text()
    except OSError:
        text = ""
    found = re.search(r'"version":\s*"([^"]+)"', text)  # versioneer's version_json
    if found:
        return found.group(1)
    from importlib import metadata

    try:
        return metadata.version("numba")
    except metadata.PackageNotFoundError:
        return "?"


def _work(dtype) -> str:
    """The kernels' working type of a run or a storage ``dtype``: float64 for float64, else float32 (float16
    sources run on the float32 kernels)."""
    return "float64" if np.dtype(dtype) == np.float64 else "float32"


@lru_cache(maxsize=256)
def _pass_source(s: PassShape, t: str) -> str:
    """The kernel source of pass shape ``s`` at working type ``t``, made once: :func:`kernel_digest` (``auto``'s
    count of kernels to load) and the executor's build both ask for it."""
    return kernel_source(s, t)


def _kernel_text(ps: Pass | ResamplePass | PointwisePass, t: str) -> tuple[str, str]:
    """The source and the numba signature of the kernel a pass runs on at working type ``t``: its shape's, or the
    one every resampling (pointwise) pass shares."""
    if isinstance(ps, ResamplePass):
        return resample_source(t), resample_signature(t)
    if isinstance(ps, PointwisePass):
        return pointwise_source(t), pointwise_signature(t)
    s = shape(ps)
    return _pass_source(s, t), signature(s.n_sources, s.period[1], t)


_digest = lru_cache(maxsize=256)(source_digest)  # auto's estimate asks for every pass of every job


def kernel_digest(ps: Pass | ResamplePass | PointwisePass, dtype=np.float32) -> str:
    """The digest of the source of the kernel a pass runs on: one per pass shape (float32 and float16 sources
    alike), one for every resampling pass, one for every pointwise pass; the float64 kernel's where ``dtype``
    is float64. Pure Python: numba is not imported."""
    return _digest(_kernel_text(ps, _work(dtype))[0])


__all__ = ["CPUExecutor", "Kernel", "OUT_DTYPES", "SMALL", "TINY", "build_ahead", "default_threads", "kernel_digest",
           "numba_version"]
