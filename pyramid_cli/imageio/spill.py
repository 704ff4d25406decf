"""Rows of several images kept until their turn: in memory, or in a raw temporary file.

A file that holds its levels one after the other (a MIP-mapped texture: level 0 first; a pyramidal
TIFF: level 0's page first) receives the coarser levels' rows while level 0 is still being written.
:class:`KeptRows` keeps them: as arrays, or, given a file, on disk with explicit ``pwrite``/``pread``
(no mapping: rows on disk do not count in the process's memory). A failure of the file (a full disk)
is an :class:`~pyramid_cli.core.errors.OutputError` naming the user's output it sits beside (exit 4).
"""

from __future__ import annotations

import os

import numpy as np

from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio.atomic import error_reason


class KeptRows:
    """The rows of images of ``shapes`` ((rows, cols, channels) each) as ``dtype``; see the module.

    Parameters
    ----------
    shapes : list of (int, int, int)
        One entry per image kept.
    path : str, optional
        The file to keep them in (opened, created if missing); None: arrays in memory.
    dtype
        What the rows are kept as.
    beside : str
        The user's output, named in errors.
    what : str
        What the rows are, for errors (``"coarser MIP levels"``).
    """

    def __init__(self, shapes: list[tuple[int, int, int]], path: str | None = None, dtype=np.float32, *,
                 beside: str = "", what: str = "levels"):
        self.shapes, self.dtype, self.beside, self.what = shapes, np.dtype(dtype), beside, what
        self.arrays: list[np.ndarray] | None = None if path else [np.empty(s, dtype=self.dtype) for s in shapes]
        self.fd: int | None = None
        self.offsets = [0]
        for h, w, c in shapes:
            self.offsets.append(self.offsets[-1] + h * w * c * self.dtype.itemsize)
        if path:
            try:
                self.fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
            except OSError as exc:
                raise self._failed(exc) from None

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def _at(self, i: int, r: int) -> int:
        _, w, c = self.shapes[i]
        return self.offsets[i] + r * w * c * self.dtype.itemsize

    def _file(self) -> int:
        if self.fd is None:
            raise ValueError(f"the temporary file of the {self.what} is closed")
        return self.fd

    def _failed(self, exc: OSError) -> OutputError:
        return OutputError(f"cannot write {self.beside}: {error_reason(exc)} (in the temporary file of its "
                           f"{self.what} beside it)")

    def write(self, i: int, r: int, px: np.ndarray) -> None:
        """Rows ``r ..`` of image ``i``."""
        if self.arrays is not None:
            self.arrays[i][r:r + len(px)] = px
            return
        fd = self._file()
        view = np.ascontiguousarray(px, dtype=self.dtype).data.cast("B")
        at = self._at(i, r)
        try:
            while view:
                n = os.pwrite(fd, view, at)
                view, at = view[n:], at + n
        except OSError as exc:
            raise self._failed(exc) from None

    def rows(self, i: int, r0: int, r1: int) -> np.ndarray:
        """Rows ``r0:r1`` of image ``i``."""
        if self.arrays is not None:
            return self.arrays[i][r0:r1]
        _, w, c = self.shapes[i]
        size = (r1 - r0) * w * c * self.dtype.itemsize
        fd = self._file()
        data = bytearray()
        try:
            while len(data) < size:
                chunk = os.pread(fd, size - len(data), self._at(i, r0) + len(data))
                if not chunk:
                    raise OSError(f"the temporary file ends {size - len(data)} bytes early")
                data += chunk
        except OSError as exc:
            raise self._failed(exc) from None
        return np.frombuffer(data, dtype=self.dtype).reshape(r1 - r0, w, c)


__all__ = ["KeptRows"]
