"""OME-Zarr multiscales: OME-NGFF 0.5 on Zarr v3, written through ``zarr``, with the metadata ``ome-zarr``'s
writer gives (:func:`write_metadata`).

The layout ``ome-zarr`` (``name.ome.zarr`` or ``name.zarr``) is one Zarr v3 group whose arrays ``0``, ``1``, …
are the pyramid's levels, largest first, as ``bioformats2raw`` and ``ome-zarr``'s writer name them, and
whose ``ome`` attributes hold the ``multiscales`` metadata (NGFF 0.5, the version ``ome-zarr`` writes and
reads by default) and the transitional ``omero`` channel metadata (colours, windows):

- **Axes** ``c`` (type channel), ``y``, ``x`` (type space), in this order (NGFF puts the channel axis
  before the space axes); every array is (channels, rows, columns) with ``dimension_names`` ``c, y, x``.
  A one-channel picture keeps its ``c`` axis of length 1.
- **Transformations.** Level k has the scale ``[1, 2^k, 2^k]`` and, from level 1 down, the translation
  ``[0, (2^k − 1)/2, (2^k − 1)/2]`` (:func:`level_transforms`): pixel i of level k is made from input
  pixels ``[2^k·i, 2^k·(i + 1))``, so with pixel centres at integer coordinates (NGFF 0.6's stated
  convention; 0.5 maps array indices to physical coordinates and says no more) its centre lies at
  ``2^k·i + (2^k − 1)/2`` input pixels. ``bioformats2raw`` and ``ome-zarr``'s writer give the scale alone,
  which puts coarse levels up to half a pixel off under that convention; a viewer that ignores the
  translation of levels after the first (napari) shows ours exactly as theirs. No physical unit is known:
  the unit is the input's pixel.
- **Levels** ``⌈n/2⌉`` each (odd sizes padded by the border), until a level fits in one chunk in both
  directions (``bioformats2raw``'s default: the smallest level is no larger than a tile).
- **Chunks** ``(1, T, T)`` with ``T = --tile-size`` (512 by default), no larger than the level; one chunk
  per channel, as ``bioformats2raw`` writes them, so that a viewer that shows each channel as a layer reads
  only its own. **Compression** (``--compression``): zarr's default (Zstandard) unless asked, see
  :func:`codecs`.
- **Values** are stored as a TIFF would store them (:attr:`OmeZarrWriter.encode_as`): the input's type
  (uint8, uint16, float32; half as float16) and colour encoding (an 8-bit sRGB input stays sRGB codes,
  as every other tool stores them; alpha straight in integers, premultiplied in floats). NGFF has no field
  for a colour space or an alpha convention: both are the input's, and nothing in the file says so.

The tile set is built in a hidden folder beside the output (:class:`~pyramid_cli.imageio.tilesets.staging.Staging`),
the metadata written last, and renamed into place; a ``zarr.Group`` given as the output (the Python API) is
written in place, its metadata last, and :meth:`OmeZarrWriter.abort` removes the levels written there.

Memory: each level holds one row of chunks (T rows of that level, stored values) until it is complete;
one chunk row at a time is written by a worker thread (zarr compresses its chunks in parallel) while the
next rows are encoded: at most about ``(levels' widths + the widest) · T · C`` stored values, linear in the
picture's width, not its area (8-bit RGB 16K wide: about 72 MiB; float32: four times that).
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.core.version import __version__
from pyramid_cli.imageio.atomic import error_reason
from pyramid_cli.imageio.formats import output_pixel_type
from pyramid_cli.imageio.image import ImageInfo, info_for_array
from pyramid_cli.imageio.tilesets.base import TileOptions, TileSetWriter, ceil_levels
from pyramid_cli.imageio.tilesets.staging import Staging
from pyramid_cli.imageio.write import diagnosis

DEFAULT_CHUNK = 512
INSTALL = "pip install 'bilinear-pyramid[viewers]'"
AXES = [{"name": "c", "type": "channel"}, {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]
# stored type of each pixel type a TIFF holds (the encode rule); half is float16, which zarr and NGFF hold
DTYPES = {"uint8": np.uint8, "uint16": np.uint16, "half": np.float16, "float": np.float32}
COLOURS = {"R": "FF0000", "G": "00FF00", "B": "0000FF"}
COMPRESSIONS = ("zstd", "blosc", "lz4", "gzip", "none")


def modules(path: object) -> Any:
    """The ``zarr`` module (UsageError, exit 2, naming the extra to install, when it does not import)."""
    try:
        import zarr
    except ImportError as exc:
        raise UsageError(f"cannot write {path}: OME-Zarr needs the {exc.name or 'zarr'} package: "
                         f"{INSTALL}") from None
    return zarr


def level_transforms(k: int) -> list[dict]:
    """NGFF coordinate transformations of level ``k`` (axes c, y, x): its scale, then (k ≥ 1) the
    translation that puts each pixel's centre at the centre of the input pixels it was made from."""
    s = float(2 ** k)
    out: list[dict] = [{"type": "scale", "scale": [1.0, s, s]}]
    if k:
        out.append({"type": "translation", "translation": [0.0, (s - 1) / 2, (s - 1) / 2]})
    return out


def codecs(compression: str | None, path: str) -> Any:
    """zarr's ``compressors`` for ``--compression``: None (zarr's default, Zstandard), ``zstd[:LEVEL]``,
    ``blosc[:LEVEL]`` (Blosc with Zstandard and byte shuffle, level 5: ``ome-zarr``'s writer's), ``lz4[:LEVEL]``
    (Blosc with LZ4, level 5), ``gzip[:LEVEL]`` (also spelt ``zip``/``deflate``, level 6), ``none``; anything
    else is refused (UsageError naming ``path``)."""
    if compression is None:
        return "auto"
    name, _, level = str(compression).strip().lower().partition(":")
    name = "gzip" if name in ("zip", "deflate") else name
    if name not in COMPRESSIONS or level and (not level.isdigit() or name == "none"):
        raise UsageError(f"{path}: unknown --compression {compression} (OME-Zarr takes "
                         f"{', '.join(COMPRESSIONS)}, zip and deflate as gzip; all but none take :LEVEL)")
    from zarr.codecs import BloscCodec, GzipCodec, ZstdCodec

    n = int(level) if level else None
    if name == "none":
        return None
    if name == "zstd":
        return ZstdCodec(level=0 if n is None else n)
    if name == "gzip":
        return GzipCodec(level=6 if n is None else n)
    return BloscCodec(cname="zstd" if name == "blosc" else "lz4", clevel=5 if n is None else n, shuffle="shuffle")


def channel_metadata(names: list[str], dtype: np.dtype, ranges: list[tuple[float, float]] | None) -> dict:
    """The transitional ``omero`` metadata (what ``ome-zarr``'s reader makes napari's colours and contrast
    limits of): R, G and B in their colours and every other channel white, alpha hidden; windows the
    type's range for integers, ``[0, 1]`` shown of the values' range (``ranges``) for floats."""
    channels = []
    for c, name in enumerate(names):
        window: dict[str, float]
        if np.issubdtype(dtype, np.integer):
            info = np.iinfo(dtype)
            window = {"min": int(info.min), "max": int(info.max), "start": 0, "end": int(info.max)}
        else:
            lo, hi = ranges[c] if ranges else (0.0, 1.0)
            window = {"min": float(min(lo, 0.0)), "max": float(max(hi, 1.0)), "start": 0.0, "end": 1.0}
        channels.append({"label": name, "color": COLOURS.get(name, "FFFFFF"), "window": window,
                         "active": name != "A", "coefficient": 1, "family": "linear", "inverted": False})
    colour = sum(n in COLOURS for n in names) == 3
    return {"channels": channels, "rdefs": {"model": "color" if colour else "greyscale"}}


def write_metadata(group: Any, datasets: list[dict], name: str | None, about: dict, omero: dict) -> None:
    """``group``'s ``ome`` attributes (NGFF 0.5): ``omero``, ``version`` and one ``multiscales`` entry of
    ``datasets`` on :data:`AXES`, named ``name`` (else the group's name), its ``metadata`` ``about``; other keys
    of an ``ome`` attribute already there are kept. The same JSON as ``ome-zarr``'s
    ``write_multiscales_metadata`` writes with ``FormatV05`` (the tests compare the two), in one write, without
    importing ``ome-zarr``: its writer imports dask.array and SciPy, 1.9 s of every run's start."""
    ome = dict(group.attrs.get("ome", {}))
    ome.update({"omero": omero, "version": "0.5",
                "multiscales": [{"datasets": datasets, "name": name or group.name, "metadata": about, "axes": AXES}]})
    group.attrs["ome"] = ome


class OmeZarrWriter(TileSetWriter):
    """OME-Zarr multiscales (see the module): levels of rows in, chunk rows out as they complete.

    Parameters
    ----------
    path : str or zarr.Group
        ``name.ome.zarr`` (or any name with ``--layout ome-zarr``), or an open Zarr v3 group to write into.
    info, size, channels, options
        As :class:`~pyramid_cli.imageio.tilesets.base.TileSetWriter`'s.
    levels : int, optional
        Level count (default :meth:`level_count`'s).
    dtype : numpy dtype, optional
        Store values of this type handed to :meth:`put` as they are (the API's arrays) instead of encoding
        linear rows like the input (:meth:`rows`).
    analysis : str, optional
        The analysis filter, recorded in the multiscales ``metadata``.
    """

    layout = "ome-zarr"
    parallel = True
    encode_as = "x.tif"
    default_tile_size = DEFAULT_CHUNK  # the chunk edge without --tile-size (for the run layer's memory estimate)

    def __init__(self, path: Any, info: ImageInfo, size: tuple[int, int], channels: int, options: TileOptions, *,
                 levels: int | None = None, dtype: Any = None, analysis: str | None = None):
        zarr = modules(path if isinstance(path, (str, os.PathLike)) else "the zarr group")
        self.group = None if isinstance(path, (str, os.PathLike)) else path
        if self.group is not None and not isinstance(self.group, zarr.Group):
            raise UsageError(f"out: a zarr.Group or a path ending in .zarr, not {type(path).__name__}")
        shown = os.fspath(path) if self.group is None else f"zarr group {self.group.store}{self.group.path}"
        super().__init__(shown, info, size, channels, options)
        if levels is not None:
            self.sizes = ceil_levels(size, levels)
        self.tile = options.tile_size or DEFAULT_CHUNK
        out_type = output_pixel_type("tiff", options.write.get("pixel_type") or info.pixel_type)
        self.dtype = np.dtype(dtype if dtype is not None else DTYPES.get(out_type, np.float32))
        self.encoded = dtype is None
        self.analysis = analysis
        self.arrays: list[Any] = []
        self.staging: Staging | None = None
        self.pool: ThreadPoolExecutor | None = None
        self.pending: Future | None = None
        self.buffers: list[np.ndarray | None] = [None] * len(self.sizes)
        self.base = [0] * len(self.sizes)      # first row of each level's buffered chunk row
        self.filled = [0] * len(self.sizes)    # rows in it
        self.stop = [h for h, _ in self.sizes]  # rows taken end here (a part: its chunk rows')
        self.ranges: list[tuple[float, float]] | None = None
        self.root: Any = None

    @classmethod
    def level_count(cls, size: tuple[int, int], options: TileOptions) -> int:
        """Levels until one fits in a chunk (``--tile-size``, 512 by default) both ways, as ``bioformats2raw``."""
        tile, (h, w), count = options.tile_size or DEFAULT_CHUNK, size, 1
        while max(h, w) > tile:
            h, w, count = (h + 1) // 2, (w + 1) // 2, count + 1
        return count

    def check(self) -> None:
        """Refuse the options OME-Zarr cannot honour: overlap, a tile file format or quality, an unknown
        compression, a Zarr v2 group, and any write option TIFF's encoding refuses."""
        o = self.options
        if o.overlap:
            raise UsageError(f"{self.path}: --overlap {o.overlap}: OME-Zarr chunks do not overlap")
        if o.suffix is not None or o.quality is not None:
            what = f"--format {o.suffix}" if o.suffix is not None else f"--quality {o.quality}"
            raise UsageError(f"{self.path}: {what}: OME-Zarr stores arrays, not tile files (see --compression)")
        if o.tile_size is not None and o.tile_size < 1:
            raise UsageError(f"{self.path}: --tile-size {o.tile_size}: at least 1")
        codecs(o.compression, self.path)
        if self.group is not None and self.group.metadata.zarr_format != 3:
            raise UsageError(f"{self.path}: a Zarr v2 group; OME-NGFF 0.5 is Zarr v3 (zarr.open_group(..., "
                             "zarr_format=3))")
        if self.encoded:
            try:
                self.encode(np.zeros((1, 1, self.channels), np.float32))
            except UsageError as exc:
                text = str(exc).replace("x.tif", self.path)
                if "--tocolorspace" in text:
                    text = (f"{self.path}: --tocolorspace {self.options.write.get('colorspace')}: OME-Zarr has no "
                            "colour space field, so it stores linear or sRGB values only (as a TIFF)")
                raise UsageError(text) from None

    # ------------------------------------------------------------------ rows in
    @property
    def takes_stored(self) -> bool:  # type: ignore[override]
        """Level 0 from the input's stored rows (where they come back): only when this writer encodes."""
        return self.encoded

    def _rows(self, level: int, y0: int, pixels: np.ndarray, owned: bool) -> None:
        del owned  # encoded here, at once
        self.put(level, y0, self.encode(pixels, y0))

    def _rows_stored(self, level: int, y0: int, stored: np.ndarray) -> None:
        self.put(level, y0, stored.astype(self.dtype, copy=False))

    def put(self, level: int, y0: int, values: np.ndarray) -> None:
        """Stored values (h, W, C) of rows ``y0 ..`` of ``level`` (in order, each row once), cast to the
        stored type; each chunk row is written when complete."""
        values = values if values.ndim == 3 else values[:, :, None]
        if not self.arrays:
            self._start(values.shape[2])
        h, w = self.sizes[level]
        if y0 != self.base[level] + self.filled[level] or y0 + len(values) > self.stop[level] or values.shape[1] != w:
            raise ValueError(f"{self.path}: level {level} expects row {self.base[level] + self.filled[level]} "
                             f"of {h}×{w}, got rows {y0}..{y0 + len(values)} of width {values.shape[1]}")
        i = 0
        while i < len(values):
            buf = self.buffers[level]
            if buf is None:
                rows = min(self.chunk_rows(level), self.stop[level] - self.base[level])
                buf = self.buffers[level] = np.empty((values.shape[2], rows, w), self.dtype)
            n = min(len(values) - i, buf.shape[1] - self.filled[level])
            buf[:, self.filled[level]:self.filled[level] + n] = np.moveaxis(values[i:i + n], 2, 0)
            self.filled[level] += n
            i += n
            if self.filled[level] == buf.shape[1]:
                self._flush(level)

    def chunk_rows(self, level: int) -> int:
        """Rows of a chunk of ``level``: the tile size, or the level's height when smaller."""
        return min(self.tile, self.sizes[level][0])

    def _start(self, channels: int) -> None:
        """The group (staged unless given) and one empty array per level."""
        zarr = modules(self.path)
        compressors = codecs(self.options.compression, self.path)
        try:
            if self.group is None:
                self.staging = Staging([self.path])
                root = zarr.open_group(self.staging.staged[0], mode="w", zarr_format=3)
            else:
                root = self.group
            for k, (h, w) in enumerate(self.sizes):
                self.arrays.append(root.create_array(
                    str(k), shape=(channels, h, w), chunks=(1, min(self.tile, h), min(self.tile, w)), dtype=self.dtype,
                    compressors=compressors, fill_value=0, dimension_names=["c", "y", "x"], overwrite=True))
        except OSError as exc:
            raise self._error(exc) from None
        self.root = root
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="omezarr")
        if self.dtype.kind == "f":
            self.ranges = [(np.inf, -np.inf)] * channels

    def _flush(self, level: int) -> None:
        """Hand the full chunk row of ``level`` to the worker (after the one before it is written)."""
        buf, y = self.buffers[level], self.base[level]
        assert buf is not None and self.pool is not None
        if self.ranges is not None:
            self._track(buf)
        self._wait()
        # a part whose client gave up and removed the staging folder: zarr would make it again
        if self.staging is None and self.group is None and self.root is not None and not os.path.isdir(
                getattr(self.root.store, "root", ".")):
            raise OutputError(f"cannot write {self.path}: its staging folder was removed")
        self.pending = self.pool.submit(self.arrays[level].__setitem__, (slice(None), slice(y, y + buf.shape[1])), buf)
        self.base[level] += buf.shape[1]
        self.filled[level], self.buffers[level] = 0, None

    def _track(self, buf: np.ndarray) -> None:
        """The finite values' range per channel (the omero windows of floats)."""
        assert self.ranges is not None
        for c, plane in enumerate(buf):
            finite = plane[np.isfinite(plane)]
            if finite.size:
                lo, hi = self.ranges[c]
                self.ranges[c] = (min(lo, float(finite.min())), max(hi, float(finite.max())))

    def _wait(self) -> None:
        """Wait for the chunk row being written; its error as an OutputError."""
        pending, self.pending = self.pending, None
        if pending is not None:
            try:
                pending.result()
            except OSError as exc:
                raise self._error(exc) from None

    def _error(self, exc: OSError) -> OutputError:
        where = self.staging.root if self.staging is not None else os.getcwd()
        return OutputError(f"cannot write {self.path}: {error_reason(exc)}{diagnosis(os.path.join(where, 'x'))}")

    # ------------------------------------------------------------------ the end
    def _finish(self) -> dict:
        missing = [k for k in range(len(self.sizes)) if self.base[k] != self.stop[k]]
        if not self.arrays or missing:
            raise ValueError(f"{self.path}: finish() before every row of level(s) {missing or [0]}")
        self._wait()
        self._close()
        names = list(self.info.channel_names) if len(self.info.channel_names) == self.arrays[0].shape[0] else \
            [f"channel{c}" for c in range(self.arrays[0].shape[0])]
        datasets = [{"path": str(k), "coordinateTransformations": level_transforms(k)} for k in range(len(self.sizes))]
        about = {"description": "Kraus & Strengert's analysis filter (GRAPP 2007) in linear light with premultiplied "
                                "alpha; level k pixel i from input pixels [2^k i, 2^k (i + 1)), sizes ceil(n / 2^k)",
                 "method": "pyramid_cli", "version": __version__, "args": {"analysis": self.analysis,
                                                                           "rule": "ceil-half"}}
        name = os.path.basename(self.path.rstrip("/\\"))
        for ext in (".zarr", ".ome"):
            name = name[:-len(ext)] if name.lower().endswith(ext) else name
        try:
            write_metadata(self.root, datasets, name or None, about, channel_metadata(names, self.dtype, self.ranges))
            if self.staging is not None:
                self.staging.commit()
        except OSError as exc:
            raise self._error(exc) from None
        return {"layout": self.layout, "path": self.path, "tile_size": self.tile, "overlap": 0,
                "format": f"zarr v3 (OME-NGFF 0.5), {self.dtype.name}, {self._codec_name()}",
                "levels": [{"level": k, "reduction": k, "size": [w, h], "scale": 2 ** k, "rule": "ceil-half",
                            "chunks": [-(-w // min(self.tile, w)), -(-h // min(self.tile, h))],
                            "translation": level_transforms(k)[-1].get("translation", [0.0, 0.0, 0.0])[1:]}
                           for k, (h, w) in enumerate(self.sizes)]}

    # ------------------------------------------------------------------ parallel parts (--cluster)
    def tile_rows(self, level: int) -> int:
        """Rows of a chunk of ``level`` (:meth:`chunk_rows`)."""
        return self.chunk_rows(level)

    def begin(self) -> str:
        """The staged group and its arrays, for the parts (see the base class); a Zarr group given is refused."""
        if self.group is not None:
            raise UsageError(f"{self.path}: parts are written into a staging folder, not into a zarr group")
        self._start(self.channels)
        assert self.staging is not None
        self.base = list(self.stop)  # this writer takes no rows: the parts write them
        return self.staging.root

    def part(self, root: str, rows: dict[int, tuple[int, int]]) -> None:
        """Write only ``rows`` of chunk rows per level into the arrays staged under ``root`` (see the base class)."""
        zarr = modules(self.path)
        staged = Staging.existing([self.path], root).staged[0]
        try:
            self.root = zarr.open_group(staged, mode="r+", zarr_format=3)
            self.arrays = [self.root[str(k)] for k in range(len(self.sizes))]
        except (OSError, KeyError) as exc:
            raise OutputError(f"cannot write {self.path}: its staging folder {root} cannot be opened "
                              f"({exc})") from None
        for k in range(len(self.sizes)):
            first, end = rows.get(k, (0, 0))
            y0, y1 = self.span(k, first, end) if first < end else (0, 0)
            self.base[k], self.stop[k] = y0, y1
        self.pool = ThreadPoolExecutor(1, thread_name_prefix="omezarr")
        if self.dtype.kind == "f":
            self.ranges = [(np.inf, -np.inf)] * self.channels

    def end_part(self) -> dict:
        """Every chunk row of the part written; the float values' ranges (see the base class)."""
        missing = [k for k in range(len(self.sizes)) if self.base[k] != self.stop[k]]
        if missing:
            raise ValueError(f"{self.path}: level(s) {missing} of the part are not complete")
        self._wait()
        self._close()
        return {"ranges": self.ranges}

    def merge(self, states: list[dict]) -> None:
        """The omero windows of floats from every part's values' range."""
        for state in states:
            ranges = state.get("ranges")
            if not ranges:
                continue
            mine = self.ranges or [(np.inf, -np.inf)] * len(ranges)
            self.ranges = [(min(a, c), max(b, d)) for (a, b), (c, d) in zip(mine, ranges, strict=True)]

    def _codec_name(self) -> str:
        c = self.options.compression
        return "zstd (zarr's default)" if c is None else str(c).lower()

    def _close(self) -> None:
        """Wait for the worker to end (whatever it was writing lands before anything is removed)."""
        if self.pool is not None:
            self.pool.shutdown(wait=True)
            self.pool = None

    def _abort(self) -> None:
        pending, self.pending = self.pending, None
        if pending is not None:
            pending.exception()  # waits; its error no longer matters
        self._close()
        if self.staging is not None:
            self.staging.discard()
        elif self.group is not None:
            for k in range(len(self.arrays)):
                try:
                    del self.group[str(k)]
                except (KeyError, OSError):
                    pass
        self.arrays = []

    def levels(self) -> list[Any]:
        """The written levels as zarr arrays, opened where they now are (after :meth:`finish`)."""
        if self.group is not None:
            return [self.group[str(k)] for k in range(len(self.sizes))]
        root = modules(self.path).open_group(self.path, mode="r")
        return [root[str(k)] for k in range(len(self.sizes))]


def write_levels(out: Any, levels: list[np.ndarray], *, tile_size: int | None = None,
                 compression: str | None = None, analysis: str | None = None) -> list[Any]:
    """Write a pyramid's levels (H×W or H×W×C arrays, each ⌈n/2⌉ of the one before, all of one dtype,
    stored as they are) as OME-Zarr multiscales into ``out`` (a ``zarr.Group`` or a ``.zarr`` path), and
    return them as zarr arrays (c, y, x): what :func:`pyramid_cli.api.pyramid` does with such an ``out``."""
    first = np.asarray(levels[0])
    channels = first.shape[2] if first.ndim == 3 else 1
    w = OmeZarrWriter(out, info_for_array("x.tif", channels), first.shape[:2], channels,
                      TileOptions(tile_size=tile_size, compression=compression), levels=len(levels),
                      dtype=first.dtype, analysis=analysis)
    w.check()
    try:
        for k, level in enumerate(levels):
            w.put(k, 0, np.asarray(level))
        w.finish()
    except BaseException:
        w.abort()
        raise
    return w.levels()


__all__ = ["OmeZarrWriter", "write_levels", "level_transforms", "codecs", "channel_metadata", "write_metadata",
           "DEFAULT_CHUNK"]
