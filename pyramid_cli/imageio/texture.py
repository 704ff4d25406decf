"""Texture files as maketx writes them: MIP-mapped (OpenEXR levels, TIFF ``.tx`` subimages) with maketx's
metadata (average and constant colour, SHA-1), whole (:func:`write_levels`) or level 0 band by band
(:func:`mip_stream_writer`); multi-part OpenEXR files of pyramid levels."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core.errors import InputError, OutputError, UsageError
from pyramid_cli.core.geometry import halved
from pyramid_cli.imageio.atomic import atomic_path
from pyramid_cli.imageio.bands import BandWriter, band_quantum, check_band_output
from pyramid_cli.imageio.encode import Encoder, encode, set_windows
from pyramid_cli.imageio.formats import format_from_path, format_title, one_line
from pyramid_cli.imageio.image import Image, ImageInfo
from pyramid_cli.imageio.write import WriteFailed, checked, write_file

#: File name endings of TIFF textures, whose tiles must be a multiple of :data:`TIFF_TILE` pixels.
TIFF_ENDINGS = (".tx", ".tif", ".tiff")
TIFF_TILE = 16


def check_texture_tile(tile: int, output: str) -> None:
    """Refuse (exit 2) a MIP-mapped texture's ``tile`` that a TIFF ``output`` (.tx, .tif, .tiff: a path or an
    output template) cannot hold: TIFF tiles are multiples of 16 pixels."""
    if tile % TIFF_TILE and output.lower().endswith(TIFF_ENDINGS):
        raise UsageError(f"--tile {tile}: TIFF tiles must be a multiple of {TIFF_TILE} ({output})")


def source_sha1(path: str | os.PathLike[str], extra: str = "") -> str:
    """maketx's ``oiio:SHA-1`` of a source file: its stored values as float32, hashed in 256-row blocks.

    See :func:`pyramid_cli.workflows.mip.pixel_sha1`; ``extra`` is what maketx appends (its filter name and a space).
    """
    from pyramid_cli.workflows.mip import pixel_sha1

    p = os.fspath(path)
    inp = oiio.ImageInput.open(p)
    if inp is None:
        raise InputError(f"cannot read {p}: {one_line(oiio.geterror(), 'unreadable')}")
    try:
        spec = inp.spec()
        data = inp.read_image("float")
    finally:
        inp.close()
    if data is None:
        raise InputError(f"cannot read {p}: {one_line(oiio.geterror(), 'read failed')}")
    return pixel_sha1(np.asarray(data, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels), extra)


def _mip_metadata(spec: oiio.ImageSpec, data: np.ndarray | None, meta: dict[str, str], arbitrary: bool,
                  colors: tuple[list[float], list[float] | None] | None = None) -> None:
    """maketx's metadata on level 0: average (and constant) colour of the stored values, plus ``meta``.

    ``colors``: (average, constant or None) when already known (a streamed level 0, :class:`MipBandWriter`),
    instead of computing them from ``data``.
    A format without arbitrary metadata (TIFF) gets the ``oiio:`` values in its ImageDescription as
    ``oiio:SHA-1=… oiio:AverageColor=…``, which is where maketx puts them and OpenImageIO's reader finds them.
    """
    from pyramid_cli.workflows.mip import average_color, constant_color, format_floats

    spec.attribute("fovcot", float(spec.full_width) / float(spec.full_height))  # maketx's: the aspect ratio
    values = dict(meta)
    if colors is None:
        if data is None:
            raise ValueError("the MIP metadata needs level 0's pixels or their colours")
        colors = (average_color(data), constant_color(data))
    average, constant = colors
    values["oiio:AverageColor"] = format_floats(average)
    if constant is not None:
        values["oiio:ConstantColor"] = format_floats(constant)
    history = spec.get_string_attribute("Exif:ImageHistory")
    desc = spec.get_string_attribute("ImageDescription")
    for key in ("oiio:ConstantColor", "oiio:AverageColor", "oiio:SHA-1"):  # never the input's stale values
        spec.erase_attribute(key)
        desc = " ".join(word for word in desc.split(" ") if not word.startswith(key + "="))
    for name, value in values.items():
        if name == "Exif:ImageHistory" and history:
            value = history.rstrip("\n") + "\n" + value
        if name.startswith("oiio:") and not arbitrary:
            desc = f"{desc} {name}={value}" if desc else f"{name}={value}"
        else:
            spec.attribute(name, value)
    if desc:
        spec.attribute("ImageDescription", desc)


def _mark_mip_level(spec: oiio.ImageSpec, fmt: str, tile: int, round_up: bool, compression: str | None) -> None:
    """A MIP level's spec as maketx writes it: tiled, "Plain Texture", OpenEXR's level and rounding modes."""
    spec.tile_width = spec.tile_height = tile
    spec.attribute("textureformat", "Plain Texture")
    if fmt == "openexr":
        spec.attribute("openexr:levelmode", 1)  # MIPMAP_LEVELS
        # ROUND_UP: sizes ⌈n/2⌉, as ⊗↓ gives; ROUND_DOWN: ⌊n/2⌋ (--round down, maketx's)
        spec.attribute("openexr:roundingmode", int(round_up))
    if fmt == "tiff":
        spec.attribute("planarconfig", "contig")
        if compression is None:
            spec.attribute("compression", "zip")  # maketx's default


def _mip_rounding(out_path: str, fmt: str, sizes: list[tuple[int, int]]) -> bool:
    """Whether MIP level sizes (width, height) round up; OutputError when OpenEXR cannot hold them."""
    pairs = list(zip(sizes[:-1], sizes[1:], strict=True))
    round_up = all(tuple(b) == halved(a) for a, b in pairs)
    round_down = all(b == (max(1, a[0] // 2), max(1, a[1] // 2)) for a, b in pairs)
    if fmt == "openexr" and not (round_up or round_down):
        raise OutputError(f"cannot write {out_path}: OpenEXR MIP levels halve each size rounding up or down; "
                          f"these are {' '.join(f'{w}x{h}' for w, h in sizes)}")
    return round_up


def _check_mip_capable(out_path: str, fmt: str) -> bool:
    """Whether the format has arbitrary metadata; OutputError when it cannot hold MIP levels."""
    probe = oiio.ImageOutput.create(fmt) if fmt else None
    if probe is None or not (probe.supports("mipmap") or (probe.supports("multiimage") and probe.supports("tiles"))):
        oiio.geterror()
        raise OutputError(f"cannot write {out_path}: the {format_title(fmt)} format cannot hold MIP levels")
    return bool(probe.supports("arbitrary_metadata"))


def write_levels(path: str | os.PathLike[str], images: list[Image], *, mode: str = "mipmap",
                 tile: int = 64, meta: dict[str, str] | None = None, **options) -> None:
    """Write several images into one file atomically: MIP levels (tiled) or EXR parts.

    Parameters
    ----------
    mode : {"mipmap", "multipart"}
        ``mipmap``: level 0 first, each a MIP level of a tiled file that
        OpenImageIO's ImageInput and TextureSystem read as MIP-mapped: OpenEXR's
        own MIP levels, or TIFF (``.tx``, ``.tif``) subimages marked as a texture
        the way maketx writes them. Level 0 gets maketx's ``oiio:AverageColor``
        (and ``oiio:ConstantColor`` when every pixel is the same) of the stored values.
        ``multipart``: one subimage per image (multi-part OpenEXR), named ``level{k}``.
    meta : dict, optional
        More attributes for level 0 (``mipmap``): ``wrapmodes``, ``oiio:SHA-1``,
        ``Software``; ``Exif:ImageHistory`` is appended to the input's history.
    options
        As for :func:`~pyramid_cli.imageio.write.write_image` (pixel_type, colorspace, alpha, dither,
        compression, force, inputs).
    """
    out_path = os.fspath(path)
    encoded = [encode(out_path, im, **options) for im in images]
    fmt = format_from_path(out_path)
    full = encoded[0][0]
    if mode == "mipmap":
        round_up = _mip_rounding(out_path, fmt, [(spec.width, spec.height) for spec, _ in encoded])
        for spec, _ in encoded:
            _mark_mip_level(spec, fmt, tile, round_up, options.get("compression"))
    else:
        for k, (spec, _) in enumerate(encoded):
            spec.attribute("name", f"level{k}")
            # OpenEXR parts share one display window: level 0's
            spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, full.width, full.height
    probe = oiio.ImageOutput.create(fmt) if fmt else None
    if mode == "mipmap":  # MIP levels of its own, or tiled subimages (TIFF: maketx's .tx)
        able = probe is not None and (probe.supports("mipmap")
                                      or (probe.supports("multiimage") and probe.supports("tiles")))
    else:
        able = probe is not None and probe.supports("multiimage")
    if probe is None or not able:
        oiio.geterror()
        raise OutputError(f"cannot write {out_path}: the {format_title(fmt)} format cannot hold "
                          f"{'MIP levels' if mode == 'mipmap' else 'several images'}")
    if mode == "mipmap":
        _mip_metadata(encoded[0][0], encoded[0][1], meta or {}, bool(probe.supports("arbitrary_metadata")))
    with atomic_path(out_path) as tmp:
        write_file(tmp, out_path, fmt, encoded, mode)


class MipBandWriter(BandWriter):
    """A MIP-mapped texture written as :func:`write_levels` writes it, level 0 band by band (:meth:`write`),
    then each coarser level from a callable giving its rows (:meth:`append_level`): use :func:`mip_stream_writer`.

    Level 0's header carries maketx's metadata, so its average and constant colour (``colors``) and SHA-1
    (in ``meta``) are known before the first row is written (:class:`pyramid_cli.workflows.mip.PixelStats`).
    """

    def __init__(self, path: str, tmp: str, fmt: str, info: ImageInfo, shapes: list[tuple[int, int, int]],
                 options: dict, *, tile: int, meta: dict[str, str], colors, arbitrary: bool):
        super().__init__(path, tmp, fmt, info, shapes[0], options)
        self.shapes, self.tile, self.meta, self.colors, self.arbitrary = shapes, tile, meta, colors, arbitrary
        self.round_up = _mip_rounding(path, fmt, [(w, h) for h, w, _ in shapes])
        self.levels = 0  # levels complete

    def _header(self, spec: oiio.ImageSpec) -> None:
        _mark_mip_level(spec, self.fmt, self.tile, self.round_up, self.options.get("compression"))
        _mip_metadata(spec, None, self.meta, self.arbitrary, self.colors)

    def append_level(self, rows, stored: bool = False) -> None:
        """The next level (1, 2, …): ``rows(r0, r1)`` gives its linear pixels, a row of tiles at a time (``stored``:
        the values the file stores, as :meth:`encoder` gives them)."""
        if self.written != self.height:
            raise ValueError(f"level 0: {self.written} of {self.height} rows written")
        self.levels = max(self.levels, 1) + 1
        h, w, _ = self.shapes[self.levels - 1]
        out = self._out
        assert out is not None, "level 0 opens the file, and it stays open until finish"
        step = band_quantum(self.tile, self.options.get("dither", False))
        try:
            spec, enc = None, None
            for r0 in range(0, h, step):
                r1 = min(h, r0 + step)
                px = rows(r0, r1)
                if enc is None:
                    enc = self.encoder(px.shape[2] if px.ndim == 3 else 1)
                data = px if stored else enc.values(px)
                if spec is None:
                    spec = enc.spec(px.shape[1], r1 - r0)
                    spec.height = spec.full_height = h
                    set_windows(spec, self.info, w, h)
                    _mark_mip_level(spec, self.fmt, self.tile, self.round_up, self.options.get("compression"))
                    append = "AppendMIPLevel" if out.supports("mipmap") else "AppendSubimage"
                    checked(out, out.open(self.tmp, spec, append), "open")
                for a in range(0, r1 - r0, self.tile):
                    b = min(a + self.tile, r1 - r0)
                    ok = out.write_tiles(spec.x, spec.x + w, spec.y + r0 + a, spec.y + r0 + b, spec.z,
                                               spec.z + 1, np.ascontiguousarray(data[a:b]))
                    checked(out, ok, "write")
        except WriteFailed as exc:
            raise self._failed(exc) from None

    def encoder(self, channels: int) -> Encoder:
        """How the levels of ``channels`` channels are stored (:meth:`append_level` with ``stored``)."""
        return Encoder(self.path, self.info, channels, **self.options)

    def finish(self) -> None:
        """Close the file and check it reads back with every level (OutputError naming the user's path)."""
        if self.written != self.height or max(self.levels, 1) != len(self.shapes):
            raise ValueError(f"{max(self.levels, 1) if self.written == self.height else 0} of {len(self.shapes)} "
                             "MIP levels written")
        self._close_verified(len(self.shapes), "mipmap")


@contextlib.contextmanager
def mip_stream_writer(path: str | os.PathLike[str], info: ImageInfo, shapes: list[tuple[int, int, int]], *,
                      tile: int = 64, meta: dict[str, str] | None = None,
                      colors: tuple[list[float], list[float] | None], pixel_type: str | None = None,
                      colorspace: str | None = None, alpha: str | None = None, dither: bool = False,
                      compression: str | None = None, force: bool = False,
                      inputs: Iterable[str | os.PathLike[str]] = ()):
    """A MIP-mapped texture of levels ``shapes`` (rows, columns, channels) written level 0 first, band by
    band, atomically: yields its :class:`MipBandWriter`. The file is the one :func:`write_levels` writes
    (``mode="mipmap"``) from the same pixels, given level 0's ``colors`` (average, constant or None)."""
    out_path = os.fspath(path)
    opts = {"pixel_type": pixel_type, "colorspace": colorspace, "alpha": alpha, "dither": dither,
            "compression": compression, "force": force, "inputs": tuple(inputs)}
    fmt = check_band_output(out_path, opts, info.colorconfig)
    arbitrary = _check_mip_capable(out_path, fmt)
    with atomic_path(out_path) as tmp:
        writer = MipBandWriter(out_path, tmp, fmt, info, shapes, opts, tile=tile, meta=meta or {}, colors=colors,
                               arbitrary=arbitrary)
        try:
            yield writer
            writer.finish()
        except BaseException:
            writer.abort()
            raise
