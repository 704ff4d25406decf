"""Images read and written a band of rows at a time (:mod:`pyramid_cli.run.stream`), each band decoded
and encoded exactly as the whole picture would be."""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Callable, Iterable, Sequence

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core import options
from pyramid_cli.core.errors import InputError, OutputError
from pyramid_cli.imageio.atomic import atomic_paths
from pyramid_cli.imageio.codecs import CodecMemory, exr_codec_memory
from pyramid_cli.imageio.encode import Encoder, check_output_path, check_write_options, set_windows
from pyramid_cli.imageio.formats import (
    ALPHA_MODES,
    ENCODE_IN_MEMORY,
    check_choice,
    format_from_path,
    format_title,
    one_line,
    pixel_type_name,
)
from pyramid_cli.imageio.image import ImageInfo
from pyramid_cli.imageio.ocio import check_names
from pyramid_cli.imageio.read import (
    apply_nan_policy,
    check_input_file,
    decode_stored,
    decoding,
    describe_spec,
    open_input,
    readable_name,
)
from pyramid_cli.imageio.write import WriteFailed, checked, diagnosis, verify


class ImageStream:
    """An image file read a band of rows at a time, each band decoded exactly as
    :func:`~pyramid_cli.imageio.read.read_image` decodes the whole picture (the decoding is pixel by pixel).
    Use :func:`open_stream`; close it (or ``with``).

    Attributes
    ----------
    info : ImageInfo
        What :func:`~pyramid_cli.imageio.read.read_image` would report.
    shape : tuple
        (rows, columns, channels).
    dtype : numpy dtype
        Of the bands :meth:`read` returns: float32, or float16 for a half file under ``keep_half`` without
        colour or alpha conversion.
    nonfinite : int
        NaN/Inf values seen so far (kept under ``nan="keep"``).
    stored_dtype : numpy dtype
        Of the rows as stored (uint8, uint16, float16 or float32), before decoding: what ``on_stored`` is given.
    chunk_rows : int
        Rows the file stores together (a row of tiles; an OpenEXR or TIFF file's chunk of scanlines or strip:
        OpenImageIO's ``oiio:RowsPerChunk``), 1 for formats read row by row. A band is read in pieces cut at
        its chunks' edges (:func:`chunk_pieces`).
    """

    def __init__(self, path: str, *, colorspace: str = "auto", alpha: str = "auto", nan: str = "keep",
                 keep_half: bool = False, colorconfig: str | None = None):
        check_names(colorspace, colorconfig=colorconfig)
        check_choice("alpha mode", alpha, ("auto", *ALPHA_MODES))
        check_choice("nan mode", nan, options.NAN_POLICIES)
        self.path = p = os.fspath(path)
        check_input_file(p)
        fmt = self._open()
        spec = self._spec
        self.info = describe_spec(spec, fmt, p, colorspace, alpha, colorconfig=colorconfig)
        native = pixel_type_name(spec.format)
        uniform = len({str(t) for t in spec.channelformats}) <= 1
        keep = ("uint8", "uint16", "half") if keep_half else ("uint8", "uint16")
        self._read_type = native if native in keep and uniform else "float"
        self.nan = nan
        self.nonfinite = 0
        self.shape = (spec.height, spec.width, spec.nchannels)
        probe = {"uint8": np.uint8, "uint16": np.uint16, "half": np.float16}.get(self._read_type, np.float32)
        self.dtype = decode_stored(np.zeros((1, 1, spec.nchannels), dtype=probe), self.info).dtype
        self.stored_dtype = np.dtype(probe)  # of the rows on_stored is given
        tiled = spec.tile_width > 0 and spec.tile_height > 0
        self.chunk_rows = int(spec.tile_height) if tiled else max(1, spec.get_int_attribute("oiio:RowsPerChunk", 1))
        self._block: tuple[int, np.ndarray] | None = None  # a row of tiles, for tiled files
        self.on_stored = None  # called with each band's rows as stored, before decoding (mipmap's SHA-1)

    def _open(self) -> str:
        """Open the file (its input, spec and subimage); its format."""
        self._stack = contextlib.ExitStack()
        name = self._name = self._stack.enter_context(readable_name(self.path))
        self._inp, self._spec, fmt, self._subimage = open_input(name, None, self.path)
        self._stack.callback(self._inp.close)
        return fmt

    def reopen(self) -> None:
        """Open the file again, in place, from its first row: OpenEXR gives a file as many line buffers as it has
        codec threads when the file opens (:func:`~pyramid_cli.imageio.codecs.limited_exr_threads`)."""
        self._stack.close()
        self._open()
        self._block = None

    def codec_memory(self) -> CodecMemory:
        """What OpenEXR's codec holds for this file (nothing for other formats:
        :func:`~pyramid_cli.imageio.codecs.exr_codec_memory`)."""
        return exr_codec_memory(self._spec, self.info.format)

    def __enter__(self) -> ImageStream:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._stack.close()

    def _stored(self, y0: int, y1: int) -> np.ndarray:
        spec, inp = self._spec, self._inp
        if spec.tile_width > 0 and spec.tile_height > 0:  # whole rows of tiles, kept for the next band
            th = self.chunk_rows
            parts = []
            y = y0
            while y < y1:
                t0 = y // th * th
                if self._block is None or self._block[0] != t0:
                    t1 = min(t0 + th, spec.height)
                    data = inp.read_tiles(self._subimage, 0, spec.x, spec.x + spec.width, spec.y + t0, spec.y + t1,
                                          spec.z, spec.z + 1, 0, spec.nchannels, self._read_type)
                    self._check(data)
                    self._block = (t0, np.asarray(data).reshape(t1 - t0, spec.width, spec.nchannels))
                t0, block = self._block
                take = block[y - t0:min(y1, t0 + len(block)) - t0]
                parts.append(take.copy())  # decoded in place: the kept block stays as stored
                y += len(take)
            return parts[0] if len(parts) == 1 else np.concatenate(parts)
        parts = [self._scanlines(a, b) for a, b in chunk_pieces(y0, y1, self.chunk_rows, spec.height)]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _scanlines(self, y0: int, y1: int) -> np.ndarray:
        spec = self._spec
        data = self._inp.read_scanlines(self._subimage, 0, spec.y + y0, spec.y + y1, spec.z, 0, spec.nchannels,
                                        self._read_type)
        self._check(data)
        return np.asarray(data).reshape(y1 - y0, spec.width, spec.nchannels)

    def _check(self, data) -> None:
        err = self._inp.geterror() if self._inp.has_error else ""
        if data is None or err:
            err = (err or oiio.geterror()).replace(self._name, self.path)
            raise InputError(f"cannot read {self.path}: {one_line(err, 'read failed')} (truncated or corrupt file?)")

    def read_stored(self, y0: int, y1: int) -> np.ndarray:
        """Rows ``y0 .. y1 − 1`` as stored (:attr:`stored_dtype`), not decoded: for a consumer that reads 8/16-bit
        codes through :func:`~pyramid_cli.imageio.read.code_table` itself (``on_stored`` is not called)."""
        return np.asarray(self._stored(y0, y1), dtype=self.stored_dtype)

    def read(self, y0: int, y1: int) -> np.ndarray:
        """Decoded rows ``y0 .. y1 − 1`` (0 is the top row), (rows, columns, channels)."""
        return self.decode(self._stored(y0, y1), y0)

    def decode(self, data: np.ndarray, y0: int = 0) -> np.ndarray:
        """Rows as stored (:meth:`read_stored`; ``y0``: the first one's row, for messages) decoded as
        :meth:`read` decodes them. The result may share memory with ``data``: neither is changed after."""
        if self.on_stored is not None:
            self.on_stored(data)
        if self._read_type == "half":
            data = np.asarray(data, dtype=np.float16)
        elif self._read_type == "float":
            data = np.asarray(data, dtype=np.float32)
        px = decode_stored(data, self.info)
        self.nonfinite += apply_nan_policy(px, self.nan, self.info, self.path, y0,
                                            floats=self._read_type not in ("uint8", "uint16"))
        return px


    def keeps_stored(self, encoder: Encoder) -> bool:
        """Whether ``encoder`` stores every row this stream decodes as the values it was decoded from, bit for bit:
        then a file that holds the input unchanged (a MIP map's level 0) may be written from :meth:`read_stored`
        without decoding and encoding it again (:meth:`gives_back` of the encoder, where that proves it: never with
        alpha that is (un)premultiplied on the way, a colour conversion that may mix channels (OCIO), dithering
        (it depends on the pixel's place) or NaN replaced by zero)."""
        info, how = self.info, decoding(self.info)
        alpha = info.alpha_channel >= 0 and info.alpha_mode != "none"
        as_stored = how == "none" and info.alpha_mode != "straight" and not encoder.converts
        if (encoder.dither or alpha and not as_stored or "ocio" in (how, encoder.how)
                or self.nan == "zero" and self.stored_dtype == np.float16):
            return False
        return self.gives_back(encoder.values)

    def gives_back(self, encode: Callable[[np.ndarray], np.ndarray]) -> bool:
        """Whether ``encode`` (linear rows to stored values) gives back every value of this stream's stored type
        (8-bit, 16-bit or half, in every channel) from its decoding, in type, shape and every bit: tried once on
        all of them. That holds for every picture only where each value is decoded and encoded on its own: the
        callers check that (:meth:`keeps_stored`, :func:`pyramid_cli.run.tiles.stored_rows`)."""
        dtype = self.stored_dtype
        if dtype not in (np.uint8, np.uint16, np.float16):
            return False
        bits = np.arange(1 << (8 * dtype.itemsize), dtype=np.uint8 if dtype == np.uint8 else np.uint16)
        probe = np.repeat(bits.view(dtype).reshape(-1, 256, 1), self.shape[2], axis=2)
        back = np.asarray(encode(decode_stored(probe.copy(), self.info)))
        if back.ndim == 2:
            back = back[..., None]
        return back.dtype == dtype and back.shape == probe.shape and np.array_equal(back.view(bits.dtype),
                                                                                   probe.view(bits.dtype))


def chunk_pieces(y0: int, y1: int, chunk: int, height: int) -> list[tuple[int, int]]:
    """Rows ``y0 .. y1 − 1`` of a file stored in chunks of ``chunk`` rows (``height`` in all) as reads that each
    lie in one chunk or cover whole ones: the rest of the chunk a band begins in, the whole chunks after it, and
    the start of the chunk it ends in.

    OpenImageIO decodes every chunk a read touches: a read that covers part of a chunk and runs on into the next
    one decoded the part-read chunk a second time, where reads within one chunk did not. Measured on 3840-wide
    files, bands of 40 rows, CPU of OpenImageIO's reads alone: a DWAB file (chunks of 256 rows) 790 ms read as
    asked, 376 ms in these pieces; PIZ (32) 628 and 340; zip (16) 436 and 384; a deflate TIFF (strips of 32 rows)
    526 and 341. A band that begins and ends at chunk edges is one piece.
    """
    if chunk <= 1:
        return [(y0, y1)]
    pieces = []
    a = min(y1, -(-y0 // chunk) * chunk)  # the end of the chunk y0 is in (y0 itself at an edge)
    if a > y0:
        pieces.append((y0, a))
    b = max(a, y1 if y1 == height else y1 // chunk * chunk)
    if b > a:
        pieces.append((a, b))
    if y1 > b:
        pieces.append((b, y1))
    return pieces


def output_codec_memory(path: str | os.PathLike[str], info: ImageInfo, channels: int, size: tuple[int, int],
                        tile: int = 0, **options) -> CodecMemory:
    """What OpenEXR's codec holds for an output ``path`` of ``size`` (rows, columns) written from ``info`` as the
    write ``options`` ask, in scanlines or in square tiles of ``tile`` pixels (a MIP file); nothing for other
    formats (:func:`~pyramid_cli.imageio.codecs.exr_codec_memory`)."""
    enc = Encoder(path, info, channels, check_path=False, **options)
    spec = enc.spec(size[1], size[0])
    if tile:
        spec.tile_width = spec.tile_height = tile
    return exr_codec_memory(spec, enc.fmt)


def open_stream(path: str | os.PathLike[str], **options) -> ImageStream:
    """An :class:`ImageStream` of ``path`` (options as :func:`~pyramid_cli.imageio.read.read_image`: colorspace,
    alpha, nan, keep_half, colorconfig)."""
    return ImageStream(os.fspath(path), **options)


def streams_to(path: str | os.PathLike[str]) -> bool:
    """Can :func:`stream_writer` write ``path`` band by band? (Formats encoded in memory cannot.)"""
    fmt = format_from_path(os.fspath(path))
    return bool(fmt) and fmt not in ENCODE_IN_MEMORY


def band_quantum(tile_rows: int, dither: bool) -> int:
    """Rows a band is encoded in multiples of: whole rows of tiles, and of the 8-row dither pattern."""
    return tile_rows * 8 // math.gcd(tile_rows, 8) if dither else tile_rows


class BandWriter:
    """Rows written as they complete into the temporary of :func:`stream_writers` (see there)."""

    def __init__(self, path: str, tmp: str, fmt: str, info: ImageInfo, shape: tuple[int, int, int], options: dict):
        self.path, self.tmp, self.fmt, self.info, self.options = path, tmp, fmt, info, options
        self.height, self.width = shape[0], shape[1]
        self.next = 0      # rows handed over
        self.written = 0   # rows encoded and written
        self.spec: oiio.ImageSpec | None = None
        self._out: oiio.ImageOutput | None = None
        self._pending: list[np.ndarray] = []  # rows waiting for a whole row of tiles, or 8 rows of dither
        self._encoder: Encoder | None = None   # decided at the first rows

    def write(self, y0: int, pixels: np.ndarray) -> None:
        """Linear pixels of rows ``y0 ..`` (in order: ``y0`` is the first row not handed over yet), encoded as
        :func:`~pyramid_cli.imageio.write.write_image` encodes the whole picture (rows are grouped so that
        dithering and tiles line up)."""
        self._take(y0, pixels, stored=False)

    def write_stored(self, y0: int, values: np.ndarray) -> None:
        """Rows ``y0 ..`` as the file stores them, written as they are (in order, as :meth:`write`; never mixed
        with it): what :meth:`write` would store for pixels whose stored values are ``values`` already
        (:meth:`ImageStream.keeps_stored`)."""
        self._take(y0, values, stored=True)

    def _take(self, y0: int, rows: np.ndarray, stored: bool) -> None:
        if y0 != self.next:
            raise ValueError(f"rows are written in order: row {self.next} expected, not {y0}")
        if not len(rows):
            return
        self.next += len(rows)
        self._pending.append(rows)
        try:
            if self._out is None:
                self._encoder = Encoder(self.path, self.info, rows.shape[2] if rows.ndim == 3 else 1, **self.options)
                self._open(self._encoder.spec(rows.shape[1], 1))
            self._flush(final=self.next >= self.height, stored=stored)
        except WriteFailed as exc:
            raise self._failed(exc) from None

    def _failed(self, exc: WriteFailed) -> OutputError:
        """The one line a failed write says, naming the user's path (not the temporary's)."""
        return OutputError(f"cannot write {self.path}: {str(exc).replace(self.tmp, self.path)}{diagnosis(self.tmp)}")

    def _open(self, band_spec: oiio.ImageSpec) -> None:
        spec = band_spec
        spec.height = spec.full_height = self.height
        set_windows(spec, self.info, spec.width, self.height)
        self._header(spec)
        out = oiio.ImageOutput.create(self.tmp)
        if out is None:
            raise WriteFailed(one_line(oiio.geterror(), "no writer for this format"))
        self._out = out
        checked(out, out.open(self.tmp, spec, "Create"), "open")
        self.spec = spec

    def _header(self, spec: oiio.ImageSpec) -> None:
        """What a subclass adds to the file's header before it opens (nothing here)."""

    def _flush(self, final: bool, stored: bool = False) -> None:
        s, out = self.spec, self._out
        assert s is not None and out is not None, "the first rows opened the file"
        tiled = s.tile_width > 0 and s.tile_height > 0
        quantum = band_quantum(s.tile_height if tiled else 1, self.options.get("dither", False))
        rows = self.next - self.written
        whole = rows if final else rows // quantum * quantum
        if not whole:
            return
        pixels = np.concatenate(self._pending) if len(self._pending) > 1 else self._pending[0]
        self._pending = [pixels[whole:]] if whole < rows else []
        assert self._encoder is not None, "the first rows made the encoder"
        data = pixels[:whole] if stored else self._encoder.values(pixels[:whole])
        start = self.written
        if tiled:
            for a in range(0, whole, quantum):
                b = min(a + quantum, whole)
                ok = out.write_tiles(s.x, s.x + s.width, s.y + start + a, s.y + start + b, s.z, s.z + 1,
                                     np.ascontiguousarray(data[a:b]))
                checked(out, ok, "write")
        else:
            checked(out, out.write_scanlines(s.y + start, s.y + start + whole, s.z, data), "write")
        self.written += whole

    def finish(self) -> None:
        """Close the file and check it reads back (OutputError naming the user's path)."""
        if self.written != self.height:
            raise ValueError(f"{self.written} of {self.height} rows written")
        self._close_verified(1, "single")

    def _close_verified(self, subimages: int, kind: str) -> None:
        """Close the file and check it reads back with ``subimages`` of its spec (``kind`` as
        :func:`~pyramid_cli.imageio.write.verify` takes it)."""
        out, spec = self._out, self.spec
        assert out is not None and spec is not None, "every row written: the file is open and its spec known"
        try:
            self._out = None
            checked(out, out.close(), "close")
            # OpenImageIO's OpenEXR writer flushes the file's last bytes when it is destroyed, not at close: a
            # small MIP-mapped EXR read back empty here while it was still held
            del out
            verify(self.tmp, self.fmt, [(spec, None)] * subimages, kind)
        except WriteFailed as exc:
            raise self._failed(exc) from None

    def abort(self) -> None:
        if self._out is not None:
            with contextlib.suppress(Exception):
                self._out.close()
            self._out = None


@contextlib.contextmanager
def stream_writers(paths: Sequence[str | os.PathLike[str]], infos: list[ImageInfo], shapes: list[tuple[int, int, int]],
                   *, pixel_type: str | None = None, colorspace: str | None = None, alpha: str | None = None,
                   dither: bool = False, compression: str | None = None, force: bool = False,
                   inputs: Iterable[str | os.PathLike[str]] = ()):
    """Several images written band by band, all or nothing (:func:`~pyramid_cli.imageio.write.write_images`'
    guarantee): one :class:`BandWriter` per path on a hidden temporary beside it.

    Each file is encoded as :func:`~pyramid_cli.imageio.write.write_image` encodes it (same options, same
    pixels); they are renamed onto their paths only when every row of every file is written and each reads
    back; any failure or interruption removes the temporaries and leaves what was at the paths untouched
    (:func:`pyramid_cli.imageio.atomic.atomic_paths`).
    """
    out_paths = [os.fspath(p) for p in paths]
    opts = {"pixel_type": pixel_type, "colorspace": colorspace, "alpha": alpha, "dither": dither,
            "compression": compression, "force": force, "inputs": tuple(inputs)}
    fmts = [check_band_output(p, opts, info.colorconfig) for p, info in zip(out_paths, infos, strict=True)]
    with atomic_paths(out_paths) as tmps:
        writers = [BandWriter(p, tmp, fmt, info, shape, opts)
                   for p, tmp, fmt, info, shape in zip(out_paths, tmps, fmts, infos, shapes, strict=True)]
        try:
            yield writers
            for w in writers:
                w.finish()
        except BaseException:
            for w in writers:
                w.abort()
            raise


def check_band_output(path: str, opts: dict, colorconfig: str | None = None) -> str:
    """The format of ``path``, refused before any work as :func:`~pyramid_cli.imageio.write.write_image`
    refuses it, or when its format is encoded whole (it cannot be written band by band)."""
    fmt = check_output_path(path, opts["force"], opts["inputs"])
    check_write_options(path, opts["pixel_type"], opts["compression"], opts["colorspace"], colorconfig)
    if not streams_to(path):
        raise OutputError(f"cannot write {path} band by band: {format_title(fmt)} is encoded whole")
    return fmt


@contextlib.contextmanager
def stream_writer(path: str | os.PathLike[str], info: ImageInfo, shape: tuple[int, int, int], **options):
    """One image written band by band, atomically (:func:`stream_writers` of one path): yields its
    :class:`BandWriter`. Options as :func:`~pyramid_cli.imageio.write.write_image`."""
    with stream_writers([path], [info], [shape], **options) as (writer,):
        yield writer
