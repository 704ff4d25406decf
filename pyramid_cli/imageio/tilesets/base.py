"""What every viewer layout's writer is: levels of rows in, a tile set on disk out.

The run layer (:mod:`pyramid_cli.run.tiles`) makes every level of the pyramid band by band
(level 0 is the input itself, level k is ⌈n/2⌉ of level k − 1 on each axis: the paper's ⊗↓ with
the odd sizes of docs/design.md) and hands each level's rows to one :class:`TileSetWriter`, in
order within each level, but interleaved across levels as the band pipeline makes them. The writer
encodes them (the input's type and colour space, as :func:`~pyramid_cli.imageio.encode.encoded_rows`
stores them for a file of its format), cuts its tiles or chunks as soon as their rows (and overlap)
are complete, and writes them under a staging path (:mod:`~pyramid_cli.imageio.tilesets.staging`)
that :meth:`TileSetWriter.finish` moves into place, descriptor last; :meth:`TileSetWriter.abort`
removes it and leaves whatever was at the output untouched.
"""

from __future__ import annotations

import abc
import os
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from pyramid_cli.core.geometry import halved
from pyramid_cli.imageio.encode import Encoder
from pyramid_cli.imageio.image import ImageInfo


@dataclass(frozen=True)
class TileOptions:
    """What the user asked of the tile set; None: the layout's default.

    Attributes
    ----------
    tile_size, overlap : int or None
        Tile edge and overlap in pixels (Deep Zoom: 254 and 1, as ``vips dzsave``).
    suffix : str or None
        Tile file format of the folder layouts (``"jpeg"``, ``"png"``, ``"webp"``, ``"tif"``), without dot.
    quality : int or None
        JPEG/WebP quality (``vips dzsave``'s Q, 75 by default).
    compression : str or None
        Codec of the chunks or TIFF tiles (``"jpeg"``, ``"deflate"``, ``"zstd"``, ``"none"``...).
    write : dict
        The write options of the other commands (``pixel_type``, ``colorspace`` (the output's),
        ``alpha``, ``dither``), passed to :func:`~pyramid_cli.imageio.encode.encoded_rows`.
    iiif_id : str or None
        IIIF layouts: the base URL of the image's ``id`` in ``info.json`` (``vips dzsave --id``; default
        ``https://example.com/iiif``), the folder's name appended. Viewers fetch the tiles from that URL.
    """

    tile_size: int | None = None
    overlap: int | None = None
    suffix: str | None = None
    quality: int | None = None
    compression: str | None = None
    write: dict = field(default_factory=dict)
    iiif_id: str | None = None


def ceil_levels(size: tuple[int, int], count: int) -> list[tuple[int, int]]:
    """(rows, cols) of levels 0..count−1, each ⌈n/2⌉ of the one before."""
    out = [tuple(size)]
    for _ in range(count - 1):
        out.append(halved(out[-1]))
    return [(int(h), int(w)) for h, w in out]


class TileSetWriter(abc.ABC):
    """One tile set being written (see the module). Subclasses set :attr:`layout` and implement
    :meth:`level_count`, :meth:`_rows`, :meth:`_finish` and :meth:`_abort`.

    Parameters
    ----------
    path : str
        The user's output path (``name.dzi``, ``folder/`` for IIIF, ``name.ome.zarr``, ``name.tif``).
    info : ImageInfo
        How the input was stored: the tiles keep its type and colour space where the format can.
    size : (int, int)
        (rows, cols) of the input, level 0.
    channels : int
        Channels of the pixels handed to :meth:`rows` (alpha included, premultiplied).
    options : TileOptions
        What the user asked.
    """

    layout: ClassVar[str]            # the --layout name: "dz", "iiif3", "iiif", "ome-zarr", "tiff", "ome-tiff"
    encode_as: ClassVar[str] = "x.tif"  # a file name whose format decides how rows are stored (folders: the suffix)
    #: Whether rows of tiles can be written by several processes at once into one staging folder (:meth:`begin`,
    #: :meth:`part`, :meth:`end_part`, :meth:`merge`: ``pyramid tiles --cluster``); a TIFF is one file written in order.
    parallel: ClassVar[bool] = False
    takes_stored: ClassVar[bool] = False  # rows(stored=...) stores them instead of encoding the pixels

    def __init__(self, path: str, info: ImageInfo, size: tuple[int, int], channels: int, options: TileOptions):
        self.path, self.info, self.channels, self.options = os.fspath(path), info, channels, options
        self._encoders: dict[tuple[int, str], Encoder] = {}
        self.sizes = ceil_levels(size, self.level_count(size, options))

    @classmethod
    @abc.abstractmethod
    def level_count(cls, size: tuple[int, int], options: TileOptions) -> int:
        """Levels the layout holds for an input of ``size`` (level 0 included): Deep Zoom's down to 1×1,
        a TIFF's until a level fits in one tile, ..."""

    def check(self) -> None:
        """Refuse, before any work, what this layout cannot hold (UsageError/OutputError, one line with the
        path): a suffix, type, channel count or option it would ignore. Nothing here."""
        return None

    def encode(self, pixels: np.ndarray, y0: int = 0) -> np.ndarray:
        """Stored values of linear premultiplied float rows (the input's type and colour space where
        :attr:`encode_as`'s format holds them). ``y0``: the rows' first row (dithering lines up at multiples
        of 8)."""
        del y0  # the 8-row dither pattern starts at each band: bands are multiples of 8 rows
        return self.encoder(pixels.shape[2] if pixels.ndim == 3 else 1).values(pixels)

    def encoder(self, channels: int, encode_as: str | None = None) -> Encoder:
        """How rows of ``channels`` channels are stored in the format of ``encode_as`` (default :attr:`encode_as`)
        with the write options, as :func:`~pyramid_cli.imageio.encode.encoded_rows` stores them: decided at the
        first band, kept for the others."""
        key = (channels, encode_as or self.encode_as)
        enc = self._encoders.get(key)
        if enc is None:
            enc = self._encoders[key] = Encoder(key[1], self.info, channels, check_path=False, **self.options.write)
        return enc

    def rows(self, level: int, y0: int, pixels: np.ndarray | None, stored: np.ndarray | None = None, *,
             owned: bool = False) -> None:
        """Linear, premultiplied float32 rows ``y0 ..`` of level ``level`` (0 = the input), (h, W, C), each row of
        each level exactly once and in order; ``pixels`` may be reused by the caller after the call, unless
        ``owned``: the caller never writes into them again (the band engine's rows), so they are kept without a
        copy.

        ``stored``: the same rows as :meth:`encode` stores them (the caller has checked that with
        :meth:`~pyramid_cli.imageio.ImageStream.gives_back`), the writer's to keep; a writer that :attr:`takes_stored`
        stores them as they are instead of encoding ``pixels`` (which may then be None), the others ignore them."""
        if stored is not None and self.takes_stored:
            self._rows_stored(level, y0, stored)
        elif pixels is None:
            raise ValueError(f"{self.layout}: rows of level {level} without pixels need stored rows it takes")
        else:
            self._rows(level, y0, pixels, owned)

    @abc.abstractmethod
    def _rows(self, level: int, y0: int, pixels: np.ndarray, owned: bool) -> None: ...

    def _rows_stored(self, level: int, y0: int, stored: np.ndarray) -> None:
        """Rows already in their stored values (writers that :attr:`takes_stored`)."""
        raise NotImplementedError

    def finish(self) -> dict:
        """Write what is left (the descriptor last), move the tile set into place, and describe it for
        ``--json``: ``{"layout", "path", "tile_size", "overlap", "format", "levels": [{"level" (the layout's own
        number), "reduction" (k), "size": [w, h], "scale": 2**k, "rule": "ceil-half", "tiles" or "chunks"}]}``."""
        return self._finish()

    @abc.abstractmethod
    def _finish(self) -> dict: ...

    def abort(self) -> None:
        """Remove everything written so far; whatever was at the output before stays as it was. A :meth:`part`
        only stops (the staging folder is its client's)."""
        self._abort()

    # ------------------------------------------------------------ parallel writing (layouts with ``parallel``)
    def tile_rows(self, level: int) -> int:
        """Rows of level ``level`` in one row of its tiles (chunks), overlap apart."""
        raise NotImplementedError(f"{self.layout}: tile rows are not written in parallel")

    def span(self, level: int, first: int, end: int) -> tuple[int, int]:
        """The rows of level ``level`` that its tile rows ``first .. end − 1`` hold (overlap included), as
        :meth:`rows` of a :meth:`part` writing them takes them."""
        t, h = self.tile_rows(level), self.sizes[level][0]
        return min(h, first * t), min(h, end * t)

    def begin(self) -> str:
        """Make the staging folder (and what the parts write into: a Zarr group's arrays) and return its root, which
        :meth:`part` writers on other machines (shared storage) are given; this writer then takes no rows, and
        :meth:`finish` (after :meth:`merge`) writes the descriptor and moves the tile set into place."""
        raise NotImplementedError(f"{self.layout}: tile rows are not written in parallel")

    def part(self, root: str, rows: dict[int, tuple[int, int]]) -> None:
        """Make this writer write only the tile rows ``rows[level] = (first, end)`` (levels not named: none) into
        the staging folder ``root`` that another writer's :meth:`begin` made; :meth:`rows` then takes exactly the
        rows :meth:`span` gives. Writing a part again writes the same files again (a retried task)."""
        raise NotImplementedError(f"{self.layout}: tile rows are not written in parallel")

    def end_part(self) -> dict:
        """Wait until every tile of the part is written (OutputError otherwise); what :meth:`merge` takes."""
        raise NotImplementedError(f"{self.layout}: tile rows are not written in parallel")

    def merge(self, states: list[dict]) -> None:
        """Take what the parts' :meth:`end_part` returned, before :meth:`finish` (nothing by default)."""
        del states

    @abc.abstractmethod
    def _abort(self) -> None: ...


__all__ = ["TileOptions", "TileSetWriter", "ceil_levels"]
