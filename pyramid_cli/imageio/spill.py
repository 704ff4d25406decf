"""Rows of several images kept until their turn: in memory, or in a raw temporary file.

A file that holds its levels one after the other (a MIP-mapped texture: level 0 first; a pyramidal
TIFF: level 0's page first) receives the coarser levels' rows while level 0 is still being written.
:class:`KeptRows` keeps them: as arrays, or, given a file, on disk with explicit ``pwrite``/``pread``
(no mapping: rows on disk do not count in the process's memory). A failure of the file (a full disk)
is an :class:`~pyramid_cli.core.errors.OutputError` naming the user's output it sits beside (exit 4).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np

from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio.atomic import error_reason


class _TempFile:
    """A raw temporary file beside the user's output ``beside``, written and read at explicit offsets (see the
    module); None as ``path``: no file (the subclass keeps arrays)."""

    def __init__(self, path: str | None, beside: str, what: str):
        self.beside, self.what = beside, what
        self.fd: int | None = None
        if path:
            try:
                self.fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
            except OSError as exc:
                raise self._failed(exc) from None

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None

    def _file(self) -> int:
        if self.fd is None:
            raise ValueError(f"the temporary file of the {self.what} is closed")
        return self.fd

    def _failed(self, exc: OSError) -> OutputError:
        return OutputError(f"cannot write {self.beside}: {error_reason(exc)} (in the temporary file of its "
                           f"{self.what} beside it)")

    def _write(self, view: memoryview, at: int) -> None:
        """All of ``view`` at offset ``at``."""
        fd = self._file()
        try:
            while view:
                n = os.pwrite(fd, view, at)
                view, at = view[n:], at + n
        except OSError as exc:
            raise self._failed(exc) from None

    def _read(self, view: memoryview, at: int) -> None:
        """``view`` filled from offset ``at``, straight into it (no bytes made on the way)."""
        fd = self._file()
        try:
            while view:
                n = os.preadv(fd, [view], at)
                if not n:
                    raise OSError(f"the temporary file ends {len(view)} bytes early")
                view, at = view[n:], at + n
        except OSError as exc:
            raise self._failed(exc) from None


class KeptRows(_TempFile):
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
        self.shapes, self.dtype = shapes, np.dtype(dtype)
        self.arrays: list[np.ndarray] | None = None if path else [np.empty(s, dtype=self.dtype) for s in shapes]
        self.offsets = [0]
        for h, w, c in shapes:
            self.offsets.append(self.offsets[-1] + h * w * c * self.dtype.itemsize)
        super().__init__(path, beside, what)

    def _at(self, i: int, r: int) -> int:
        _, w, c = self.shapes[i]
        return self.offsets[i] + r * w * c * self.dtype.itemsize

    def write(self, i: int, r: int, px: np.ndarray) -> None:
        """Rows ``r ..`` of image ``i``."""
        if self.arrays is not None:
            self.arrays[i][r:r + len(px)] = px
            return
        self._write(np.ascontiguousarray(px, dtype=self.dtype).data.cast("B"), self._at(i, r))

    def rows(self, i: int, r0: int, r1: int) -> np.ndarray:
        """Rows ``r0:r1`` of image ``i``."""
        if self.arrays is not None:
            return self.arrays[i][r0:r1]
        _, w, c = self.shapes[i]
        out = np.empty((r1 - r0, w, c), dtype=self.dtype)
        self._read(out.data.cast("B"), self._at(i, r0))
        return out


class KeptChunks(_TempFile):
    """Encoded chunks of ``count`` images (a level's compressed tiles, in file order) kept until their turn in the
    temporary file ``path``: appended as they are made, read back one at a time, in order (no mapping: nothing of
    them in the process's memory). Errors as :class:`KeptRows`'s."""

    def __init__(self, count: int, path: str, *, beside: str = "", what: str = "levels"):
        self.index: list[list[tuple[int, int]]] = [[] for _ in range(count)]  # (offset, length) per chunk
        self.end = 0
        super().__init__(path, beside, what)

    def append(self, i: int, data: bytes) -> None:
        """The next chunk of image ``i``."""
        self._write(memoryview(data), self.end)
        self.index[i].append((self.end, len(data)))
        self.end += len(data)

    def chunks(self, i: int) -> Iterator[bytes]:
        """Image ``i``'s chunks, in the order they came."""
        for at, size in self.index[i]:
            data = bytearray(size)
            self._read(memoryview(data), at)
            yield bytes(data)


__all__ = ["KeptChunks", "KeptRows"]
