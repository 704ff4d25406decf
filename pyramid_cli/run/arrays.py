"""Arrays through a session for the Python API: whole, or band by band in bounded memory, with the dtype
rules of :mod:`pyramid_cli.imageio.dtypes` (what each result is stored as, at which width it is computed)."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from pyramid_cli.core.errors import UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.imageio import dtypes
from pyramid_cli.jobs.work import Work


class ArrayInput:
    """One array argument: checked, its pixels at the width its job computes at, and its results' dtype.

    Parameters
    ----------
    array : array_like
        H×W or H×W×C values (:func:`pyramid_cli.imageio.dtypes.as_pixels`).
    dtype : dtype, optional
        The results' dtype (default the array's: :func:`pyramid_cli.imageio.dtypes.result_dtype`).
    name : str
        The argument's name in error messages.
    """

    def __init__(self, array: ArrayLike, dtype: DTypeLike | None = None, name: str = "array"):
        self.array = array if isinstance(array, np.ndarray) else np.asarray(array)
        self.name = name
        self.pixels = dtypes.as_pixels(self.array, name)  # checks the shape and type first
        self.dtype = dtypes.result_dtype(self.array.dtype, dtype)
        self.wide = dtypes.is_wide(self.array.dtype, self.dtype)
        if self.wide:
            self.pixels = dtypes.as_pixels(self.array, name, wide=True)

    @property
    def compute(self) -> type:
        """What the session is asked for: float64 (:meth:`~pyramid_cli.exec.session.Session.run`'s float64
        path), float16 (rounded by the executor) or float32."""
        return np.float64 if self.wide else np.float16 if self.dtype == np.float16 else np.float32

    def at(self, wide: bool) -> np.ndarray:
        """The pixels at float64 when ``wide`` (another input's job is computed in float64), else as they are."""
        return dtypes.as_pixels(self.array, self.name, wide=True) if wide and not self.wide else self.pixels

    def results(self, outs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """``outs`` as this input's result dtype."""
        return [dtypes.to_dtype(o, self.dtype) for o in outs]


def run(session: Session, work: Work, inputs: Sequence[np.ndarray], first: ArrayInput) -> list[np.ndarray]:
    """Every output of ``work`` on ``inputs`` (pixels), computed at ``first``'s width and stored as its dtype;
    a job that keeps its input (pyramid, MIP levels) gives a copy of it as level 0."""
    outs = session.run(work, list(inputs), first.compute)
    if not work.keeps_input:
        return first.results(outs)
    return [dtypes.level_zero(first.array, first.pixels, first.dtype), *first.results(outs[1:])]


def fill_colour(colour: np.ndarray, first: ArrayInput, holes: str) -> np.ndarray:
    """:func:`pyramid_cli.workflows.methods.fill_inputs`' colours (float32) at ``first``'s width: where it
    computes in float64, the same channels of its float64 pixels (the alpha channel, the last, left out
    for ``holes="alpha"``; NaN/Inf pixels as 0 for ``"nan"``), so that known pixels come back bit for bit."""
    if not first.wide:
        return colour
    a3 = first.pixels if first.pixels.ndim == 3 else first.pixels[:, :, None]
    a3 = a3[:, :, :-1] if holes == "alpha" else a3
    if holes == "nan":
        a3 = np.where(np.all(np.isfinite(a3), axis=2, keepdims=True), a3, 0.0)
    return np.ascontiguousarray(a3, dtype=np.float64)


def fill_result(filled: np.ndarray, first: ArrayInput, holes: str, keep_alpha: bool) -> np.ndarray:
    """:func:`pyramid_cli.workflows.methods.fill_output` at ``first``'s width and as its dtype: where it computes
    in float64, the filled colours are put back in float64 (fill_output's alpha layout is float32)."""
    from pyramid_cli.workflows.methods import fill_output

    out = fill_output(filled, first.pixels, holes, keep_alpha=keep_alpha)
    if first.wide and holes == "alpha":
        out = out.astype(np.float64)
        out[:, :, :-1] = filled if filled.ndim == 3 else filled[:, :, None]
    return dtypes.to_dtype(out, first.dtype)


def as_array(array: ArrayLike) -> np.ndarray:
    """``array`` itself when it is a numpy array (a memmap stays one), else as one."""
    return array if isinstance(array, np.ndarray) else np.asarray(array)


def wanted(array: object, out: object, memory: object) -> bool:
    """Whether a call runs band by band: ``out=``, ``memory=`` or a memory-mapped input."""
    return out is not None or memory is not None or isinstance(array, np.memmap)


def zarr_out(out: object) -> bool:
    """Whether ``out`` is an OME-Zarr output: a ``zarr.Group`` or a path whose name ends in ``.zarr`` (told
    without loading zarr or image I/O)."""
    if isinstance(out, (str, os.PathLike)):
        return os.fspath(out).rstrip("/\\").lower().endswith(".zarr")
    return type(out).__module__.split(".")[0] == "zarr" and type(out).__name__ == "Group"


def to_zarr(out: object, levels: list[np.ndarray], analysis: str) -> list:
    """A pyramid's ``levels`` written into ``out`` as OME-Zarr, as zarr arrays (c, y, x):
    :func:`pyramid_cli.imageio.tilesets.omezarr.write_levels`."""
    from pyramid_cli.imageio.tilesets import omezarr

    return omezarr.write_levels(out, levels, analysis=analysis)


def banded(session: Session, work: Work, array: ArrayLike, out: Sequence[np.ndarray] | None,
           memory: int | str | None, dtype: DTypeLike | None = None) -> list[np.ndarray]:
    """One image through ``work`` band by band (:mod:`pyramid_cli.exec.tiles`), computed in float32: a
    memory-mapped input is read a band at a time and the results written into ``out`` (one float array per
    output of the plan, after level 0 for a job that keeps its input; a memmap keeps it on disk), within
    ``memory`` bytes of working set (default: :func:`pyramid_cli.run.budget.default_budget`), the pixels of
    the whole run. Without ``out`` the results are new arrays of the input's result dtype (``dtype``)."""
    from pyramid_cli.exec import tiles
    from pyramid_cli.run import stream

    a = array if isinstance(array, np.ndarray) else np.asarray(array)
    if a.ndim not in (2, 3) or 0 in a.shape or a.dtype.kind not in "fiub":
        dtypes.as_pixels(a)  # raises the usual message
    want = dtypes.result_dtype(a.dtype, dtype)
    if session.executor is None:
        raise UsageError("out= and memory= need a plan executor (backend 'gl' or 'cpu'): the reference "
                         "backend holds whole pictures")
    work.check((a.shape[:2],))
    plan = session.plan(work, [a.shape[:2]])
    if plan is None:
        return []
    shapes = [plan.images[k].size + a.shape[2:] for k in plan.outputs]
    store = want if want in dtypes.FLOATS else np.dtype(np.float32)
    outs = [np.empty(shape, dtype=store) for shape in shapes] if out is None else list(out)
    if len(outs) != len(shapes):
        raise UsageError(f"out: expected {len(shapes)} arrays (shapes {shapes}), got {len(outs)}")
    for k, (o, shape) in enumerate(zip(outs, shapes, strict=True)):
        if tuple(o.shape) != shape or o.dtype not in dtypes.FLOATS:
            name = "out" if len(outs) == 1 else f"out[{k}]"
            raise UsageError(f"{name}: expected a float array of shape {shape}, got {o.dtype} {tuple(o.shape)}")
    budget = stream.parse_size(memory) if isinstance(memory, str) else memory or stream.default_memory()
    channels = a.shape[2] if a.ndim == 3 else 1
    executor = session.executor
    choice = stream.choose(plan, channels, budget, in_bytes=max(4, a.dtype.itemsize), force=True,
                           **stream.costs(executor))
    band = choice.band if choice.band is not None else a.shape[0]  # forced: always a band, else the whole height
    tiles.run_arrays(executor, plan, [a], band=band, out=outs, convert=dtypes.as_pixels)
    session.ran = session.name
    return outs if out is not None or store == want else [dtypes.to_dtype(o, want) for o in outs]


__all__ = ["ArrayInput", "run", "fill_colour", "fill_result", "as_array", "wanted", "zarr_out", "to_zarr",
           "banded"]
