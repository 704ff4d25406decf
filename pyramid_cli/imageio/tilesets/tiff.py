"""Pyramidal tiled TIFF and OME-TIFF, written through tifffile as the levels stream in.

``name.tif`` (:class:`PyramidTiffWriter`): level 0 in the first page, every reduced level in a page of its
own after it, marked NewSubfileType = 1 (reduced resolution), all tiled: the file ``vips tiffsave --tile
--pyramid`` writes, which OpenSlide (its generic tiled TIFF) and tifffile read as one pyramid (QuPath reads
it through either) and OpenImageIO as one subimage per level. ``name.ome.tif`` (:class:`OmeTiffWriter`): the
OME-XML in the first IFD's ImageDescription and the reduced levels as SubIFDs of the full-resolution IFD, as
``bioformats2raw``/``raw2ometiff`` and tifffile's OME writer store them (OpenImageIO sees level 0 only).

Rows are encoded to their stored values on a pool of ``ENCODERS`` threads (the 8-bit sRGB encoding is
most of a writer's time) and stored in the order given. A TIFF holds level 0's tiles first, so they are
written as each row of tiles completes: tifffile's ``TiffWriter.write`` consumes a generator of tiles on a
thread of its own, fed through a short queue by
:meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.rows` (which waits when the file is behind). The
coarser levels (a third of level 0 in all) are kept in a temporary file in the staging folder (explicit reads and
writes: no mapping, nothing of them in the process's memory) and written from it at
:meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.finish`. With JPEG every level's rows of tiles are
compressed on the pool as they complete, by tifffile's own codec and arguments (:meth:`PyramidTiffWriter._pack`:
the bytes tifffile makes, less the tables every tile shares, which each page holds once as JPEGTables, as libtiff
and so ``vips tiffsave`` store them: 15 % of an 8K file at Q 75), and tifffile only writes them; otherwise it
compresses level 0's tiles on its threads
and the coarser levels' stored values at the end. Memory: a few rows of level 0's
tiles (tile size × width × channels each: the one being filled, two queued for the file, and what tifffile
gathers to compress on its threads) and a few bands being encoded, never a whole level.

Levels are ⌈n/2⌉ of the one before (``ceil-half``), as many as ``vips tiffsave --pyramid`` makes: it halves
to ⌊n/2⌋ (dropping an odd last row or column) until a level fits in one tile or a side is 1 pixel (tifffile
finds a pyramid only down to there). So the level count is vips's and each level is vips's or one pixel wider
or taller; the last level may then be one pixel more than a tile (a 257-pixel side with 128-pixel tiles: vips
128, ours 129). vips keeps level 0's resolution tags on every level; here level k's resolution is level 0's
/ 2^k, as tifffile's OME writer and bioformats2raw write it.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.imageio.atomic import error_reason
from pyramid_cli.imageio.encode import encode as encode_image
from pyramid_cli.imageio.image import Image
from pyramid_cli.imageio.spill import KeptChunks, KeptRows
from pyramid_cli.imageio.tilesets.base import TileOptions, TileSetWriter
from pyramid_cli.imageio.tilesets.jpeg import rows_together, shared_tables
from pyramid_cli.imageio.tilesets.staging import Staging

TILE = 256  # the default tile edge (vips tiffsave's is 128: give --tile-size 128 for its grid)
QUALITY = 75  # JPEG quality, vips's Q
# --compression: name -> tifffile's name; "none" by default, as vips tiffsave
CODECS = {"none": None, "jpeg": "jpeg", "deflate": "zlib", "zip": "zlib", "zstd": "zstd", "lzw": "lzw",
          "packbits": "packbits"}
_LEVELLED = ("deflate", "zip", "zstd")  # take :LEVEL
_IMAGECODECS = {"jpeg": "JPEG8", "deflate": "ZLIB", "zip": "ZLIB", "zstd": "ZSTD", "lzw": "LZW", "packbits": "PACKBITS"}
_DTYPES = {"uint8": np.uint8, "uint16": np.uint16, "half": np.float16, "float": np.float32}
_NAMES = {np.dtype(t).name: name for name, t in _DTYPES.items()}
_UNITS = {"in": ("INCH", 25400.0), "inch": ("INCH", 25400.0), "cm": ("CENTIMETER", 1e4),
          "centimeter": ("CENTIMETER", 1e4)}  # OpenImageIO's ResolutionUnit -> tifffile's, µm per unit
_QUEUED = 2  # rows of level-0 tiles waiting for the file at most
ENCODERS = 2  # threads encoding rows to stored values beside the band pipeline
_ENCODING = 2  # bands being encoded before rows() waits for the oldest (copies of the caller's float rows)
_PACKING = 2   # rows of tiles of levels 1.. being compressed before rows() waits for the oldest


class _Aborted(Exception):
    """Raised in the tile generator to stop tifffile's write when the run is aborted."""


def _tiles(band: np.ndarray, tile: int, pad: bool) -> Iterator[np.ndarray]:
    """The tiles of one row of tiles, left to right (one channel: 2-D, as tifffile takes a grey image);
    ``pad``: edge tiles filled out to ``tile`` × ``tile`` by repeating their last row and column (JPEG's blocks
    across the edge stay smooth; tifffile pads with zeros)."""
    if band.shape[2] == 1:
        band = band[..., 0]
    for x in range(0, band.shape[1], tile):
        t = band[:, x:x + tile]
        if pad and t.shape[:2] != (tile, tile):
            t = np.pad(t, ((0, tile - t.shape[0]), (0, tile - t.shape[1])) + ((0, 0),) * (t.ndim - 2), mode="edge")
        yield t


@dataclass(frozen=True)
class _Jpeg:
    """A pyramidal TIFF's JPEG tiles: tifffile's codec with the arguments its ``write`` would give it, the tile shape,
    the tables every tile shares (each page's JPEGTables) and how a tile is stored without them
    (:func:`~pyramid_cli.imageio.tilesets.jpeg.shared_tables`)."""

    encode: Callable[..., bytes]
    shape: tuple[int, int, int]
    args: dict
    tables: bytes
    store: Callable[[bytes], bytes]


class PyramidTiffWriter(TileSetWriter):
    """A pyramidal tiled TIFF (``name.tif``): reduced levels as further pages, NewSubfileType = 1 (see the
    module). ``--compression`` none (default, as vips), jpeg (8-bit grey or RGB; ``--quality``, 75 by default),
    deflate|zstd[:LEVEL], lzw, packbits; ``--tile-size`` a multiple of 16 (256 by default); no overlap."""

    layout: ClassVar[str] = "tiff"
    ome: ClassVar[bool] = False

    def __init__(self, path, info, size, channels, options: TileOptions):
        super().__init__(path, info, size, channels, options)
        self.tile = options.tile_size or TILE
        self.codec = str(options.compression or "none").strip().lower()
        self._staging: Staging | None = None
        self._spill: KeptRows | None = None
        self._tif: Any = None
        self._thread: threading.Thread | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=_QUEUED)
        self._stop = threading.Event()
        self._failure: BaseException | None = None
        self._bands: list[np.ndarray | None] = [None] * len(self.sizes)  # each level's row of tiles being filled
        self._packed: KeptChunks | None = None  # levels 1..'s tiles compressed as they complete (JPEG)
        self._packing: deque[tuple[int, Future]] = deque()  # rows of tiles being compressed, in level order
        self._given = [0] * len(self.sizes)   # rows received per level
        self._done = [0] * len(self.sizes)    # rows stored per level
        self._pool: ThreadPoolExecutor | None = None
        self._encoding: deque[tuple[int, int, Future]] = deque()  # bands being encoded, in the order given
        self._spec: Any = None
        self._jpeg: _Jpeg | None = None  # see _codec

    @classmethod
    def level_count(cls, size: tuple[int, int], options: TileOptions) -> int:
        """``vips tiffsave --pyramid``'s level count, level 0 included: halve (⌊n/2⌋, as vips) until a level
        fits in one tile (``options.tile_size``, 256 by default) or a side is 1 pixel."""
        tile = max(1, options.tile_size or TILE)
        h, w = size
        n = 1
        while (h > tile or w > tile) and h >= 2 and w >= 2:
            h, w, n = h // 2, w // 2, n + 1
        return n

    # ---- what the file stores ----

    def check(self) -> None:
        """Refuse a tile size that is not a multiple of 16, an overlap, a tile suffix, an unknown compression,
        a quality without JPEG, JPEG of anything but 8-bit grey or RGB, and a missing tifffile."""
        p, o = self.path, self.options
        if os.path.isdir(p):
            raise OutputError(f"cannot write {p}: it is a directory")
        if self.tile < 16 or self.tile % 16:
            raise UsageError(f"{p}: --tile-size {self.tile}: TIFF tiles are a multiple of 16 pixels")
        if o.overlap:
            raise UsageError(f"{p}: --overlap {o.overlap}: TIFF tiles do not overlap (Deep Zoom's do)")
        if o.suffix is not None:
            raise UsageError(f"{p}: --format {o.suffix}: a TIFF's tiles are inside it; give --compression "
                             f"({', '.join(CODECS)})")
        name, _, level = self.codec.partition(":")
        if name not in CODECS or level and (name not in _LEVELLED or not level.isdigit()):
            raise UsageError(f"{p}: unknown --compression {o.compression} (a TIFF takes {', '.join(CODECS)}; "
                             f"{', '.join(c for c in _LEVELLED if c != 'zip')} take :LEVEL)")
        if o.quality is not None:
            if name != "jpeg":
                raise UsageError(f"{p}: --quality {o.quality} applies to --compression jpeg only")
            if not 1 <= o.quality <= 100:
                raise UsageError(f"{p}: --quality {o.quality}: 1 to 100")
        try:
            import imagecodecs
            import tifffile  # noqa: F401
        except ImportError:
            raise UsageError(f"{p}: writing TIFF pyramids needs tifffile and imagecodecs: "
                             "pip install 'bilinear-pyramid[viewers]'") from None
        spec = self._stored()
        if name == "jpeg":
            if self.dtype != np.uint8 or spec.nchannels not in (1, 3):
                raise UsageError(f"{p}: --compression jpeg holds 8-bit grey or RGB without alpha; this image "
                                 f"stores {spec.nchannels} channel(s) of {spec.format} (give --compression deflate)")
        if name != "none":
            codec = getattr(imagecodecs, _IMAGECODECS[name], None)
            if codec is None or not getattr(codec, "available", False):
                raise UsageError(f"{p}: --compression {name}: imagecodecs has no {name} codec here")

    def _stored(self):
        """The spec of what the file stores (type, channels, alpha, resolution, ICC), from a one-pixel encode."""
        if self._spec is None:
            px = np.zeros((1, 1, self.channels), np.float32)
            # the input's type unless --type says: tifffile writes half as half (OpenImageIO's TIFF writer, which
            # a plain write goes through, stores a half input as float: encode.stored_type)
            write = dict(self.options.write, pixel_type=self.options.write.get("pixel_type") or self.info.pixel_type)
            spec, _ = encode_image(self.encode_as, Image(px, self.info), check_path=False, **write)
            self._spec = spec
        return self._spec

    @property
    def dtype(self) -> np.dtype:
        """The stored sample type (the input's, as a TIFF holds it)."""
        return np.dtype(_DTYPES.get(str(self._stored().format), np.float32))

    def encode(self, pixels: np.ndarray, y0: int = 0) -> np.ndarray:
        """Stored values of linear premultiplied rows, in :attr:`dtype` (half stays half)."""
        data = super().encode(pixels, y0)
        if data.ndim == 2:
            data = data[..., None]
        return data.astype(self.dtype, copy=False)

    def _page_options(self, k: int) -> dict:
        """tifffile's ``write`` arguments for level ``k`` (photometric, extra samples, codec, resolution, the JPEG
        tables of the tiles compressed here, ...)."""
        spec = self._stored()
        n, alpha = spec.nchannels, spec.alpha_channel
        colour = 3 if n >= 3 else 1
        extra = []
        for c in range(colour, n):
            if c == alpha:
                extra.append("unassalpha" if spec.get_int_attribute("oiio:UnassociatedAlpha", 0) else "assocalpha")
            else:
                extra.append("unspecified")
        name = self.codec.partition(":")[0]
        kw: dict[str, Any] = {"tile": (self.tile, self.tile), "photometric": "rgb" if colour == 3 else "minisblack",
                              "compression": CODECS[name], "maxworkers": 2,
                              # tiles tifffile gathers before compressing them: about one row of level 0's
                              "buffersize": max(1 << 22, self.tile * self.sizes[0][1] * n * self.dtype.itemsize)}
        if n > 1:
            kw["planarconfig"] = "contig"
        if extra:
            kw["extrasamples"] = extra
        args = self._compression_args()
        if args:
            kw["compressionargs"] = args
        if self._packs():
            kw["jpegtables"] = self._codec().tables
        if name in ("deflate", "zip", "zstd", "lzw"):
            kw["predictor"] = True  # horizontal differencing (floating point for floats), as vips's default
        if k:
            kw["subfiletype"] = 1
        res = self._resolution()
        if res is not None:
            (x, y), unit, _ = res
            kw["resolution"], kw["resolutionunit"] = (x / 2 ** k, y / 2 ** k), unit
        icc = spec.getattribute("ICCProfile")  # the input's, kept when the stored values are in its space
        if icc is not None:
            kw["iccprofile"] = bytes(np.asarray(icc, dtype=np.uint8))
        return kw

    def _compression_args(self) -> dict:
        """The codec's level as tifffile takes it: ``--quality`` for JPEG (75 by default), else ``CODEC:LEVEL``'s."""
        name, _, level = self.codec.partition(":")
        if name == "jpeg":
            return {"level": self.options.quality or QUALITY}
        return {"level": int(level)} if level else {}

    def _resolution(self) -> tuple[tuple[float, float], str, float] | None:
        """Level 0's (x, y) pixels per unit, tifffile's unit and µm per unit, when the input said them."""
        spec = self._stored()
        x, y = spec.get_float_attribute("XResolution", 0.0), spec.get_float_attribute("YResolution", 0.0)
        unit = _UNITS.get(spec.get_string_attribute("ResolutionUnit", "").lower())
        if x <= 0 or y <= 0 or unit is None:
            return None
        return (x, y), unit[0], unit[1]

    def _metadata(self) -> dict | None:
        """The first page's ImageDescription: none for a plain TIFF (vips writes none; tifffile's JSON would
        make it read the pyramid as one shaped series)."""
        return None

    # ---- streaming ----

    def _start(self) -> None:
        """The staging folder, the spill of levels 1.., the file and the thread writing level 0's tiles."""
        import tifffile

        self._staging = Staging([self.path])
        c, item = self._stored().nchannels, self.dtype.itemsize
        shapes = [(h, w, c) for h, w in self.sizes]
        if len(shapes) > 1 and self._packs():
            self._packed = KeptChunks(len(shapes) - 1, os.path.join(self._staging.root, "levels.jpeg"),
                                      beside=self.path, what="reduced levels")
        elif len(shapes) > 1:
            self._spill = KeptRows(shapes[1:], os.path.join(self._staging.root, "levels.raw"), self.dtype,
                                   beside=self.path, what="reduced levels")
        total = sum(h * w for h, w, _ in shapes) * c * item
        try:
            self._tif = tifffile.TiffWriter(self._staging.staged[0], bigtiff=total > 2**32 - 2**26, ome=self.ome)
        except OSError as exc:
            raise self._error(exc) from None
        self._pool = ThreadPoolExecutor(ENCODERS, thread_name_prefix="tiff-encode")
        self._thread = threading.Thread(target=self._write_level0, name="tiff-level0", daemon=True)
        self._thread.start()

    def _shape(self, k: int) -> tuple[int, ...]:
        """Level ``k``'s shape as tifffile takes it: (h, w) for one channel, else (h, w, channels)."""
        n = self._stored().nchannels
        return self.sizes[k] if n == 1 else (*self.sizes[k], n)

    def _write_level0(self) -> None:
        kw = self._page_options(0)
        if self.ome and len(self.sizes) > 1:
            kw["subifds"] = len(self.sizes) - 1
        try:
            self._tif.write(self._queued(), shape=self._shape(0), dtype=self.dtype,
                            metadata=self._metadata(), **kw)
        except BaseException as exc:  # surfaced by rows()/finish() on the caller's thread
            self._failure = exc

    def _queued(self) -> Iterator[np.ndarray | bytes]:
        """Level 0's tiles in file order, as rows() completes them: compressed on the pool already (JPEG,
        :meth:`_packs`), else for tifffile to compress."""
        pad = self.codec.startswith("jpeg")
        for _ in range(-(-self.sizes[0][0] // self.tile)):
            while True:
                if self._stop.is_set():
                    raise _Aborted
                try:
                    band = self._queue.get(timeout=0.1)
                    break
                except queue.Empty:
                    continue
            if band is None:
                raise _Aborted
            if isinstance(band, Future):
                yield from band.result()
            else:
                yield from _tiles(band, self.tile, pad)

    def _put(self, band: np.ndarray | Future) -> None:
        """Hand a row of tiles to the file's thread, waiting while it is behind; its failure is raised here."""
        while True:
            self._raise_failure()
            try:
                self._queue.put(band, timeout=0.1)
                return
            except queue.Full:
                continue

    def _raise_failure(self) -> None:
        if self._failure is not None:
            exc = self._failure
            if isinstance(exc, OutputError | UsageError):
                raise exc
            if isinstance(exc, OSError):
                raise self._error(exc)
            raise RuntimeError(f"writing {self.path}: {exc!r}") from exc

    def _error(self, exc: OSError) -> OutputError:
        from pyramid_cli.imageio.write import diagnosis

        where = self._staging.staged[0] if self._staging else self.path
        return OutputError(f"cannot write {self.path}: {error_reason(exc)}{diagnosis(where)}")

    takes_stored = True

    def _rows(self, level: int, y0: int, pixels: np.ndarray, owned: bool) -> None:
        self._follows(level, y0, pixels)
        assert self._pool is not None
        # encoded on the pool (numpy's table lookups let go of the GIL), stored in the order given: a copy unless
        # owned, since the caller may reuse its rows
        rows = np.asarray(pixels, np.float32) if owned else np.array(pixels, np.float32)
        self._encoding.append((level, y0, self._pool.submit(self.encode, rows, y0)))
        self._take(_ENCODING)

    def _rows_stored(self, level: int, y0: int, stored: np.ndarray) -> None:
        self._follows(level, y0, stored)
        done: Future = Future()
        done.set_result(stored.astype(self.dtype, copy=False))  # behind the bands being encoded: stored in order
        self._encoding.append((level, y0, done))
        self._take(_ENCODING)

    def _follows(self, level: int, y0: int, rows: np.ndarray) -> None:
        """Check that ``rows`` are ``level``'s next ones and count them; starts the file with the first rows."""
        if self._staging is None:
            self._start()
        if y0 != self._given[level]:
            raise ValueError(f"level {level}: rows from {y0} given, {self._given[level]} expected")
        self._given[level] = y0 + len(rows)

    def _take(self, keep: int) -> None:
        """Store the encoded bands that are ready, in the order they came, waiting for the oldest while more than
        ``keep`` are being encoded."""
        while self._encoding and (len(self._encoding) > keep or self._encoding[0][2].done()):
            level, y0, future = self._encoding.popleft()
            self._store(level, y0, future.result())

    def _store(self, level: int, y0: int, data: np.ndarray) -> None:
        """Stored rows ``y0..`` of ``level``: level 0 into its row of tiles, handed to the file's thread when
        complete; levels 1.. likewise into rows of tiles compressed on the pool (JPEG), else to the spill."""
        self._done[level] = y0 + len(data)
        if level and self._packed is None:
            assert self._spill is not None, "levels 1.. have a spill"
            self._spill.write(level - 1, y0, data)
            return
        assert self._pool is not None
        for band in self._tile_rows(level, y0, data):
            if not level:
                self._put(self._pool.submit(self._pack, band) if self._packs() else band)
                continue
            self._packing.append((level, self._pool.submit(self._pack, band)))
            self._unpack(_PACKING)

    def _tile_rows(self, level: int, y0: int, data: np.ndarray) -> Iterator[np.ndarray]:
        """Each row of tiles of ``level`` that rows ``y0..`` complete (filled in :attr:`_bands`)."""
        h, w = self.sizes[level]
        t, at = self.tile, 0
        while at < len(data):
            y = y0 + at
            band = self._bands[level]
            if band is None:
                band = self._bands[level] = np.empty((min(t, h - y), w, data.shape[2]), self.dtype)
            r = y % t
            n = min(len(data) - at, len(band) - r)
            band[r:r + n] = data[at:at + n]
            at += n
            if r + n == len(band):
                self._bands[level] = None
                yield band

    def _packs(self) -> bool:
        """Whether every level's rows of tiles are compressed on the pool as they complete (JPEG: tifffile's codec
        called alone, :meth:`_pack`), tifffile then only writing them, rather than compressed by tifffile: level
        0's on its threads, the coarser levels' stored values at the end."""
        return self.codec.startswith("jpeg")

    def _pack(self, band: np.ndarray) -> list[bytes]:
        """A row of tiles as the file stores them: tifffile's own JPEG encoding of each, as its ``write`` sets it
        up for these pages (its codec at the level asked, and for RGB the 2×2 subsampling into YCbCr it writes the
        tags of), so the file holds the bytes tifffile would have made, less the tables (:meth:`_codec`)."""
        c = self._codec()
        return [c.store(c.encode(rows_together(t).reshape(c.shape), **c.args)) for t in _tiles(band, self.tile, True)]

    def _codec(self) -> _Jpeg:
        """How this file's JPEG tiles are made and stored (:class:`_Jpeg`), the same for every level and row."""
        if self._jpeg is None:  # two pool threads may both make it: no matter
            import tifffile

            args = self._compression_args()
            n = self._stored().nchannels
            if n == 3:
                args.update(subsampling=(2, 2), colorspace="RGB", outcolorspace="YCBCR")
            encode, shape = tifffile.TIFF.COMPRESSORS[7], (self.tile, self.tile, n)
            self._jpeg = _Jpeg(encode, shape, args, *shared_tables(encode(np.zeros(shape, self.dtype), **args)))
        return self._jpeg

    def _unpack(self, keep: int) -> None:
        """Keep the compressed rows of tiles that are ready, in the order they came, waiting for the oldest while
        more than ``keep`` are being compressed."""
        assert self._packed is not None
        while self._packing and (len(self._packing) > keep or self._packing[0][1].done()):
            level, future = self._packing.popleft()
            for data in future.result():
                self._packed.append(level - 1, data)

    def _finish(self) -> dict:
        if self._staging is None:
            raise ValueError("no rows were given")
        self._raise_failure()
        assert self._pool is not None
        self._take(0)
        if self._packed is not None:
            self._unpack(0)
        self._pool.shutdown()
        missing = [k for k, (h, _) in enumerate(self.sizes) if self._done[k] != h]
        if missing:
            raise ValueError(f"level(s) {missing} incomplete")
        assert self._thread is not None
        while self._thread.is_alive():
            self._thread.join(0.1)
        self._raise_failure()
        try:
            for k in range(1, len(self.sizes)):
                tiles = self._from_spill(k) if self._packed is None else self._packed.chunks(k - 1)
                self._tif.write(tiles, shape=self._shape(k), dtype=self.dtype,
                                metadata=None if not self.ome else {}, **self._page_options(k))
            tif, self._tif = self._tif, None
            tif.close()
            with open(self._staging.staged[0], "rb+") as fh:
                os.fsync(fh.fileno())
            for kept in (self._spill, self._packed):
                if kept is not None:
                    kept.close()
            self._staging.commit()
        except OSError as exc:
            raise self._error(exc) from None
        return self._report()

    def _from_spill(self, k: int) -> Iterator[np.ndarray]:
        assert self._spill is not None
        h = self.sizes[k][0]
        pad = self.codec.startswith("jpeg")
        for y in range(0, h, self.tile):
            yield from _tiles(self._spill.rows(k - 1, y, min(h, y + self.tile)), self.tile, pad)

    def _report(self) -> dict:
        t = self.tile
        levels = [{"level": k, "reduction": k, "size": [w, h], "scale": 2 ** k, "rule": "ceil-half",
                   "tiles": [-(-w // t), -(-h // t)]} for k, (h, w) in enumerate(self.sizes)]
        return {"layout": self.layout, "path": self.path, "tile_size": t, "overlap": 0, "format": "tiff",
                "compression": self.codec, "dtype": _NAMES[self.dtype.name], "levels": levels}

    def _abort(self) -> None:
        self._stop.set()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._encoding.clear()
        self._packing.clear()
        with contextlib.suppress(queue.Full):
            self._queue.put_nowait(None)
        if self._thread is not None:
            while self._thread.is_alive():
                self._thread.join(0.1)
        if self._tif is not None:
            with contextlib.suppress(Exception):
                self._tif.close()
            self._tif = None
        for kept in (self._spill, self._packed):
            if kept is not None:
                kept.close()
        if self._staging is not None:
            self._staging.discard()


class OmeTiffWriter(PyramidTiffWriter):
    """An OME-TIFF (``name.ome.tif``): OME-XML in the first IFD, the reduced levels as its SubIFDs (see the
    module); options as :class:`PyramidTiffWriter`'s. The physical pixel size is the input's resolution; half
    is stored as float."""

    layout: ClassVar[str] = "ome-tiff"
    ome: ClassVar[bool] = True

    @property
    def dtype(self) -> np.dtype:
        """The stored sample type; half is stored as float (OME-XML has no 16-bit float type), the same values."""
        dtype = super().dtype
        return np.dtype(np.float32) if dtype == np.float16 else dtype

    def _metadata(self) -> dict | None:
        spec = self._stored()
        name = os.path.basename(self.path)
        for ends in (".ome.tiff", ".ome.tif", ".tiff", ".tif"):
            if name.lower().endswith(ends):
                name = name[:-len(ends)]
                break
        meta: dict[str, Any] = {"axes": "YXS" if spec.nchannels > 1 else "YX", "Name": name or "image"}
        res = self._resolution()
        if res is not None:
            (x, y), _, um = res
            meta.update(PhysicalSizeX=um / x, PhysicalSizeXUnit="µm", PhysicalSizeY=um / y,
                        PhysicalSizeYUnit="µm")
        return meta


__all__ = ["CODECS", "OmeTiffWriter", "PyramidTiffWriter"]
