"""Tile-set writers for testing the run layer of ``pyramid tiles`` without a real layout.

:class:`RecordingWriter` keeps every level it is handed (whole, in memory: tests compare them to the
reference) and checks the contract's order; :class:`FileWriter` streams the rows into one staged file
(raw float32, level after level as they come, then a trailer), so that interruptions, full disks and
memory can be tested in real processes. :func:`main` runs the ``pyramid`` command with every layout
written by :class:`FileWriter` (``python -c 'from helpers.fake_tiles import main; main()' tiles ...``).
"""

from __future__ import annotations

import os
import time

import numpy as np

from pyramid_cli.core.errors import OutputError
from pyramid_cli.core.geometry import mip_levels
from pyramid_cli.imageio.tilesets import TileSetWriter
from pyramid_cli.imageio.tilesets.staging import Staging

TRAILER = b"END OF FAKE TILE SET\n"
DELAY = float(os.environ.get("FAKE_TILES_DELAY", "0"))  # seconds FileWriter waits per band of level 0
DISCARD = bool(os.environ.get("FAKE_TILES_DISCARD"))  # FileWriter counts the rows only (memory measurements)


class RecordingWriter(TileSetWriter):
    """Every row of every level into arrays; ``calls`` lists (level, y0, rows) in the order they came."""

    layout = "fake"
    made: list[RecordingWriter] = []   # every writer made, for the test to look at
    levels_cap: int | None = None

    def __init__(self, path, info, size, channels, options):
        super().__init__(path, info, size, channels, options)
        self.levels = [np.full((h, w, channels), np.nan, np.float32) for h, w in self.sizes]
        self.next_row = [0] * len(self.sizes)
        self.calls: list[tuple[int, int, int]] = []
        self.state = "open"
        self.staging = Staging([self.path])
        type(self).made.append(self)

    @classmethod
    def level_count(cls, size, options):
        n = mip_levels(tuple(size)) + 1
        return n if cls.levels_cap is None else min(n, cls.levels_cap)

    def _rows(self, level, y0, pixels, owned=False):
        assert self.state == "open"
        assert pixels.dtype == np.float32, pixels.dtype
        assert y0 == self.next_row[level], (level, y0, self.next_row[level])
        h = pixels.shape[0]
        assert pixels.shape[1:] == self.levels[level].shape[1:], (pixels.shape, self.levels[level].shape)
        self.levels[level][y0:y0 + h] = pixels
        self.next_row[level] += h
        self.calls.append((level, y0, h))

    def _finish(self):
        assert self.next_row == [h for h, _ in self.sizes], (self.next_row, self.sizes)
        with open(self.staging.staged[0], "wb") as f:
            f.write(TRAILER)
        self.staging.commit()
        self.state = "finished"
        return {"layout": self.layout, "path": self.path, "tile_size": self.options.tile_size,
                "overlap": self.options.overlap, "format": self.options.suffix,
                "levels": [{"level": k, "reduction": k, "size": [w, h], "scale": 2 ** k, "rule": "ceil-half"}
                           for k, (h, w) in enumerate(self.sizes)]}

    def _abort(self):
        self.staging.discard()
        self.state = "aborted"


class FileWriter(TileSetWriter):
    """Rows streamed into one staged file as they come (never a whole level held), the trailer last."""

    layout = "fake-file"

    def __init__(self, path, info, size, channels, options):
        super().__init__(path, info, size, channels, options)
        self.staging = Staging([self.path])
        self.file = open(self.staging.staged[0], "wb")  # noqa: SIM115 - closed in finish or abort

    @classmethod
    def level_count(cls, size, options):
        return mip_levels(tuple(size)) + 1

    def check(self):
        if self.options.tile_size is not None and self.options.tile_size < 2:
            from pyramid_cli.core.errors import UsageError

            raise UsageError(f"--tile-size {self.options.tile_size}: the fake layout needs at least 2")

    def _write(self, data: bytes) -> None:
        try:
            self.file.write(data)
            self.file.flush()
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}") from None

    def _rows(self, level, y0, pixels, owned=False):
        if level == 0 and DELAY:  # a slow disk: signals reach the run mid-way at any load
            time.sleep(DELAY)
        self.rows_seen = getattr(self, "rows_seen", 0) + len(pixels)
        if not DISCARD:
            self._write(np.ascontiguousarray(pixels, dtype=np.float32).tobytes())

    def _finish(self):
        self._write(TRAILER)
        self.file.close()
        self.staging.commit()
        return {"layout": self.layout, "path": self.path, "levels": [{"size": [w, h]} for h, w in self.sizes]}

    def _abort(self):
        if not self.file.closed:
            try:
                self.file.close()
            except OSError:
                pass
        self.staging.discard()


def complete(path) -> bool:
    """Whether ``path`` is a whole tile set of :class:`FileWriter`."""
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        if f.tell() < len(TRAILER):
            return False
        f.seek(-len(TRAILER), os.SEEK_END)
        return f.read() == TRAILER


def main() -> None:
    """The ``pyramid`` console script with every layout written by :class:`FileWriter`."""
    from pyramid_cli.cli.group import run
    from pyramid_cli.imageio import tilesets

    tilesets.writer_class = lambda layout: FileWriter
    run()
