"""Deep Zoom (``name.dzi`` + ``name_files/``) and static IIIF Image API level-0 folders (versions 3 and 2), laid
out exactly as ``vips dzsave`` (``--layout dz``, ``iiif3``, ``iiif``) lays them out, so that a viewer set up for
its output takes ours unchanged.

What is ``vips dzsave``'s (libvips ``foreign/dzsave.c``):

- Deep Zoom: tiles of 254 pixels with 1 pixel of overlap, JPEG Q 75 named ``.jpeg``, levels down to 1×1 numbered
  from the 1×1 one (0) up to the input; tile ``(c, r)`` of a level of W×H holds the pixels
  ``[c·T − o, (c+1)·T + o) × [r·T − o, (r+1)·T + o)`` clipped to the level (edge tiles overlap on their inner sides
  only); the descriptor's XML, byte for byte.
- IIIF: tiles of 512 without overlap, ``.jpg``, levels until one fits in one tile; a tile's folder is its region in
  full-resolution pixels, its size (``w,h`` in version 3, ``w,`` in version 2) and rotation 0
  (``0,0,1024,700/512,350/0/default.jpg``; ``full/…`` for the tile that covers the whole picture), and
  ``info.json`` as dzsave writes it (``id`` ``https://example.com/iiif/NAME`` unless told).
- JPEG as libvips writes it (baseline, standard Huffman tables, 4:2:0 chroma below Q 90, 4:4:4 from Q 90): the
  entropy-coded data of a tile is byte-identical to libvips's for the same pixels; only the header differs (a JFIF
  APP0). WebP at Q 75 (lossy) like ``vips webpsave``.

What is not: ``vips-properties.xml`` (libvips's own metadata dump, which no viewer reads) is not written, and no
metadata goes into the tiles (dzsave's default ``--keep none``).

The rows come in a level at a time, levels interleaved
(:class:`~pyramid_cli.imageio.tilesets.base.TileSetWriter`). They are encoded to their stored values on a pool of
two threads, then each level keeps only the rows of the tile row being completed plus its overlap (``T + 2·o``
rows, stored values); a row of tiles goes to the pool as soon as its last row is in, each tile encoded into memory
(JPEG by imagecodecs's libjpeg-turbo where the ``viewers`` extra installed it, else by OpenImageIO, the same
bytes: :mod:`pyramid_cli.imageio.tilesets.jpeg`) and written with ``os.write`` (a full disk is an error, never a
process exit), all under a hidden staging folder that
:meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.finish` moves into place, the descriptor last. At most a
few bands and :data:`MAX_PENDING` tiles wait for the pool.
"""

from __future__ import annotations

import collections
import json
import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from typing import ClassVar

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core.errors import OutputError, PyramidError, UsageError
from pyramid_cli.imageio.atomic import error_reason
from pyramid_cli.imageio.encode import check_write_options
from pyramid_cli.imageio.formats import png_compression
from pyramid_cli.imageio.image import default_channel_names
from pyramid_cli.imageio.tilesets.base import TileOptions, TileSetWriter
from pyramid_cli.imageio.tilesets.jpeg import jpeg_bytes, libjpeg
from pyramid_cli.imageio.tilesets.staging import Staging
from pyramid_cli.imageio.write import WriteFailed, checked, diagnosis

# tile suffix (as given) → OpenImageIO format, and the dummy name whose format decides the stored values
FORMATS = {"jpeg": "jpeg", "jpg": "jpeg", "png": "png", "webp": "webp", "tif": "tiff", "tiff": "tiff"}
_ENCODE_AS = {"jpeg": "x.jpg", "png": "x.png", "webp": "x.webp", "tiff": "x.tif"}
DEFAULT_QUALITY = 75  # vips dzsave's Q (JPEG and WebP)
THREADS = 2           # encoders beside the band pipeline
MAX_PENDING = 64      # tiles queued for the encoders before rows() waits: bounds the rows held
MAX_BANDS = 3         # bands of rows queued for encoding before rows() waits
MAX_TILE = 8192       # vips dzsave's largest tile size and overlap
IIIF_ID = "https://example.com/iiif"


class _Level:
    """One level's grid and the rows of its tile row being completed."""

    def __init__(self, k: int, size: tuple[int, int], tile: int, overlap: int):
        self.k, (self.height, self.width) = k, size
        self.tile, self.overlap = tile, overlap
        self.cols, self.nrows = -(-self.width // tile), -(-self.height // tile)
        self.row = 0                         # the tile row being filled
        self.next = 0                        # the next row of the level expected
        self.buf: np.ndarray | None = None   # rows span(row) of the level, stored values
        self.filled = 0                      # rows of the level in buf end here
        self.last, self.stop = self.nrows, self.height  # tile rows written end here; rows taken end here

    def limit(self, first: int, end: int) -> None:
        """Write only tile rows ``first .. end − 1``: the rows taken are those they hold (a part, or none)."""
        first, end = max(0, first), min(self.nrows, end)
        if first >= end:
            self.row = self.last = self.nrows
            self.next = self.stop = 0
        else:
            self.row, self.last = first, end
            self.next, self.stop = self.span(first)[0], self.span(end - 1)[1]
        self.buf, self.filled = None, self.next

    def span(self, r: int) -> tuple[int, int]:
        """Rows (or columns, with the width) of tile row ``r``: its T rows and the overlap on its inner sides."""
        return max(0, r * self.tile - self.overlap), min(self.height, (r + 1) * self.tile + self.overlap)

    def col_span(self, c: int) -> tuple[int, int]:
        return max(0, c * self.tile - self.overlap), min(self.width, (c + 1) * self.tile + self.overlap)


class _TileFolderWriter(TileSetWriter):
    """What Deep Zoom and IIIF share: the streaming cut into tiles and their encoding (see the module)."""

    default_tile_size: ClassVar[int]
    default_overlap: ClassVar[int]
    default_suffix: ClassVar[str]

    def __init__(self, path: str, info, size: tuple[int, int], channels: int, options: TileOptions):
        super().__init__(path, info, size, channels, options)
        self.tile = self.tile_size(options)
        self.overlap = self.default_overlap if options.overlap is None else int(options.overlap)
        names = list(info.channel_names)
        self.alpha = (info.alpha_channel >= 0 if len(names) == channels
                      else "A" in default_channel_names(channels))
        suffix = options.suffix
        if suffix is None:  # JPEG holds no alpha: PNG then, as the run layer chooses
            suffix = "png" if self.alpha else self.default_suffix
        self.suffix = self._suffix_name(str(suffix).lower().lstrip("."))
        self.fmt = FORMATS.get(self.suffix, "")
        self.quality = DEFAULT_QUALITY if options.quality is None else int(options.quality)
        self._levels = [_Level(k, s, max(1, self.tile), self.overlap) for k, s in enumerate(self.sizes)]
        self._staging: Staging | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._pending: collections.deque[Future] = collections.deque()
        self._bands: collections.deque[tuple[_Level, Future]] = collections.deque()
        self._template: oiio.ImageSpec | None = None
        self._local = threading.local()
        self._memfds: list[int] = []
        self._lock = threading.Lock()
        self._files = threading.Lock()  # held while a tile's file is made (_write_file)
        self._folders: set[str] = set()  # level folders made (or found) by _write_file
        self._jpeg = libjpeg(self.quality) if self.fmt == "jpeg" else None  # None: OpenImageIO encodes
        self._part = False  # writes tile rows into another writer's staging folder (part)

    # ---------------------------------------------------------------- geometry
    @classmethod
    def tile_size(cls, options: TileOptions) -> int:
        """The tile edge ``options`` asks for, else the layout's default."""
        return cls.default_tile_size if options.tile_size is None else int(options.tile_size)

    def _suffix_name(self, suffix: str) -> str:
        return suffix

    def _tile_path(self, level: _Level, c: int, r: int) -> str:
        """Where tile (c, r) of ``level`` goes, relative to the tile folder."""
        raise NotImplementedError

    def grid(self, k: int) -> tuple[int, int]:
        """(columns, rows) of tiles of level ``k`` (reduction k: 0 is the input)."""
        return self._levels[k].cols, self._levels[k].nrows

    def tile_box(self, k: int, c: int, r: int) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1): the pixels of level ``k`` that tile (c, r) holds, overlap included."""
        (x0, x1), (y0, y1) = self._levels[k].col_span(c), self._levels[k].span(r)
        return x0, y0, x1, y1

    def tile_name(self, k: int, c: int, r: int) -> str:
        """The file of tile (c, r) of level ``k``, relative to :attr:`tile_folder`."""
        return self._tile_path(self._levels[k], c, r)

    @property
    def tile_folder(self) -> str:
        """The folder the tiles go in (Deep Zoom: ``NAME_files``; IIIF: the output)."""
        return self._outputs()[0]

    # ---------------------------------------------------------------- checks
    def check(self) -> None:
        """Refuse a suffix, option, type or channel count these tiles cannot hold (UsageError, one line)."""
        p, o = self.path, self.options
        if not self.fmt:
            raise UsageError(f"{p}: --format {o.suffix}: tiles are jpeg, png, webp or tif")
        if self.fmt not in oiio.get_string_attribute("format_list").split(","):
            raise UsageError(f"{p}: --format {o.suffix}: this OpenImageIO cannot write {self.fmt} files")
        if not 1 <= self.tile <= MAX_TILE:
            raise UsageError(f"{p}: --tile-size {self.tile}: must be 1 to {MAX_TILE}")
        if not 0 <= self.overlap <= MAX_TILE:
            raise UsageError(f"{p}: --overlap {self.overlap}: must be 0 to {MAX_TILE}")
        if o.quality is not None:
            if self.fmt not in ("jpeg", "webp"):
                raise UsageError(f"{p}: --quality has no effect on {self.suffix} tiles (jpeg and webp take it)")
            if not 1 <= int(o.quality) <= 100:
                raise UsageError(f"{p}: --quality {o.quality}: must be 1 to 100")
        if o.compression is not None and self.fmt in ("jpeg", "webp"):
            raise UsageError(f"{p}: --compression has no effect on {self.suffix} tiles (use --quality)")
        if self.fmt == "jpeg":
            if self.alpha:
                raise UsageError(f"{p}: JPEG tiles hold no alpha: use --format png (or webp)")
            if self.channels not in (1, 3):
                raise UsageError(f"{p}: JPEG tiles hold 1 or 3 channels, not {self.channels}: use --format png or tif")
        elif self.fmt == "png" and self.channels > 4:
            raise UsageError(f"{p}: PNG tiles hold 1 to 4 channels, not {self.channels}: use --format tif")
        elif self.fmt == "webp" and self.channels not in (3, 4):
            raise UsageError(f"{p}: WebP tiles hold 3 or 4 channels, not {self.channels}: use --format png or tif")
        w = o.write
        try:
            check_write_options(_ENCODE_AS[self.fmt], w.get("pixel_type"),
                                None if self.fmt in ("jpeg", "webp") else o.compression, w.get("colorspace"),
                                self.info.colorconfig)
        except UsageError as exc:
            raise UsageError(exc.message.replace(_ENCODE_AS[self.fmt], f"{p} ({self.suffix} tiles)")) from None
        limit = _size_limit()
        bound = 2 * (self.tile + 2 * self.overlap) ** 2 * self.channels * 4 + (1 << 20)
        if limit is not None and bound > limit:
            raise OutputError(f"cannot write {p}: a tile may need up to {bound} bytes, over the file size limit "
                              f"(ulimit -f) of {limit} bytes")

    # ---------------------------------------------------------------- rows in
    def encode(self, pixels: np.ndarray, y0: int = 0) -> np.ndarray:
        """Stored values of the rows in the tiles' type and colour space (see
        :meth:`~pyramid_cli.imageio.tilesets.base.TileSetWriter.encode`)."""
        del y0
        enc = self.encoder(pixels.shape[2], _ENCODE_AS[self.fmt])
        if self._template is None:
            self._template = self._tile_spec(enc.spec(pixels.shape[1], pixels.shape[0]))
        return enc.values(pixels)

    def _tile_spec(self, spec: oiio.ImageSpec) -> oiio.ImageSpec:
        """The spec every tile is written with, but its size: no metadata (dzsave's ``--keep none``)."""
        t = oiio.ImageSpec(1, 1, spec.nchannels, spec.format)
        t.channelnames = spec.channelnames
        t.alpha_channel = spec.alpha_channel
        for name in ("oiio:ColorSpace", "oiio:UnassociatedAlpha", "png:filter"):
            if spec.getattribute(name) is not None:
                t.attribute(name, spec.getattribute(name))
        if self.fmt == "jpeg":
            t.attribute("compression", f"jpeg:{self.quality}")
            # libvips's rule: chroma halved both ways below Q 90, kept whole from Q 90
            t.attribute("jpeg:subsampling", "4:4:4" if self.quality >= 90 else "4:2:0")
        elif self.fmt == "webp":
            t.attribute("compression", f"webp:{self.quality}")
        elif self.options.compression is not None:
            c = str(self.options.compression)
            if self.fmt == "png":
                level, filters = png_compression(c)
                t.attribute("png:compressionLevel", level)
                t.attribute("png:filter", filters)
            else:
                t.attribute("compression", c)
        return t

    takes_stored = True

    def _rows(self, level: int, y0: int, pixels: np.ndarray, owned: bool) -> None:
        lv = self._follows(level, y0, pixels)
        if lv is None:
            return
        assert self._pool is not None
        # encoded on the pool (numpy's table lookups let go of the GIL), taken in order: a copy unless owned, since
        # the caller may reuse ``pixels``
        self._bands.append((lv, self._pool.submit(self.encode, pixels if owned else np.array(pixels), y0)))
        self._drain(MAX_BANDS)

    def _rows_stored(self, level: int, y0: int, stored: np.ndarray) -> None:
        lv = self._follows(level, y0, stored)
        if lv is None:
            return
        if self._template is None:  # the spec the tiles are written with comes from an encode
            self.encode(np.zeros((1, 1, self.channels), np.float32))
        done: Future = Future()
        done.set_result(stored)  # in the queue behind the bands still being encoded: taken in order
        self._bands.append((lv, done))
        self._drain(MAX_BANDS)

    def _follows(self, level: int, y0: int, rows: np.ndarray) -> _Level | None:
        """``level``'s state after checking that ``rows`` are its next ones and counting them; None when there
        are none. Starts the tile set with the first rows."""
        lv = self._levels[level]
        if y0 != lv.next or y0 + rows.shape[0] > lv.stop or rows.shape[1] != lv.width:
            raise ValueError(f"level {level}: rows {y0}..{y0 + rows.shape[0]} of width {rows.shape[1]} do not "
                             f"follow row {lv.next} of a {lv.width}x{lv.height} level")
        if rows.shape[0] == 0:
            return None
        if self._staging is None:
            self._start()
        lv.next += rows.shape[0]
        return lv

    def _drain(self, keep: int) -> None:
        """Take the encoded bands that are ready, in the order they came, and wait for the oldest while more than
        ``keep`` are queued."""
        while self._bands and (self._bands[0][1].done() or len(self._bands) > keep):
            lv, band = self._bands.popleft()
            self._take(lv, band.result())

    def _take(self, lv: _Level, data: np.ndarray) -> None:
        """Stored rows of ``lv`` (the next ones) into its tile row; emit what they complete."""
        at = 0
        while at < data.shape[0]:
            start, end = lv.span(lv.row)
            if lv.buf is None:
                lv.buf = np.empty((end - start,) + data.shape[1:], dtype=data.dtype)
                lv.filled = start
            n = min(data.shape[0] - at, end - lv.filled)
            lv.buf[lv.filled - start:lv.filled - start + n] = data[at:at + n]
            lv.filled += n
            at += n
            self._complete(lv)

    def _complete(self, lv: _Level) -> None:
        """Emit every tile row of ``lv`` whose rows are all in; the next one starts with the overlap rows."""
        while lv.buf is not None and lv.filled == lv.span(lv.row)[1]:
            buf, (start, end) = lv.buf, lv.span(lv.row)
            self._emit(lv, buf)
            lv.row += 1
            lv.buf = None
            if lv.row < lv.last:
                nstart, nend = lv.span(lv.row)
                lv.buf = np.empty((nend - nstart,) + buf.shape[1:], dtype=buf.dtype)
                lv.buf[:end - nstart] = buf[nstart - start:]
                lv.filled = end

    def _emit(self, lv: _Level, buf: np.ndarray) -> None:
        """Queue the tiles of ``lv``'s completed tile row (``buf`` is not touched again)."""
        assert self._pool is not None
        for c in range(lv.cols):
            x0, x1 = lv.col_span(c)
            self._pending.append(self._pool.submit(self._write_tile, self._tile_path(lv, c, lv.row), buf[:, x0:x1]))
        while self._pending and (self._pending[0].done() or len(self._pending) > MAX_PENDING):
            self._pending.popleft().result()

    def _start(self) -> None:
        self._staging = Staging(self._outputs())
        try:
            self._prepare(self._staging)
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {error_reason(exc)}") from None
        self._pool = ThreadPoolExecutor(THREADS, thread_name_prefix="tiles")

    # ---------------------------------------------------------------- a tile out
    def _encoder(self) -> tuple[oiio.ImageOutput, int, str]:
        """This thread's OpenImageIO writer, and the memory file it encodes into (its fd and a name for it)."""
        loc = self._local
        if not hasattr(loc, "out"):
            out = oiio.ImageOutput.create(self.fmt)
            if out is None:
                raise WriteFailed(f"no {self.fmt} writer ({oiio.geterror().strip()})")
            if hasattr(os, "memfd_create") and os.path.isdir("/proc/self/fd"):
                fd = os.memfd_create("pyramid-tile", getattr(os, "MFD_CLOEXEC", 0))
                name = f"/proc/self/fd/{fd}"
            else:  # no memory files: a hidden file in the staging folder
                assert self._staging is not None
                name = os.path.join(self._staging.root,
                                    f".encode-{os.getpid()}-{threading.get_ident()}.{self.suffix}")
                fd = os.open(name, os.O_RDWR | os.O_CREAT, 0o600)
            with self._lock:
                self._memfds.append(fd)
            loc.out, loc.mem, loc.name = out, fd, name
        return loc.out, loc.mem, loc.name

    def _write_tile(self, rel: str, tile: np.ndarray) -> None:
        """Encode one tile into memory (libjpeg ends the process on a failed write: never on the disk) and write
        it to its file in the staging folder; OutputError names the user's path."""
        assert self._staging is not None and self._template is not None
        target = os.path.join(self._staging.staged[0], rel)
        try:
            if self._jpeg is not None:
                try:
                    encoded = self._jpeg(tile)
                except (RuntimeError, ValueError) as exc:  # imagecodecs's Jpeg8Error is a RuntimeError
                    raise WriteFailed(f"encode failed: {exc}") from None
                with self._files:  # one file made at a time: see _write_file
                    self._write_file(target, encoded)
                return
            out, mem, name = self._encoder()
            spec = oiio.ImageSpec(self._template)
            spec.width, spec.height = tile.shape[1], tile.shape[0]
            spec.full_width, spec.full_height = spec.width, spec.height
            failure = None  # (OpenImageIO's open truncates the memory file)
            try:
                checked(out, out.open(name, spec), "open")
                checked(out, out.write_image(tile), "write")  # a column slice: OpenImageIO takes its strides
            except WriteFailed as exc:
                failure = exc
            finally:
                closed = out.close()
            if failure is not None:
                raise failure
            checked(out, closed, "close")
            data = self._encoded(mem)
            if not data:
                raise WriteFailed("nothing was encoded")
            with self._files:  # one file made at a time: see _write_file
                self._write_file(target, jpeg_bytes(data) if self.fmt == "jpeg" else data)
        except WriteFailed as exc:
            raise OutputError(f"cannot write {self.path}: {rel}: {exc}{diagnosis(target)}") from None
        except PyramidError:
            raise
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {error_reason(exc)}{diagnosis(target)}") from None

    def _encoded(self, mem: int) -> memoryview:
        """The bytes of the memory file ``mem``, read in one call into this thread's buffer (grown while full): a
        tile's every call that lets go of the GIL waits to take it back while the other threads run Python."""
        loc = self._local
        buf = getattr(loc, "buf", None) or bytearray(1 << 16)
        while (n := os.preadv(mem, [buf], 0)) == len(buf):
            buf = bytearray(2 * len(buf))
        loc.buf = buf
        return memoryview(buf)[:n]

    def _write_file(self, target: str, data: bytes | bytearray | memoryview) -> None:
        """``data`` into the new file ``target`` (its level folder made when missing). The encoders take turns here:
        files made at once in one folder contend for its lock in the kernel, which spins (on ext4 without a
        journal, each new file first passes over every inode deleted in the last minutes: an 8K Deep Zoom written
        just after another was removed spent more CPU spinning there than encoding its tiles)."""
        assert self._staging is not None
        folder = os.path.dirname(target)
        if folder not in self._folders:
            _make_folders(self._staging.staged[0], folder)
            self._folders.add(folder)
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)

    # ---------------------------------------------------------------- the end
    def _finish(self) -> dict:
        self._check_complete("")
        if self._staging is None:
            self._start()
        assert self._staging is not None and self._pool is not None
        self._settle()
        try:
            self._descriptor(self._staging)
        except OSError as exc:
            raise OutputError(f"cannot write {self.path}: {error_reason(exc)}") from None
        self._staging.commit()
        self._staging = None
        return self._describe()

    def _abort(self) -> None:
        if self._pool is not None:
            for f in [*self._pending, *(b for _, b in self._bands)]:
                f.cancel()
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._pending.clear()
        self._bands.clear()
        self._close_encoders()
        if self._staging is not None and not self._part:
            self._staging.discard()
        self._staging = None

    # ---------------------------------------------------------------- parallel parts (--cluster)
    def tile_rows(self, level: int) -> int:
        """Rows of a tile, overlap apart: the tile size at every level."""
        return self._levels[level].tile

    def span(self, level: int, first: int, end: int) -> tuple[int, int]:
        """Rows of tile rows ``first .. end − 1`` with their overlap (see the base class)."""
        lv = self._levels[level]
        first, end = max(0, first), min(lv.nrows, end)
        return (lv.span(first)[0], lv.span(end - 1)[1]) if first < end else (0, 0)

    def begin(self) -> str:
        """The staging folder with its level folders, for the parts (see the base class)."""
        self._start()
        for lv in self._levels:
            lv.limit(0, 0)
        assert self._staging is not None
        return self._staging.root

    def part(self, root: str, rows: dict[int, tuple[int, int]]) -> None:
        """Write only ``rows`` of tile rows per level into ``root`` (see the base class)."""
        self._part = True
        self._staging = Staging.existing(self._outputs(), root)
        for lv in self._levels:
            lv.limit(*rows.get(lv.k, (0, 0)))
        self._pool = ThreadPoolExecutor(THREADS, thread_name_prefix="tiles")

    def end_part(self) -> dict:
        """Every tile of the part written (see the base class)."""
        self._check_complete(" of the part")
        assert self._pool is not None, "part() first"
        self._settle()
        self._staging = None
        return {}

    def _check_complete(self, what: str) -> None:
        """Refuse to end while a level (of the part) still lacks rows: a caller's bug, never the user's."""
        missing = [lv.k for lv in self._levels if lv.next != lv.stop]
        if missing:
            raise ValueError(f"levels {missing}{what} are not complete")

    def _settle(self) -> None:
        """Every queued tile written (its errors raised here), the pool and the encoders closed."""
        assert self._pool is not None, "the pool runs until the end"
        self._drain(0)
        while self._pending:
            self._pending.popleft().result()
        self._pool.shutdown(wait=True)
        self._pool = None
        self._close_encoders()

    def _close_encoders(self) -> None:
        with self._lock:
            fds, self._memfds = self._memfds, []
        for fd in fds:
            try:
                os.close(fd)
            except OSError:
                pass

    def _describe(self) -> dict:
        return {"layout": self.layout, "path": self.path, "tile_size": self.tile, "overlap": self.overlap,
                "format": self.suffix,
                "levels": [{"level": self._level_name(lv.k), "reduction": lv.k, "size": [lv.width, lv.height],
                            "scale": 2 ** lv.k, "rule": "ceil-half", "tiles": [lv.cols, lv.nrows]}
                           for lv in self._levels]}

    def _level_name(self, k: int) -> int:
        return k

    # ---------------------------------------------------------------- per layout
    def _outputs(self) -> list[str]:
        raise NotImplementedError

    def _prepare(self, staging: Staging) -> None:
        os.mkdir(staging.staged[0])

    def _descriptor(self, staging: Staging) -> None:
        raise NotImplementedError


def _size_limit() -> int | None:
    """The process's file size limit (ulimit -f) in bytes, None when unlimited."""
    try:
        import resource
    except ImportError:
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _make_folders(base: str, folder: str) -> None:
    """``folder`` and the folders between it and ``base``, never ``base`` itself: a staging folder removed under a
    part being written (its client gave up) is not made again (FileNotFoundError)."""
    if os.path.isdir(folder) or os.path.normpath(folder) == os.path.normpath(base):
        return
    _make_folders(base, os.path.dirname(folder))
    try:
        os.mkdir(folder)
    except FileExistsError:
        pass


def _write_text(path: str, text: str) -> None:
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


class DeepZoomWriter(_TileFolderWriter):
    """Deep Zoom: ``NAME.dzi`` and ``NAME_files/LEVEL/COL_ROW.SUFFIX`` (see the module)."""

    layout = "dz"
    parallel = True
    default_tile_size = 254
    default_overlap = 1
    default_suffix = "jpeg"

    @classmethod
    def level_count(cls, size: tuple[int, int], options: TileOptions) -> int:
        """Down to 1×1 (dzsave's ``--depth onepixel``)."""
        n, (h, w) = 1, size
        while h > 1 or w > 1:
            h, w, n = (h + 1) // 2, (w + 1) // 2, n + 1
        return n

    def _names(self) -> tuple[str, str]:
        base = self.path[:-4] if self.path.lower().endswith(".dzi") else self.path
        return base + "_files", base + ".dzi"

    def _outputs(self) -> list[str]:
        return list(self._names())

    def _level_name(self, k: int) -> int:
        return len(self.sizes) - 1 - k

    def _prepare(self, staging: Staging) -> None:
        os.mkdir(staging.staged[0])
        for k in range(len(self.sizes)):
            os.mkdir(os.path.join(staging.staged[0], str(self._level_name(k))))

    def _tile_path(self, level: _Level, c: int, r: int) -> str:
        return f"{self._level_name(level.k)}/{c}_{r}.{self.suffix}"

    def descriptor_text(self) -> str:
        """The ``.dzi``, as dzsave writes it."""
        h, w = self.sizes[0]
        return ('<?xml version="1.0" encoding="UTF-8"?>\n'
                '<Image xmlns="http://schemas.microsoft.com/deepzoom/2008"\n'
                f'  Format="{self.suffix}"\n'
                f'  Overlap="{self.overlap}"\n'
                f'  TileSize="{self.tile}"\n'
                '  >\n'
                '  <Size \n'
                f'    Height="{h}"\n'
                f'    Width="{w}"\n'
                '  />\n'
                '</Image>\n')

    def _descriptor(self, staging: Staging) -> None:
        _write_text(staging.staged[1], self.descriptor_text())

    def _describe(self) -> dict:
        return {**super()._describe(), "descriptor": self._names()[1], "folder": self._names()[0]}


class IIIF3Writer(_TileFolderWriter):
    """A static IIIF Image API 3 level-0 folder: ``FOLDER/info.json`` and ``FOLDER/REGION/SIZE/0/default.SUFFIX``
    (see the module)."""

    layout = "iiif3"
    parallel = True
    version: ClassVar[int] = 3
    default_tile_size = 512
    default_overlap = 0
    default_suffix = "jpg"

    @classmethod
    def level_count(cls, size: tuple[int, int], options: TileOptions) -> int:
        """Until a level fits in one tile (dzsave's ``--depth onetile``)."""
        limit, n, (h, w) = max(1, cls.tile_size(options)), 1, size  # a tile size below 1 is refused by check()
        while h > limit or w > limit:
            h, w, n = (h + 1) // 2, (w + 1) // 2, n + 1
        return n

    def check(self) -> None:
        """As every tile folder's, and IIIF tiles do not overlap."""
        if self.overlap:
            raise UsageError(f"{self.path}: --overlap {self.overlap}: IIIF tiles do not overlap (give 0)")
        super().check()

    def _suffix_name(self, suffix: str) -> str:
        return {"jpeg": "jpg", "tiff": "tif"}.get(suffix, suffix)  # IIIF's format names

    def _folder(self) -> str:
        return self.path.rstrip("/" + os.sep) or self.path

    def _outputs(self) -> list[str]:
        return [self._folder()]

    @property
    def image_id(self) -> str:
        """The ``id`` of ``info.json``: the base URL (``--id``) and the folder's name, as dzsave."""
        return f"{self.options.iiif_id or IIIF_ID}/{os.path.basename(self._folder())}"

    def _tile_path(self, level: _Level, c: int, r: int) -> str:
        H, W = self.sizes[0]
        sub, t = 2 ** level.k, self.tile
        left, top = c * t * sub, r * t * sub
        width, height = min(t * sub, W - left), min(t * sub, H - top)
        xsize, ysize = min(t, level.width - c * t), min(t, level.height - r * t)
        region = "full" if (left, top, width, height) == (0, 0, W, H) else f"{left},{top},{width},{height}"
        size = f"{xsize},{ysize}" if self.version == 3 else f"{xsize},"
        return f"{region}/{size}/0/default.{self.suffix}"

    def info_json(self) -> dict:
        """``info.json``'s fields, in dzsave's order."""
        H, W = self.sizes[0]
        head: dict[str, object]
        if self.version == 3:
            head = {"@context": "http://iiif.io/api/image/3/context.json", "id": self.image_id,
                    "type": "ImageService3", "profile": "level0"}
        else:
            head = {"@context": "http://iiif.io/api/image/2/context.json", "@id": self.image_id,
                    "profile": ["http://iiif.io/api/image/2/level0.json",
                                {"formats": [self.suffix], "qualities": ["default"]}]}
        return {**head, "protocol": "http://iiif.io/api/image",
                "tiles": [{"scaleFactors": [2 ** k for k in range(len(self.sizes))], "width": self.tile}],
                "width": W, "height": H}

    def _descriptor(self, staging: Staging) -> None:
        _write_text(os.path.join(staging.staged[0], "info.json"), json.dumps(self.info_json(), indent=2) + "\n")

    def _describe(self) -> dict:
        return {**super()._describe(), "descriptor": os.path.join(self._folder(), "info.json"), "id": self.image_id}


class IIIF2Writer(IIIF3Writer):
    """A static IIIF Image API 2 level-0 folder (sizes ``w,``; ``@id``; the profile lists the format)."""

    layout = "iiif"
    version = 2


__all__ = ["DeepZoomWriter", "IIIF2Writer", "IIIF3Writer"]
