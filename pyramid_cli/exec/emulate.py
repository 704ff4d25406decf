"""The living definition of a :class:`~pyramid_cli.plan.model.Plan`: numpy, software bilinear.

It runs a plan exactly as the GL executor must (same coordinates, same clamping
to each texture's stored extent, same bilinear mixing), so tests can check the
planner without GL, and the GL executor against it. :class:`Emulator` is the same
behind the :class:`~pyramid_cli.exec.base.Executor` protocol (the session's executor
where neither GL nor numba is usable, and the tile scheduler's float64 reference).
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

import numpy as np

from pyramid_cli.core.border import Border, fold
from pyramid_cli.core.geometry import base_index
from pyramid_cli.plan.model import Image, Plan, PointwisePass, ResamplePass, Tap


def pointwise(op: str, srcs: list[np.ndarray], param: float | Fraction = 1.0) -> np.ndarray:
    """The formulas of :data:`pyramid_cli.plan.model.POINTWISE_OPS`, elementwise on arrays of one shape."""
    k = float(param)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if op == "mul":
            a, b = srcs
            return a * b
        if op == "pull_colour":
            a, b = srcs
            return np.where(b > 0, a * (np.minimum(1.0, k * b) / np.where(b > 0, b, 1.0)), 0.0)
        if op == "pull_weight":
            (a,) = srcs
            return np.minimum(1.0, k * a)
        if op == "divide":
            a, b = srcs
            return np.where(b > 0, a / np.where(b > 0, b, 1.0), 0.0)
        if op == "over":
            a, b, c = srcs
            return a + (1.0 - b) * c
        if op == "blend":
            a, b, c = srcs
            return c * a + (1.0 - c) * b
    raise ValueError(f"unknown pointwise op {op!r}")


def sample(src: np.ndarray, guard_lo: tuple[int, int], rows: np.ndarray, cols: np.ndarray,
           border: str = "clamp") -> np.ndarray:
    """Bilinear read of ``src`` (stored array) at logical 1-based fractional indices.

    Reads outside the stored extent resolve by ``border``: clamped to the texture, or
    (mirror, wrap, zero) each of the two neighbours per axis folded by the mode.
    """
    q = rows.astype(np.float64) - 1 + guard_lo[0]
    p = cols.astype(np.float64) - 1 + guard_lo[1]
    if border != "clamp":
        return _folded_sample(src, q, p, Border.parse(border))
    q = np.clip(q, 0, src.shape[0] - 1)
    p = np.clip(p, 0, src.shape[1] - 1)
    i0, j0 = np.floor(q).astype(int), np.floor(p).astype(int)
    a, b = q - i0, p - j0
    i1, j1 = np.minimum(i0 + 1, src.shape[0] - 1), np.minimum(j0 + 1, src.shape[1] - 1)
    extra = (slice(None),) * 2 + (None,) * (src.ndim - 2)
    a, b = a[:, None][extra], b[None, :][extra]
    return ((1 - a) * (1 - b) * src[_grid(i0, j0)] + (1 - a) * b * src[_grid(i0, j1)]
            + a * (1 - b) * src[_grid(i1, j0)] + a * b * src[_grid(i1, j1)])


def _grid(rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.ix_(rows, cols)`` for two integer index arrays, without its checks (a tenth of a small tiled run)."""
    return rows[:, None], cols[None, :]


def _folded_sample(src: np.ndarray, q: np.ndarray, p: np.ndarray, border: Border) -> np.ndarray:
    """Bilinear read at stored 0-based positions, each integer neighbour folded by ``border``."""
    i0, j0 = np.floor(q).astype(np.int64), np.floor(p).astype(np.int64)
    a, b = q - i0, p - j0
    rows = [fold(i0 + 1, src.shape[0], border), fold(i0 + 2, src.shape[0], border)]
    cols = [fold(j0 + 1, src.shape[1], border), fold(j0 + 2, src.shape[1], border)]
    padded = np.zeros((src.shape[0] + 1, src.shape[1] + 1) + src.shape[2:])
    padded[1:, 1:] = src  # folded index 0 reads zero
    extra = (slice(None),) * 2 + (None,) * (src.ndim - 2)
    a, b = a[:, None][extra], b[None, :][extra]
    return ((1 - a) * (1 - b) * padded[_grid(rows[0], cols[0])] + (1 - a) * b * padded[_grid(rows[0], cols[1])]
            + a * (1 - b) * padded[_grid(rows[1], cols[0])] + a * b * padded[_grid(rows[1], cols[1])])


def plan_inputs(plan: Plan, images, dtype=None, codes: bool = False) -> list[np.ndarray]:
    """The executors' check of a plan's inputs: one array per ``plan.inputs``, each (H, W) or (H, W, C) of
    the input image's size (its stored extent where it has a guard band: a tile's window), one channel layout;
    float32 and float16 arrays are kept (uint8 and uint16 ones too where ``codes``: codes the executor reads
    through its table), others made float32 (every one made ``dtype`` where it is given: a float64 run's inputs).

    Raises
    ------
    ValueError
        A wrong count, shape, size or channel layout (the executors' callers turn these into messages).
    """
    keep: tuple[np.dtype, ...] = (np.dtype(np.float32), np.dtype(np.float16)) if dtype is None else (np.dtype(dtype),)
    if codes:
        keep += (np.dtype(np.uint8), np.dtype(np.uint16))
    arrays = [a if isinstance(a, np.ndarray) and a.dtype in keep else np.asarray(a, dtype=keep[0])
              for a in (images if isinstance(images, (list, tuple)) else [images])]
    if len(arrays) != len(plan.inputs):
        raise ValueError(f"plan takes {len(plan.inputs)} input image(s), got {len(arrays)}")
    for k, a in zip(plan.inputs, arrays, strict=True):
        im = plan.images[k]
        if a.ndim not in (2, 3) or 0 in a.shape:
            raise ValueError(f"an image must be (H, W) or (H, W, C) with nonzero sizes, not {a.shape}")
        if any(im.guard):  # a window of a larger image (pyramid_cli.exec.tiles): its stored extent, guard included
            if tuple(a.shape[:2]) != tuple(im.stored):
                raise ValueError(f"plan input {k} stores {im.stored[0]}x{im.stored[1]} (rows x columns, guard "
                                 f"band {im.guard} included), image is {a.shape[0]}x{a.shape[1]}")
        elif tuple(a.shape[:2]) != tuple(im.size):
            raise ValueError(f"plan input {k} is {im.size[0]}x{im.size[1]} (rows x columns), image is "
                             f"{a.shape[0]}x{a.shape[1]}")
        if a.shape[2:] != arrays[0].shape[2:]:
            raise ValueError(f"all inputs must have one channel layout: {arrays[0].shape} and {a.shape}")
    return arrays


def run(plan: Plan, image: np.ndarray) -> np.ndarray:
    """Execute ``plan`` on ``image`` (H, W) or (H, W, C); returns the output's logical pixels, float64."""
    return _logical(plan, _execute(plan, image), plan.outputs[-1])


def _execute(plan: Plan, image: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray | None]:
    """``image``: one array, or one per ``plan.inputs``. Returns every image of the plan as stored (None
    where neither an input nor a pass's target)."""
    images = image if isinstance(image, (list, tuple)) else [image]
    assert len(images) == len(plan.inputs)
    stored: list[np.ndarray | None] = [None] * len(plan.images)
    for index, px in zip(plan.inputs, images, strict=True):
        stored[index] = np.asarray(px, dtype=np.float64)
    channels = _written(stored, plan.inputs[0]).shape[2:]
    for ps in plan.passes:
        if isinstance(ps, ResamplePass):
            stored[ps.target] = resample(_written(stored, ps.source), ps, plan.images[ps.source])
            continue
        if isinstance(ps, PointwisePass):
            stored[ps.target] = pointwise(ps.op, [_written(stored, s) for s in ps.srcs], ps.param)
            continue
        target = plan.images[ps.target]
        h, w = target.stored
        top, left = target.guard[0], target.guard[1]
        out = np.zeros((h, w) + channels)
        r_all = np.arange(h) + 1 - top
        c_all = np.arange(w) + 1 - left
        (pr, pc), (sr, sc) = ps.period, ps.stride
        for (phr, phc), taps in ps.phases.items():
            ri = np.nonzero(r_all % pr == phr)[0]
            ci = np.nonzero(c_all % pc == phc)[0]
            if not len(ri) or not len(ci):
                continue
            base_r = base_index(r_all[ri], pr, sr)
            base_c = base_index(c_all[ci], pc, sc)
            acc = np.zeros((len(ri), len(ci)) + out.shape[2:])
            for t in taps:
                acc += float(t.weight) * _read(plan, stored, t, base_r, base_c)
            out[_grid(ri, ci)] = acc
        stored[ps.target] = out
    return stored


def resample_table(ps: ResamplePass, source: Image, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """A :class:`ResamplePass`'s table for an executor: (indices, weights), both (n_out, width); indices are
    0-based *stored* indices of ``source`` along the pass's axis (logical plus its guard there: a tile's window,
    :mod:`pyramid_cli.exec.tiles`), folded by its border mode over its stored extent; a read of zero ("zero"
    border) is index 0 with weight 0."""
    offset, n_in = source.guard[ps.axis], source.stored[ps.axis]
    idx = np.asarray(ps.starts, dtype=np.int64)[:, None] + np.arange(ps.width)[None, :] + offset
    folded = fold(idx + 1, n_in, Border.parse(source.border)) - 1
    weights = np.array([[float(w) for w in row] for row in ps.weights], dtype=dtype)
    weights[folded < 0] = 0
    return np.maximum(folded, 0), weights


def resample(src: np.ndarray, ps: ResamplePass, source: Image) -> np.ndarray:
    """One :class:`ResamplePass` on a stored source (guard bands only along the pass's axis), float64."""
    idx, weights = resample_table(ps, source)
    picked = np.take(src, idx, axis=ps.axis)  # axis 0: (n_out, width, W, …); axis 1: (H, n_out, width, …)
    extra = (None,) * (src.ndim - 1 - ps.axis)
    return (picked * weights[(...,) + extra]).sum(axis=ps.axis + 1)


def run_outputs(plan: Plan, image: np.ndarray | Sequence[np.ndarray]) -> list[np.ndarray]:
    """Like :func:`run`, returning every image in ``plan.outputs``."""
    stored = _execute(plan, image)
    return [_logical(plan, stored, i) for i in plan.outputs]


def _written(stored: list[np.ndarray | None], index: int) -> np.ndarray:
    """Image ``index`` of ``stored``, which a plan writes before any pass reads it
    (:func:`pyramid_cli.plan.model.check`)."""
    a = stored[index]
    assert a is not None, f"image {index} is read before it is written"
    return a


def _logical(plan: Plan, stored: list[np.ndarray | None], index: int) -> np.ndarray:
    img = plan.images[index]
    t, l = img.guard[0], img.guard[1]
    return _written(stored, index)[t:t + img.size[0], l:l + img.size[1]]


def _read(plan: Plan, stored: list[np.ndarray | None], t: Tap, base_r: np.ndarray,
          base_c: np.ndarray) -> np.ndarray:
    src = plan.images[t.source]
    rows = base_r - float(t.offset[0])
    cols = base_c - float(t.offset[1])
    return sample(_written(stored, t.source), (src.guard[0], src.guard[1]), rows, cols, src.border)


class Emulator:
    """The plan emulator behind the :class:`~pyramid_cli.exec.base.Executor` protocol: numpy, float64.

    Its intermediates are float64 (``work_dtype``): :meth:`run_outputs` returns them as they are
    for ``dtype=float64`` (its default, what the tile scheduler asks), and otherwise rounds them
    as every executor rounds, float64 → float32 → ``dtype``.
    """

    name = "cpu (numpy plan emulator)"
    backend = "cpu"       # stands in for the compiled CPU executor where numba is missing
    strategy = "cost"
    work_dtype = np.dtype(np.float64)
    max_texture_size = None
    host_textures = False
    writes_into = False

    @staticmethod
    def texture_bytes(extent: tuple[int, int]) -> int:
        """No textures beside the pictures: 0."""
        return 0

    def run_outputs(self, plan: Plan, images, dtype=np.float64) -> list[np.ndarray]:
        """Every image of ``plan.outputs`` (:func:`run_outputs`), float64, or rounded to ``dtype``."""
        outs = run_outputs(plan, list(images) if isinstance(images, (list, tuple)) else images)
        if np.dtype(dtype) == np.float64:
            return outs
        return [rounded(o, dtype) for o in outs]

    def uncached(self, plan: Plan, dtype=np.float32) -> int:
        """Nothing to compile: 0."""
        return 0

    def prepare(self, plan: Plan) -> None:
        """Nothing to get ready."""

    def close(self) -> None:
        """Nothing held."""


def rounded(values: np.ndarray, dtype) -> np.ndarray:
    """A float64 result as ``dtype``, through float32 as the executors round: float64 → float32 → half."""
    return np.asarray(values).astype(np.float32).astype(dtype, copy=False)
