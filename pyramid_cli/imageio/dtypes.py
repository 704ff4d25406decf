"""NumPy arrays as pixels and back: the Python API's dtype rules.

An array's values are read as scikit-image's ``img_as_float`` reads them: floats as they are,
unsigned integers as ``code / max``, signed ones as ``code / max`` clipped at −1, booleans as 0/1.
A result goes back to the caller's dtype (:func:`result_dtype`): a float keeps its width, an
integer type gets its codes back (``round(value · max)``, clipped to the type's range; NaN
becomes 0), a boolean input gives float32. :func:`is_wide` says which results are computed in
float64 (float64 results, and integers of more than 16 bits) rather than float32.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pyramid_cli.core.errors import UsageError

#: The float types a result keeps as they are.
FLOATS = (np.dtype(np.float16), np.dtype(np.float32), np.dtype(np.float64))


def result_dtype(source: np.dtype, dtype: Any = None) -> np.dtype:
    """The dtype of a result of an input stored as ``source``: ``dtype`` when given (a float or integer
    type), else ``source`` itself (float16/32/64, an integer type), float64 for a wider float, float32 for
    booleans.

    Raises
    ------
    UsageError
        ``dtype`` is not a real float or integer type.
    """
    if dtype is not None:
        try:
            asked = np.dtype(dtype)
        except TypeError:
            raise UsageError(f"dtype {dtype!r} is not a numpy type") from None
        if asked.kind not in "fiu":
            raise UsageError(f"dtype must be a float or integer type, not {asked}")
        return np.dtype(np.float64) if asked.kind == "f" and asked.itemsize > 8 else asked
    if source.kind == "f":
        return np.dtype(np.float64) if source.itemsize > 8 else source
    if source.kind in "iu":
        return source
    return np.dtype(np.float32)


def is_wide(source: np.dtype, result: np.dtype) -> bool:
    """Whether a job on ``source`` pixels giving ``result`` is computed in float64: when the result is float64
    (or a wider float) or an integer of more than 16 bits, whose codes float32 cannot hold exactly. A float32 or
    float16 result (``dtype=np.float32`` of a float64 input, say) is computed in float32, the fast path."""
    return (result.kind == "f" and result.itemsize >= 8) or (result.kind in "iu" and result.itemsize > 2)


def as_pixels(array: Any, name: str = "array", wide: bool = False) -> np.ndarray:
    """``array`` as pixels the executors take: 2-D or 3-D, float; integers and booleans normalised (see the
    module) to float32, or float64 when ``wide``; floats as they are (float64 when ``wide``).

    Raises
    ------
    UsageError
        Not 2-D or 3-D, empty, or not a real number type.
    """
    a = np.asarray(array)
    if a.ndim not in (2, 3):
        raise UsageError(f"{name}: expected a 2-D (H, W) or 3-D (H, W, C) array, got shape {a.shape}")
    if 0 in a.shape:
        raise UsageError(f"{name}: an image needs at least one row, column and channel, got shape {a.shape}")
    work = np.float64 if wide else np.float32
    if a.dtype.kind == "f":
        return a.astype(np.float64, copy=False) if wide or a.dtype.itemsize > 8 else a
    if a.dtype.kind == "b":
        return a.astype(work)
    if a.dtype.kind == "u":
        return (a / np.float64(np.iinfo(a.dtype).max)).astype(work, copy=False)
    if a.dtype.kind == "i":
        return np.maximum(a / np.float64(np.iinfo(a.dtype).max), -1.0).astype(work, copy=False)
    raise UsageError(f"{name}: pixels must be real numbers, not {a.dtype}")


def to_dtype(values: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Pixel values as ``dtype``: a float type rounds to nearest (no copy when it is theirs already); an
    integer type gets codes ``round(value · max)`` clipped to its range (signed: from ``−max``), NaN as 0."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return np.asarray(values).astype(dtype, copy=False)
    info = np.iinfo(dtype)
    codes = np.rint(np.nan_to_num(np.asarray(values, dtype=np.float64), nan=0.0) * info.max)
    return np.clip(codes, -info.max if info.min < 0 else 0, info.max).astype(dtype)


def level_zero(array: Any, pixels: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """A pyramid's level 0 as ``dtype``, never the caller's own memory: a copy of ``array`` where it is stored
    as ``dtype`` already, else its ``pixels`` (:func:`as_pixels`) converted by :func:`to_dtype`."""
    a = np.asarray(array)
    if a.dtype == dtype:
        return np.array(a, copy=True)
    out = to_dtype(pixels, dtype)
    return np.array(out, copy=True) if np.may_share_memory(out, a) else out


__all__ = ["FLOATS", "result_dtype", "is_wide", "as_pixels", "to_dtype", "level_zero"]
