"""The encoding rules: what a write stores for an image (pixel type, colour encoding, alpha, metadata,
windows, compression) and the checks that refuse an output before any work.

:func:`encode` gives the spec and stored values; :mod:`pyramid_cli.imageio.write` writes them.
"""

from __future__ import annotations

import math
import os

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.imageio.colour import colour_mask, encode_integer, linear_to_srgb, premultiply, srgb8, unpremultiply
from pyramid_cli.imageio.formats import (
    ALPHA_MODES,
    ASSOCIATED_CAPABLE,
    COMPRESSION_LEVELS,
    COMPRESSIONS,
    FORMAT_TYPES,
    HALF_AS_FLOAT,
    NO_ALPHA_FORMATS,
    PIXEL_TYPES,
    PNG_FILTER_NAMES,
    PNG_FILTERS,
    TILED_FORMATS,
    check_choice,
    format_from_path,
    format_title,
    output_pixel_type,
    png_compression,
)
from pyramid_cli.imageio.image import Image, ImageInfo, default_channel_names
from pyramid_cli.imageio.ocio import (
    BUILTIN,
    convert,
    describe,
    equivalent,
    holds,
    is_linear,
    kind,
    known,
    label,
    output_space,
    short_name,
)

# Attributes that describe the file's layout rather than the image; they are
# recomputed by OpenImageIO for each file, so copying them could only conflict.
_DERIVED_ATTRIBUTES = frozenset({
    "tiff:Compression",
    "tiff:PhotometricInterpretation",
    "tiff:PlanarConfiguration",
    "tiff:RowsPerStrip",
    "openexr:chunkCount",
    "openexr:version",
})

_FORMAT_ONLY_ATTRIBUTES = frozenset({"compression", "planarconfig", "Compression"})

# Attributes that only make sense with the colour encoding they came with.
_COLOUR_PROFILE_ATTRIBUTES = frozenset({"ICCProfile", "oiio:Gamma", "png:gAMA", "CICP", "colorInteropID"})


def _ext(path: str) -> str:
    return os.path.splitext(path)[1].lower().lstrip(".")


def output_colorspace(path: str, info: ImageInfo, out_type: str, colorspace: str | None = None) -> str:
    """The space an output of ``info``'s image is stored in (short name, :func:`pyramid_cli.imageio.ocio.short_name`):
    ``colorspace`` when asked (refused, UsageError, when the format cannot say it holds it, or when it would turn
    data into colour or colour into data), else :func:`pyramid_cli.imageio.ocio.output_space`."""
    fmt, cfg = format_from_path(path), info.colorconfig
    if colorspace is None:
        return output_space(info.colorspace, info.linear_space, info.pixel_type in ("uint8", "uint16"), fmt,
                            _ext(path), out_type, cfg)
    want = short_name(colorspace, cfg)
    if (kind(want, cfg) == "data") != (kind(info.colorspace, cfg) == "data") and want != info.colorspace:
        what = "data" if kind(info.colorspace, cfg) == "data" else "colour"
        raise UsageError(f"{path}: --tocolorspace {colorspace}: the input ({info.colorspace}) is {what}; "
                         "data is never converted to or from colour")
    if not holds(fmt, _ext(path), out_type, want, cfg):
        raise UsageError(f"{path}: --tocolorspace {colorspace} cannot be stored in {format_title(fmt)} {out_type} "
                         "files (their colour space label cannot say it; OpenEXR can)")
    return want


def _output_alpha_mode(info: ImageInfo, fmt: str, out_type: str) -> str:
    if info.alpha_mode == "none":
        return "none"
    if fmt == "openexr":
        return "premultiplied"
    if fmt == "tiff":
        if info.format == "tiff":
            return info.alpha_mode
        return "straight" if out_type in ("uint8", "uint16") else "premultiplied"
    return "straight"


def _keep_attribute(name: str, same_format: bool, same_encoding: bool) -> bool:
    if name.startswith("oiio:") or name in _DERIVED_ATTRIBUTES:
        return False
    if name in _COLOUR_PROFILE_ATTRIBUTES and not same_encoding:
        return False
    if not same_format:
        if name in _FORMAT_ONLY_ATTRIBUTES:
            return False
        prefix = name.split(":", 1)[0].lower() if ":" in name else ""
        if prefix in _KNOWN_FORMAT_PREFIXES:
            return False
    return True


def _known_format_prefixes() -> frozenset[str]:
    names = {entry.partition(":")[0] for entry in
             oiio.get_string_attribute("extension_list").split(";") if entry}
    return frozenset(names | {"exr", "tif", "jpg", "heif", "raw", "ffmpeg", "openvdb"})


_KNOWN_FORMAT_PREFIXES = _known_format_prefixes()


def _is_same_file(a: str, b: str) -> bool:
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def check_output_path(out_path: str, force: bool, inputs) -> str:
    """The output's format, after refusing an unknown extension, a folder, or an input without ``force``."""
    fmt = format_from_path(out_path)
    if not fmt:
        raise OutputError(f"cannot write {out_path}: unknown image file extension")
    if os.path.isdir(out_path):
        raise OutputError(f"cannot write {out_path}: it is a directory")
    if os.path.lexists(out_path) and not os.path.isfile(out_path) and not os.path.islink(out_path):
        raise OutputError(f"cannot write {out_path}: it exists and is not a regular file")
    if not force:
        for inp in inputs:
            if _is_same_file(out_path, os.fspath(inp)):
                raise OutputError(f"refusing to overwrite input {out_path} (use --force)")
    return fmt


def pixels_in(image: Image, space: str) -> np.ndarray:
    """``image``'s pixels converted from the linear space they are in to ``space`` (float32, premultiplied by
    alpha as the image is: an encoded space is converted on straight colour); data is never converted."""
    info, px = image.spec, np.array(image.pixels, dtype=np.float32)
    target = short_name(space, info.colorconfig)
    how = _encoding(info, target)
    if how == "none":
        return px
    colour = colour_mask(px.shape[2], info.alpha_channel, info.channel_names)
    straight = image.premultiplied and not is_linear(target, info.colorconfig)
    if straight:
        unpremultiply(px, info.alpha_channel, colour)
    if how == "srgb":
        px[..., colour] = linear_to_srgb(px[..., colour])
    else:
        px[..., colour] = convert(px[..., colour], info.linear_space, target, info.colorconfig)
    if straight:
        premultiply(px, info.alpha_channel, colour)
    return px


def describe_output(path: str | os.PathLike[str], info: ImageInfo, *, pixel_type: str | None = None,
                    colorspace: str | None = None, **_ignored) -> str:
    """How ``-v`` says what an output of ``info``'s image stores: ``"output o.png: uint8, sRGB … (option)"``
    (options as :func:`~pyramid_cli.imageio.write.write_image`'s)."""
    out_path = os.fspath(path)
    out_type = stored_type(format_from_path(out_path), pixel_type, info)
    space = output_colorspace(out_path, info, out_type, colorspace)
    return f"output {out_path}: {out_type}, {describe(space, 'option' if colorspace else '', info.colorconfig)}"


def check_write_options(path: str | os.PathLike[str], pixel_type: str | None = None,
                        compression: str | None = None, colorspace: str | None = None,
                        colorconfig: str | None = None) -> None:
    """Refuse (UsageError, exit 2) a --type, --compression or --tocolorspace the output's format would not honour.

    Without this OpenImageIO stores the nearest type or its default compression without a word.
    ``None`` means "not asked": the input's type (as the format allows) and compression apply.
    Cheap: call it before any work.
    """
    out_path = os.fspath(path)
    fmt = format_from_path(out_path)
    if not fmt:
        return  # the write reports the unknown extension
    title = format_title(fmt)
    if pixel_type is not None:
        check_choice("pixel type", pixel_type, PIXEL_TYPES)
        allowed = FORMAT_TYPES.get(fmt)
        if allowed is not None and pixel_type not in allowed:
            raise UsageError(f"{out_path}: --type {pixel_type} cannot be stored in {title} files "
                             f"(they hold {' or '.join(allowed)})")
    if colorspace is not None:
        want = short_name(colorspace, colorconfig)
        types = [pixel_type] if pixel_type else list(FORMAT_TYPES.get(fmt, PIXEL_TYPES))
        if not any(holds(fmt, _ext(out_path), t, want, colorconfig) for t in types):
            raise UsageError(f"{out_path}: --tocolorspace {colorspace} cannot be stored in {title} files "
                             "(their colour space label cannot say it; OpenEXR can)")
    if compression is None:
        return
    c = str(compression).strip().lower()
    name, _, level = c.partition(":")
    if fmt == "png":
        try:
            png_compression(c)
        except ValueError:
            raise UsageError(f"{out_path}: unknown --compression {compression} (PNG takes a zlib level 0-9, and "
                             f"optionally :FILTERS, the row filters from {', '.join(PNG_FILTER_NAMES)} joined with "
                             "+, e.g. 6:none)") from None
    elif fmt == "jpeg":
        q = level if name == "jpeg" else c
        if not (q.isdigit() and 1 <= int(q) <= 100):
            raise UsageError(f"{out_path}: unknown --compression {compression} "
                             "(JPEG takes a quality 1-100, or jpeg:QUALITY)")
    elif fmt in COMPRESSIONS:
        ok = name in COMPRESSIONS[fmt] and (not level or (name in COMPRESSION_LEVELS and _is_number(level)))
        if not ok:
            levels = ", ".join(c for c in COMPRESSIONS[fmt] if c in COMPRESSION_LEVELS)
            raise UsageError(f"{out_path}: unknown --compression {compression} "
                             f"({title} takes {', '.join(COMPRESSIONS[fmt])}; {levels} take :LEVEL)")
    else:
        raise UsageError(f"{out_path}: --compression has no effect on {title} files")


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def encode(path, image: Image, *, pixel_type=None, colorspace=None, alpha=None, dither=False, compression=None,
            force=False, inputs=(), check_path: bool = True) -> tuple[oiio.ImageSpec, np.ndarray]:
    """The spec and encoded pixels :func:`~pyramid_cli.imageio.write.write_image` would write (checks included).

    ``check_path`` False: ``path`` only names the format (a tile set's tiles, a streamed texture's statistics):
    what is on disk there is not looked at. Rows written band by band decide once: :class:`Encoder`."""
    pixels = _as_rows(os.fspath(path), image.pixels)
    enc = Encoder(path, image.spec, pixels.shape[2], pixel_type=pixel_type, colorspace=colorspace, alpha=alpha,
                  dither=dither, compression=compression, force=force, inputs=inputs, check_path=check_path)
    return enc.spec(pixels.shape[1], pixels.shape[0]), enc.values(pixels)


def _as_rows(out_path: str, pixels) -> np.ndarray:
    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.ndim != 3 or 0 in pixels.shape:
        raise OutputError(f"cannot write {out_path}: bad pixel array shape {pixels.shape}")
    return pixels


class Encoder:
    """How :func:`encode` stores linear premultiplied pixels of ``channels`` channels described by ``info`` at
    ``path`` (the options as :func:`encode` takes them, checked here): decided once, then applied to any number
    of bands of rows (:meth:`values`) — the rules take longer to work out than a band of 8-bit rows takes to
    encode, and a streamed picture or a tile set encodes hundreds of bands."""

    def __init__(self, path, info: ImageInfo, channels: int, *, pixel_type=None, colorspace=None, alpha=None,
                 dither=False, compression=None, force=False, inputs=(), check_path: bool = True):
        out_path = os.fspath(path)
        if pixel_type is not None:
            check_choice("pixel type", pixel_type, PIXEL_TYPES)
        if alpha is not None:
            check_choice("alpha mode", alpha, ALPHA_MODES)
        fmt = check_output_path(out_path, force, inputs) if check_path else format_from_path(out_path)
        if not fmt:
            raise OutputError(f"cannot write {out_path}: unknown image file extension")
        check_write_options(out_path, pixel_type, compression, colorspace, info.colorconfig)
        names, alpha_channel = list(info.channel_names), info.alpha_channel
        if len(names) != channels:
            names = default_channel_names(channels)
            alpha_channel = names.index("A") if "A" in names else -1
        out_type, encoding, self.memory_premultiplied, mode = _write_rules(out_path, info, alpha_channel,
                                                                            pixel_type, colorspace, alpha)
        self.how = _encoding(info, encoding)
        # "ocio" into a linear space is a matrix: it commutes with premultiplication
        self.transfer = self.how == "srgb" or self.how == "ocio" and not is_linear(encoding, info.colorconfig)
        self.path, self.info, self.fmt, self.out_type, self.encoding = out_path, info, fmt, out_type, encoding
        self.pixel_type, self.compression, self.dither, self.channels = pixel_type, compression, dither, channels
        self.in_names, self.in_alpha = names, alpha_channel
        # The common 8-bit sRGB file without alpha: encoded by table, a channel at a time
        self.table = (out_type == "uint8" and self.how == "srgb" and mode == "none" and not dither
                      and not (fmt in NO_ALPHA_FORMATS and alpha_channel >= 0))
        self.drops_alpha = not self.table and fmt in NO_ALPHA_FORMATS and alpha_channel >= 0
        if self.drops_alpha:  # no alpha in the file: premultiplied linear colour alone is the image, over black
            self.names = [n for i, n in enumerate(names) if i != alpha_channel]
            self.alpha_channel, self.mode, self.nch = -1, "none", channels - 1
        else:
            self.names, self.alpha_channel, self.mode, self.nch = names, alpha_channel, mode, channels
        self.colour = colour_mask(self.nch, self.alpha_channel, self.names)
        self.converts = _converts(fmt, alpha_channel, self.memory_premultiplied, self.how, mode)

    def spec(self, width: int, height: int) -> oiio.ImageSpec:
        """The file's spec for ``width`` × ``height`` pixels (:func:`_output_spec`)."""
        return _output_spec(self.info, self.fmt, self.out_type, self.names, self.alpha_channel, self.nch, width,
                            height, self.encoding, self.mode, self.pixel_type, self.compression)

    def values(self, pixels: np.ndarray) -> np.ndarray:
        """The stored values of ``pixels`` (H×W×C or H×W; a band of rows decodes as the whole picture does, the
        dither pattern starting at its first row)."""
        pixels = _as_rows(self.path, pixels)
        if pixels.shape[2] != self.channels:
            raise ValueError(f"{pixels.shape[2]} channels given to an encoder of {self.channels}")
        out_type, how, colour = self.out_type, self.how, self.colour
        if self.table:
            if all(colour):  # one pass over the whole array: no strided per-channel copies (1.6× faster at 4K)
                return srgb8(pixels)
            data: np.ndarray = np.empty(pixels.shape, dtype=np.uint8)
            for c in range(self.nch):
                data[..., c] = srgb8(pixels[..., c]) if colour[c] else \
                    encode_integer(pixels[..., c:c + 1].astype(np.float64), out_type, False, colour[c:c + 1])[..., 0]
            return data
        out_int = out_type in ("uint8", "uint16")
        if not out_int and not self.converts:
            # Stored as they are: no copy (float16 stays float16 for a half file; OIIO converts float32).
            px = pixels if pixels.dtype in (np.float16, np.float32) else pixels.astype(np.float32)
        else:
            px = pixels.astype(np.float64 if out_int else np.float32)  # a copy: encoded in place below
        if self.drops_alpha:
            if not self.memory_premultiplied:
                premultiply(px, self.in_alpha, colour_mask(self.channels, self.in_alpha, self.in_names))
            px = px[..., [i for i in range(self.channels) if i != self.in_alpha]]
        info, mode, alpha_channel = self.info, self.mode, self.alpha_channel

        def to_output(values: np.ndarray) -> np.ndarray:
            if how == "srgb":
                return linear_to_srgb(values)
            return convert(values, info.linear_space, self.encoding, info.colorconfig).astype(values.dtype)

        if mode != "none":
            if self.memory_premultiplied and (mode == "straight" or self.transfer):
                unpremultiply(px, alpha_channel, colour)
            if how != "none":
                px[..., colour] = to_output(px[..., colour])
            if mode == "premultiplied" and (self.transfer or not self.memory_premultiplied):
                premultiply(px, alpha_channel, colour)
        elif how != "none":
            px[..., colour] = to_output(px[..., colour])
        if out_int:
            data = encode_integer(px, out_type, self.dither, colour)
        else:
            data = px if px.dtype == np.float16 and out_type == "half" else px.astype(np.float32, copy=False)
        return np.ascontiguousarray(data)


def _output_spec(info: ImageInfo, fmt: str, out_type: str, names: list[str], alpha_channel: int, nch: int,
                 width: int, height: int, encoding: str, mode: str, pixel_type: str | None,
                 compression: str | None) -> oiio.ImageSpec:
    """The file's spec: type, channels, windows, carried metadata, colour space, alpha and compression."""
    spec = oiio.ImageSpec(width, height, nch, out_type)
    spec.channelnames = tuple(names)
    spec.alpha_channel = alpha_channel
    same_format = fmt == info.format
    if (same_format and pixel_type is None and info.channel_pixel_types
            and len(info.channel_pixel_types) == nch):
        spec.channelformats = tuple(oiio.TypeDesc(t) for t in info.channel_pixel_types)
    set_windows(spec, info, width, height)

    cfg = info.colorconfig
    same_encoding = encoding == info.colorspace
    for name, value in info.attributes.items():
        if not _keep_attribute(name, same_format, same_encoding):
            continue
        type_name = info.attribute_types.get(name)
        try:
            if type_name:
                spec.attribute(name, oiio.TypeDesc(type_name), value)
            else:
                spec.attribute(name, value)
        except (TypeError, ValueError, RuntimeError):
            continue  # metadata OpenImageIO cannot express for this file: drop it
    old_cs = info.attributes.get("oiio:ColorSpace")
    if isinstance(old_cs, str) and equivalent(old_cs, encoding, cfg):
        spec.attribute("oiio:ColorSpace", old_cs)
    else:  # every output names the space its pixels are in, unlabelled inputs' too
        spec.attribute("oiio:ColorSpace", label(encoding, cfg))
    name = spec.get_string_attribute("oiio:ColorSpace")
    if fmt == "openexr" and name and not known(name, BUILTIN):
        # OpenImageIO's EXR writer keeps only the names its built-in config knows, as colorInteropID: a
        # studio config's name is written there itself (the reader takes oiio:ColorSpace from it)
        spec.attribute("colorInteropID", name)
    if mode == "straight" or (mode == "none" and alpha_channel >= 0) or (
            alpha_channel >= 0 and fmt not in ASSOCIATED_CAPABLE):
        # The values handed over are exactly what is to be stored: stop
        # OpenImageIO from unpremultiplying them again.
        spec.attribute("oiio:UnassociatedAlpha", 1)
    if fmt in HALF_AS_FLOAT and out_type == "half":  # asked for (stored_type): OpenImageIO writes float otherwise
        spec.attribute("tiff:half", 1)
    if fmt == "png":
        level, filters = png_compression(compression) if compression is not None else (None, PNG_FILTERS)
        spec.attribute("png:filter", filters)
        if level is not None:
            spec.attribute("png:compressionLevel", level)  # zlib level 0-9
    elif compression is not None:
        if fmt == "jpeg" and compression.strip().isdigit():
            spec.attribute("compression", f"jpeg:{int(compression)}")  # quality 1-100
        else:
            spec.attribute("compression", compression)
    if same_format and info.tile is not None and fmt in TILED_FORMATS:
        # A tiled input is written back tiled, with its tile size.
        spec.tile_width, spec.tile_height = info.tile
    return spec


def set_windows(spec: oiio.ImageSpec, info: ImageInfo, width: int, height: int) -> None:
    """The data and display windows of the input, which only still apply at the input's size."""
    same_size = (width, height) == (info.width, info.height)
    if same_size and (info.origin != (0, 0) or info.display_window is not None):
        spec.x, spec.y = info.origin
        if info.display_window is not None:
            spec.full_x, spec.full_y, spec.full_width, spec.full_height = info.display_window
        else:
            spec.full_x, spec.full_y = info.origin
            spec.full_width, spec.full_height = width, height


def _write_rules(path: str, info: ImageInfo, alpha_channel: int, pixel_type: str | None, colorspace: str | None,
                 alpha: str | None) -> tuple[str, str, bool, str]:
    """How a write stores the image: (pixel type, colour space, whether memory is premultiplied, alpha mode)."""
    fmt = format_from_path(path)
    out_type = stored_type(fmt, pixel_type, info)
    encoding = output_colorspace(path, info, out_type, colorspace)
    memory_premultiplied = alpha_channel >= 0 and info.alpha_mode != "none"
    mode = "none" if alpha_channel < 0 else (alpha or _output_alpha_mode(info, fmt, out_type))
    return out_type, encoding, memory_premultiplied, mode


def stored_type(fmt: str, pixel_type: str | None, info: ImageInfo) -> str:
    """The pixel type an output of ``info``'s image stores: ``pixel_type`` (``--type``) as the format ``fmt`` holds
    it, else the input's; a half input is stored as float where the format takes half only when asked
    (:data:`~pyramid_cli.imageio.formats.HALF_AS_FLOAT`: TIFF)."""
    if pixel_type is None and fmt in HALF_AS_FLOAT and info.pixel_type == "half":
        return "float"
    return output_pixel_type(fmt, pixel_type or info.pixel_type)


def _encoding(info: ImageInfo, space: str) -> str:
    """How linear pixels become ``space``: ``"none"``, ``"srgb"`` (the exact sRGB curve) or ``"ocio"``."""
    if space == info.linear_space or kind(info.linear_space, info.colorconfig) == "data":
        return "none"
    return "srgb" if info.linear_space == "linear" and space == "srgb" else "ocio"


def _converts(fmt: str, alpha_channel: int, memory_premultiplied: bool, how: str, mode: str) -> bool:
    """Does writing change the values (alpha dropped or re-associated, a colour conversion)?"""
    if fmt in NO_ALPHA_FORMATS and alpha_channel >= 0 or how != "none":
        return True
    return mode != "none" and (mode == "straight" and memory_premultiplied
                               or mode == "premultiplied" and not memory_premultiplied)


def stores_half_unchanged(path: str | os.PathLike[str], info: ImageInfo, *, pixel_type: str | None = None,
                          colorspace: str | None = None, alpha: str | None = None) -> bool:
    """Will :func:`~pyramid_cli.imageio.write.write_image` store linear values as half without converting them?

    Then a float result may be rounded to half (nearest even) before writing, with the
    same file as a result: the GL read-back does that and moves half the bytes.
    """
    fmt = format_from_path(os.fspath(path))
    if not fmt or fmt in HALF_AS_FLOAT and pixel_type != "half":  # a TIFF of a half input holds float32
        return False
    out_type, encoding, memory_premultiplied, mode = _write_rules(os.fspath(path), info, info.alpha_channel,
                                                                  pixel_type, colorspace, alpha)
    return out_type == "half" and not _converts(fmt, info.alpha_channel, memory_premultiplied,
                                                _encoding(info, encoding), mode)


def encoded_rows(path: str | os.PathLike[str], image: Image, **options) -> np.ndarray:
    """The values :func:`~pyramid_cli.imageio.write.write_image` would store for ``image`` at ``path`` (a band
    of rows: dithering lines up when the band starts at a multiple of 8 rows), e.g. for a streamed texture's
    ``oiio:AverageColor``. ``path`` only names the format: nothing on disk there is looked at."""
    pixels = _as_rows(os.fspath(path), image.pixels)
    return Encoder(path, image.spec, pixels.shape[2], check_path=False, **options).values(pixels)
