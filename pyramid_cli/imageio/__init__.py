"""Reading and writing images with OpenImageIO, in linear premultiplied light.

Everything the rest of the tool filters is an :class:`Image`: float32 pixels (or,
when asked, a half file's own float16 values) of shape ``(H, W, C)`` (row 0 is
the top row of the file, nothing is ever flipped) in linear light, with colour
premultiplied by alpha when the image has an alpha channel, plus an
:class:`ImageInfo` that remembers how the file stored them so that
:func:`write_image` can store the result the same way.

Rules
-----
Colour encoding
    8/16-bit integer files are sRGB-encoded unless their ``oiio:ColorSpace``
    metadata names a linear space; half/float files are linear unless their
    metadata names an sRGB-like space. Decoding uses the exact piecewise sRGB
    EOTF (not a 2.2 power) on colour channels only, never on alpha.
Alpha
    Files are opened with the ``oiio:UnassociatedAlpha`` hint so that
    OpenImageIO hands over the stored values untouched. A file whose spec then
    reports ``oiio:UnassociatedAlpha`` (PNG, unassociated TIFF, ...) stores
    straight alpha and is premultiplied after linearising; anything else (EXR,
    associated TIFF) is already premultiplied. Where alpha is 0 a straight
    colour is written as 0: premultiplied data holds no colour there, so an
    integer RGBA file round-trips bit-exactly except for the colour under
    alpha 0.
Pixel types
    The output keeps the input's type unless ``pixel_type`` is given. When the
    output format cannot hold the input's type it gets the nearest one it can:
    PNG and other 8/16-bit formats take ``uint16`` for half/float, 8-bit-only
    formats (JPEG, GIF, BMP, TGA, WebP, ICO) take ``uint8``, and float-only
    formats (EXR, HDR) take ``half`` for integers (``float`` for HDR). A
    ``pixel_type`` asked for that the format cannot hold is refused
    (:func:`check_write_options`), as is a ``compression`` it would ignore.
Tiles
    A tiled input (EXR, TIFF) is written back tiled with its tile size when
    the output has the same format; anything else is written as scanlines.
Writing
    Every write goes to a hidden temporary beside the output (its folder is
    created if missing) and is checked before the rename: every OpenImageIO
    call's result and error state, a non-empty file, PNG's and JPEG's end
    markers and a header that reads back. A full disk, a quota, a file size
    limit, a read-only or vanished folder end as :class:`OutputError` naming
    the output; the previous file is untouched and no temporary is left.
Metadata
    Attributes are carried to the output when they still apply: attributes
    specific to a file format (``openexr:*``, ``tiff:*``, ``png:*``, ...,
    ``compression``) only when the output has the same format, colour profile
    data only when the encoding is unchanged, and bookkeeping attributes that
    OpenImageIO derives from the data (``oiio:*``) never.
"""

from __future__ import annotations

import contextlib
import math
import os
import stat
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import OpenImageIO as oiio

try:
    import resource
except ImportError:  # not on Windows: no file size limit to respect
    resource = None

from pyramid_cli.core import options
from pyramid_cli.core.errors import DataError, InputError, OutputError, UsageError
from pyramid_cli.core.geometry import check_size  # noqa: F401  (part of io's API: image size limits)
from pyramid_cli.imageio.atomic import atomic_path, atomic_paths, ensure_output_dir, is_utf8
from pyramid_cli.imageio.colour import (  # noqa: F401  (_srgb8_tables, _integer_levels: io's tested internals)
    _colour_mask,
    _decode_integer,
    _encode_integer,
    _integer_levels,
    _premultiply,
    _srgb8,
    _srgb8_tables,
    _unpremultiply,
    count_nonfinite,
    linear_to_srgb,
    srgb_to_linear,
)

__all__ = [
    "Image",
    "ImageInfo",
    "check_pyramid",
    "check_same_channels",
    "check_size",
    "check_write_options",
    "ensure_output_dir",
    "count_nonfinite",
    "describe_rules",
    "linear_to_srgb",
    "output_pixel_type",
    "read_image",
    "srgb_to_linear",
    "write_image",
    "write_images",
    "write_levels",
    "ImageStream",
    "open_stream",
    "stream_writer",
    "stream_writers",
    "streams_to",
]

PIXEL_TYPES = options.PIXEL_TYPES
COLORSPACES = options.ENCODINGS
ALPHA_MODES = options.STORED_ALPHA

# The colour space names written into ``oiio:ColorSpace`` (OpenImageIO 3
# built-in names, understood by older versions as well).
_OIIO_COLORSPACE = {"linear": "lin_rec709_scene", "srgb": "srgb_rec709_scene"}

# Pixel types each format can store, for the formats that cannot store all
# four. Formats not listed are assumed to store any of them.
_FORMAT_TYPES: dict[str, tuple[str, ...]] = {
    "openexr": ("half", "float"),
    "png": ("uint8", "uint16"),
    "jpeg": ("uint8",),
    "gif": ("uint8",),
    "bmp": ("uint8",),
    "targa": ("uint8",),
    "webp": ("uint8",),
    "ico": ("uint8",),
    "sgi": ("uint8", "uint16"),
    "dpx": ("uint8", "uint16"),
    "jpeg2000": ("uint8", "uint16"),
    "hdr": ("float",),
    "pnm": ("uint8", "uint16", "float"),
}

# Formats that can store premultiplied (associated) alpha; all others store
# straight alpha only.
_ASSOCIATED_CAPABLE = ("openexr", "tiff")

# Formats that hold no alpha channel at all: alpha is dropped on write, which
# leaves the premultiplied colour, i.e. the image composited over black.
_NO_ALPHA_FORMATS = ("jpeg", "hdr")

# --compression values each format honours (OpenImageIO writes anything else as its default
# without a word, so anything else is refused). ``name:N`` sets a level or quality.
_COMPRESSIONS: dict[str, tuple[str, ...]] = {
    "openexr": ("none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"),
    "tiff": ("none", "lzw", "zip", "packbits", "ccittrle"),
}
_COMPRESSION_LEVELS = frozenset({"zip", "zips", "dwaa", "dwab", "lzw"})

# Formats whose OpenImageIO writer ends the whole process on a write error (libjpeg's default
# error handler calls exit()): they are encoded into memory first and copied to the file with
# os.write, which reports a full disk as an error.
_ENCODE_IN_MEMORY = frozenset({"jpeg"})

# Formats that can be tiled: a tiled input is written back tiled.
_TILED_FORMATS = ("openexr", "tiff")

_FORMAT_TITLES = {"openexr": "OpenEXR", "png": "PNG", "jpeg": "JPEG", "tiff": "TIFF", "hdr": "HDR"}

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
_COLOUR_PROFILE_ATTRIBUTES = frozenset({"ICCProfile", "oiio:Gamma", "png:gAMA", "CICP"})

_NON_LINEAR_KEYWORDS = ("srgb", "rec709", "g22", "g18", "gamma", "sycc")
_LINEAR_NAMES = frozenset({"linear", "scene_linear", "acescg", "aces", "aces2065-1",
                           "raw", "data", "role_scene_linear"})


@dataclass
class ImageInfo:
    """How an image was stored, so that it can be written back the same way.

    Attributes
    ----------
    path : str
        The file it was read from.
    format : str
        OpenImageIO format name, e.g. ``"openexr"``, ``"png"``, ``"tiff"``.
    pixel_type : str
        ``"uint8"``, ``"uint16"``, ``"half"`` or ``"float"`` (other stored
        types are reported as ``"float"``).
    channel_names : list of str
        One name per channel, in file order.
    alpha_channel : int
        Index of the alpha channel, -1 if none.
    colorspace : str
        Encoding of the stored values: ``"linear"`` or ``"srgb"``.
    alpha_mode : str
        How the file stores alpha: ``"straight"``, ``"premultiplied"``, or
        ``"none"`` (no alpha, or alpha treated as an ordinary channel).
    attributes : dict
        Metadata to carry through, name to value.
    attribute_types : dict
        OpenImageIO type name of each attribute (e.g. ``"float2"``) so that it
        is written back with the same type.
    channel_pixel_types : list of str
        Per-channel stored types when they differ (EXR), else empty.
    width, height : int
        Size of the stored data window (0 if unknown).
    origin : tuple of int
        ``(x, y)`` of the data window's top-left pixel.
    display_window : tuple of int or None
        ``(x, y, width, height)`` of the display window when it differs from
        the data window.
    tile : tuple of int or None
        ``(tile width, tile height)`` of a tiled file, None for scanlines; a
        tiled input is written back tiled (EXR, TIFF).
    pixel_hash : hashlib object or None
        Under ``read_image(hash_source=True)``: the unfinished SHA-1 of the stored
        pixels as maketx's ``computePixelHashSHA1`` hashes them
        (:func:`pyramid_cli.workflows.mip.sha1_state`), computed while they were in memory.
    """

    path: str
    format: str
    pixel_type: str
    channel_names: list[str]
    alpha_channel: int
    colorspace: str
    alpha_mode: str
    attributes: dict[str, Any] = field(default_factory=dict)
    attribute_types: dict[str, str] = field(default_factory=dict, repr=False)
    channel_pixel_types: list[str] = field(default_factory=list)
    width: int = 0
    height: int = 0
    origin: tuple[int, int] = (0, 0)
    display_window: tuple[int, int, int, int] | None = None
    tile: tuple[int, int] | None = None
    pixel_hash: Any = field(default=None, repr=False, compare=False)  # read_image(hash_source=True)


@dataclass
class Image:
    """Pixels in linear light plus how the file stored them.

    Attributes
    ----------
    pixels : numpy.ndarray
        float32, shape ``(H, W, C)``, linear light; colour is premultiplied by
        alpha when :attr:`premultiplied` is true.
    spec : ImageInfo
        What is needed to write the image back like its input.
    """

    pixels: np.ndarray
    spec: ImageInfo

    @property
    def premultiplied(self) -> bool:
        """Whether colour channels in :attr:`pixels` are multiplied by alpha."""
        return self.spec.alpha_channel >= 0 and self.spec.alpha_mode != "none"


# ---------------------------------------------------------------------------
# Helpers


def _one_line(message: str, fallback: str) -> str:
    lines = [ln.strip() for ln in str(message).splitlines() if ln.strip()]
    return lines[0] if lines else fallback


def _check_choice(name: str, value: str, choices: Iterable[str]) -> None:
    choices = tuple(choices)
    if value not in choices:
        raise UsageError(f"bad {name} {value!r}: expected one of {', '.join(choices)}")


def _type_name(t: oiio.TypeDesc) -> str:
    base = t.basetype
    if base == oiio.UINT8:
        return "uint8"
    if base == oiio.UINT16:
        return "uint16"
    if base == oiio.HALF:
        return "half"
    return "float"


def _classify_colorspace(name: str) -> str | None:
    n = name.strip().lower()
    if not n:
        return None
    if n in _LINEAR_NAMES or n.startswith(("lin", "g10")) or "linear" in n:
        return "linear"
    if any(k in n for k in _NON_LINEAR_KEYWORDS):
        return "srgb"
    return None


def _default_colorspace(pixel_type: str) -> str:
    return "srgb" if pixel_type in ("uint8", "uint16") else "linear"


def _default_names(nchannels: int) -> list[str]:
    return {1: ["Y"], 2: ["Y", "A"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}.get(
        nchannels, [f"channel{i}" for i in range(nchannels)])


def info_for_array(path: str | os.PathLike[str], nchannels: int, channel_names: list[str] | None = None) -> ImageInfo:
    """How to store linear float pixels that came from no file: named by channel count (Y, YA, RGB,
    RGBA), alpha (a channel named A) taken as premultiplied, as :func:`read_image` returns it."""
    names = list(channel_names) if channel_names else _default_names(nchannels)
    if len(names) != nchannels:
        raise UsageError(f"{len(names)} channel names for {nchannels} channels")
    alpha = next((i for i, n in enumerate(names) if n in ("A", "a", "alpha", "Alpha", "ALPHA")), -1)
    p = os.fspath(path)
    return ImageInfo(path=p, format=_format_from_path(p), pixel_type="float", channel_names=names,
                     alpha_channel=alpha, colorspace="linear", alpha_mode="premultiplied" if alpha >= 0 else "none")


def _find_alpha(spec: oiio.ImageSpec, names: list[str]) -> int:
    if 0 <= spec.alpha_channel < spec.nchannels:
        return int(spec.alpha_channel)
    for i, name in enumerate(names):
        if name in ("A", "a", "alpha", "Alpha", "ALPHA"):
            return i
    return -1


def _format_from_path(path: str) -> str:
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    if not ext:
        return ""
    for entry in oiio.get_string_attribute("extension_list").split(";"):
        fmt, _, exts = entry.partition(":")
        if ext in exts.split(","):
            return fmt
    return ""


def output_pixel_type(fmt: str, pixel_type: str) -> str:
    """The pixel type a format will store when asked for ``pixel_type``.

    Parameters
    ----------
    fmt : str
        OpenImageIO format name.
    pixel_type : str
        Requested type: ``"uint8"``, ``"uint16"``, ``"half"`` or ``"float"``.

    Returns
    -------
    str
        ``pixel_type`` if the format can hold it, else the nearest type it can:
        the widest integer type for a float request, ``half`` (or the
        narrowest float) for an integer request.
    """
    allowed = _FORMAT_TYPES.get(fmt)
    if allowed is None or pixel_type in allowed:
        return pixel_type
    if pixel_type in ("half", "float"):
        ints = [t for t in allowed if t in ("uint8", "uint16")]
        if ints:
            return ints[-1]
        return "float" if "float" in allowed else allowed[-1]
    floats = [t for t in allowed if t in ("half", "float")]
    if floats:
        return floats[0]
    return allowed[-1]


# ---------------------------------------------------------------------------
# Reading


def read_image(path: str | os.PathLike[str], *, colorspace: str = "auto",
               alpha: str = "auto", nan: str = "keep", subimage: int | None = None,
               keep_half: bool = False, hash_source: bool = False) -> Image:
    """Read an image into linear, premultiplied float32 pixels.

    Parameters
    ----------
    path : str or os.PathLike
        Any regular file OpenImageIO can read (FIFOs, devices and folders are
        refused at once; a name that is not valid UTF-8 is read through its
        open file descriptor).
    subimage : int, optional
        Which part of a multi-part file to read. None (the default): the file
        must hold one image; a multi-part file is refused with an InputError
        naming its parts (:func:`read_parts` reads them all).
    colorspace : {"auto", "linear", "srgb"}
        Encoding of the stored values; ``"auto"`` decides from the
        ``oiio:ColorSpace`` metadata, then from the pixel type (integer: sRGB,
        half/float: linear).
    alpha : {"auto", "straight", "premultiplied", "none"}
        How the file stores alpha; ``"auto"`` follows the file (see the module
        notes). ``"none"`` treats alpha as an ordinary channel: it is neither
        decoded nor multiplied in.
    nan : {"keep", "zero", "fail"}
        What to do with NaN/Inf values: keep them, replace them with 0, or
        raise :class:`DataError`.
    keep_half : bool
        Return a half file's pixels as float16 (exactly what it stores, half
        the memory of float32) when no colour or alpha conversion applies.
    hash_source : bool
        Also hash the stored pixels before any conversion, as maketx does for
        ``oiio:SHA-1`` (``spec.pixel_hash``; :func:`pyramid_cli.workflows.mip.finish_sha1`).

    Returns
    -------
    Image
        float32 ``(H, W, C)`` pixels (float16 under ``keep_half``), row 0 the
        top row of the file.

    Raises
    ------
    InputError
        Missing, unreadable, truncated, corrupt, unsupported or zero-size file.
    DataError
        Non-finite values under ``nan="fail"``.
    UsageError
        An unknown ``colorspace``, ``alpha`` or ``nan`` value.
    """
    _check_choice("colorspace", colorspace, ("auto", *COLORSPACES))
    _check_choice("alpha mode", alpha, ("auto", *ALPHA_MODES))
    _check_choice("nan mode", nan, options.NAN_POLICIES)
    p = os.fspath(path)

    check_input_file(p)
    with _readable_name(p) as name:
        data, spec, fmt = _read_pixels(name, subimage, keep_half, shown=p)
    pixel_hash = None
    if hash_source:  # before the conversions below, some of which work in place
        from pyramid_cli.workflows.mip import sha1_state

        pixel_hash = sha1_state(data)
    info = _describe(spec, fmt, p, colorspace, alpha, pixel_hash)
    pixels = _decode(data, info)
    _apply_nan_policy(pixels, nan, info, p, floats=data.dtype.kind == "f")
    return Image(pixels=pixels, spec=info)


def _describe(spec: oiio.ImageSpec, fmt: str, p: str, colorspace: str, alpha: str,
              pixel_hash: Any = None) -> ImageInfo:
    """What :func:`read_image` says of a file from its header (the encoding and alpha mode it decodes by)."""
    names = [str(n) for n in spec.channelnames] or _default_names(spec.nchannels)
    pixel_type = _type_name(spec.format)
    alpha_channel = _find_alpha(spec, names)

    attributes: dict[str, Any] = {}
    attribute_types: dict[str, str] = {}
    for attr in spec.extra_attribs:
        attributes[attr.name] = attr.value
        attribute_types[attr.name] = str(attr.type)

    if colorspace == "auto":
        meta = attributes.get("oiio:ColorSpace")
        encoding = _classify_colorspace(meta) if isinstance(meta, str) else None
        encoding = encoding or _default_colorspace(pixel_type)
    else:
        encoding = colorspace

    if alpha_channel < 0:
        alpha_mode = "none"
    elif alpha == "auto":
        unassociated = spec.get_int_attribute("oiio:UnassociatedAlpha", 0)
        alpha_mode = "straight" if unassociated else "premultiplied"
    else:
        alpha_mode = alpha

    channel_types = [_type_name(t) for t in spec.channelformats]
    if len(set(channel_types)) <= 1:
        channel_types = []
    display = (spec.full_x, spec.full_y, spec.full_width, spec.full_height)
    tiled = spec.tile_width > 0 and spec.tile_height > 0
    return ImageInfo(
        path=p,
        format=fmt,
        pixel_type=pixel_type,
        channel_names=names,
        alpha_channel=alpha_channel,
        colorspace=encoding,
        alpha_mode=alpha_mode,
        attributes=attributes,
        attribute_types=attribute_types,
        channel_pixel_types=channel_types,
        width=spec.width,
        height=spec.height,
        origin=(spec.x, spec.y),
        display_window=None if display == (spec.x, spec.y, spec.width, spec.height) else display,
        tile=(int(spec.tile_width), int(spec.tile_height)) if tiled else None,
        pixel_hash=pixel_hash,
    )


def _decode(px: np.ndarray, info: ImageInfo) -> np.ndarray:
    """Stored values (as :func:`_read_pixels` returns them) → linear premultiplied float32 (or kept half).

    Pixel by pixel: a band of rows decodes exactly as the whole image does."""
    alpha_channel, encoding, alpha_mode = info.alpha_channel, info.colorspace, info.alpha_mode
    colour = _colour_mask(px.shape[2], alpha_channel, info.channel_names)
    has_alpha = alpha_channel >= 0 and alpha_mode != "none"
    if px.dtype in (np.uint8, np.uint16):
        px = _decode_integer(px, encoding == "srgb", colour, alpha_channel if has_alpha else -1,
                             alpha_mode == "straight")
    else:
        if px.dtype == np.float16 and (encoding == "srgb" or has_alpha and alpha_mode == "straight"):
            px = px.astype(np.float32)  # converted below: not in half precision
        if encoding == "srgb":
            if has_alpha and alpha_mode == "premultiplied":
                # The file premultiplied the encoded values: divide them back out
                # before decoding, premultiply again in linear light below.
                _unpremultiply(px, alpha_channel, colour)
            px[..., colour] = srgb_to_linear(px[..., colour])
            if has_alpha:
                _premultiply(px, alpha_channel, colour)
        elif has_alpha and alpha_mode == "straight":
            _premultiply(px, alpha_channel, colour)
    return px if px.dtype == np.float16 else px.astype(np.float32, copy=False)


def _apply_nan_policy(pixels: np.ndarray, nan: str, info: ImageInfo, p: str, row: int = 0,
                      floats: bool = True) -> int:
    """``nan="fail"``: DataError naming the first non-finite value; ``"zero"``: replaced in place.
    Returns the count found (``row``: where ``pixels`` starts in the image, for the message; ``floats``
    False: decoded from integers, always finite, not scanned)."""
    bad = count_nonfinite(pixels) if floats else 0
    if bad and nan == "fail":
        y, x, c = (int(v) for v in np.argwhere(~np.isfinite(pixels))[0])
        names = info.channel_names
        raise DataError(
            f"{p}: {bad} non-finite pixel value{'s' if bad != 1 else ''} (NaN/Inf), "
            f"first at x={x}, y={y + row}, channel {c} ({names[c] if c < len(names) else c})"
        )
    if bad and nan == "zero":
        pixels[~np.isfinite(pixels)] = 0.0
    return bad


def check_input_file(path: str | os.PathLike[str]) -> None:
    """Refuse at once what cannot be an image file: missing, a folder, a FIFO, a device, unreadable, empty.

    Raises
    ------
    InputError
        Exit code 3, one line naming ``path``.
    """
    p = os.fspath(path)
    if not os.path.lexists(p):
        raise InputError(f"cannot read {p}: no such file")
    try:
        st = os.stat(p)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"cannot read {p}: it is a directory")
    if not stat.S_ISREG(st.st_mode):
        # Opening a FIFO or a device could block forever or never end.
        kind = ("a FIFO, " if stat.S_ISFIFO(st.st_mode) else "a socket, " if stat.S_ISSOCK(st.st_mode)
                else "a device, " if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "")
        raise InputError(f"cannot read {p}: it is {kind}not a regular file")
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        os.close(fd)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}") from None
    if st.st_size == 0:
        raise InputError(f"cannot read {p}: the file is empty")


@contextlib.contextmanager
def _readable_name(p: str):
    """A name OpenImageIO can open for ``p``: itself, or /proc/self/fd/N when it is not valid UTF-8."""
    if is_utf8(p):
        yield p
        return
    if not os.path.isdir("/proc/self/fd"):
        raise InputError(f"cannot read {p!r}: the file name is not valid UTF-8")
    try:
        fd = os.open(p, os.O_RDONLY)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}") from None
    try:
        yield f"/proc/self/fd/{fd}"
    finally:
        os.close(fd)


def read_shape(path: str | os.PathLike[str]) -> tuple[int, int, int] | None:
    """(height, width, channels) from the file's header, without its pixels; None if it cannot be read.

    Cheap enough to plan ahead while the pixels decode; :func:`read_image` reports the errors.
    """
    p = os.fspath(path)
    try:
        if not stat.S_ISREG(os.stat(p).st_mode) or not is_utf8(p):
            return None  # a FIFO would block here: read_image refuses it
        inp = oiio.ImageInput.open(p)
    except Exception:  # noqa: BLE001 - binding errors: read_image says what they are
        return None
    if inp is None:
        oiio.geterror()  # clear it: read_image reports it
        return None
    try:
        spec = inp.spec()
        return (spec.height, spec.width, spec.nchannels) if spec.width > 0 and spec.height > 0 else None
    finally:
        inp.close()


def count_parts(path: str | os.PathLike[str]) -> int:
    """How many subimages (EXR parts) a file holds; 1 for ordinary images."""
    p = os.fspath(path)
    check_input_file(p)
    with _readable_name(p) as name:
        inp = oiio.ImageInput.open(name)
        if inp is None:
            raise InputError(f"cannot read {p}: {_one_line(oiio.geterror(), 'open failed')}")
        try:
            return len(_part_names(inp))
        finally:
            inp.close()


def _part_names(inp) -> list[str]:
    """The name of every subimage of an open file (``part k`` where it has none); leaves it at subimage 0."""
    names = []
    while inp.seek_subimage(len(names), 0):
        names.append(inp.spec().get_string_attribute("name") or f"part {len(names)}")
    inp.geterror()  # the last, failed seek's message
    inp.seek_subimage(0, 0)
    return names or ["part 0"]


def read_parts(path: str | os.PathLike[str], **options) -> list[Image]:
    """Every subimage of a multi-part file (as :func:`read_image` reads one), in order.

    Raises
    ------
    InputError
        As :func:`read_image`, or when parts differ in channel count (they cannot be one pyramid).
    """
    options.pop("subimage", None)
    first = read_image(path, subimage=0, **options)
    parts = [first] + [read_image(path, subimage=k, **options) for k in range(1, count_parts(path))]
    check_same_channels(parts)
    return parts


def check_pyramid(images: list[Image]) -> None:
    """Refuse (InputError, exit 3) levels that cannot be one pyramid (``pyramid collapse``'s bands):
    different channel counts, or a level whose size is not ⌈n/2⌉ of the one before."""
    check_same_channels(images)
    for k in range(1, len(images)):
        h, w = images[k - 1].pixels.shape[:2]
        want = (-(-h // 2), -(-w // 2))
        got = images[k].pixels.shape[:2]
        if tuple(got) != want:
            im = images[k]
            where = im.spec.path if im.spec.path != images[0].spec.path else f"{im.spec.path}: part {k}"
            raise InputError(f"cannot read {where}: level {k} is {got[1]}x{got[0]}, but the level after a "
                             f"{w}x{h} one is {want[1]}x{want[0]}")


def check_same_channels(images: list[Image]) -> None:
    """Refuse (InputError, exit 3) images meant to be one pyramid whose channel counts differ."""
    want = images[0].pixels.shape[2] if images else 0
    for k, im in enumerate(images):
        n = im.pixels.shape[2]
        if n != want:
            where = im.spec.path if im.spec.path != images[0].spec.path else f"{im.spec.path}: part {k}"
            raise InputError(f"cannot read {where}: {n} channel{'s' if n != 1 else ''} "
                             f"({', '.join(im.spec.channel_names)}), where the first has {want} "
                             f"({', '.join(images[0].spec.channel_names)}); every level needs the same channels")


def _open_input(name: str, subimage: int | None, p: str):
    """An open ImageInput positioned on one checked subimage: ``(input, spec, format name, subimage)``.

    ``subimage`` None refuses a multi-part file; InputError (naming ``p``) for what cannot be read."""
    config = oiio.ImageSpec()
    # Ask for the stored values: without this hint OpenImageIO premultiplies
    # straight-alpha files itself, in the encoded (non-linear) space.
    config.attribute("oiio:UnassociatedAlpha", 1)
    try:
        inp = oiio.ImageInput.open(name, config)
    except Exception as exc:  # binding errors become one line
        raise InputError(f"cannot read {p}: {_one_line(str(exc), 'open failed')}") from None
    if inp is None:
        msg = _one_line(oiio.geterror().replace(name, p), "not an image file OpenImageIO can read")
        raise InputError(f"cannot read {p}: {msg}")
    try:
        if subimage is None:
            if inp.seek_subimage(1, 0):
                parts = _part_names(inp)
                raise InputError(f"cannot read {p}: it holds {len(parts)} parts ({', '.join(parts)}) and this "
                                 "command reads one image (pyramid collapse reads every part; oiiotool "
                                 "--subimage extracts one)")
            subimage = 0
            inp.geterror()  # the failed seek's message: not an error of this file
            inp.seek_subimage(0, 0)  # a failed seek can leave a reader (TIFF) nowhere
        elif subimage and not inp.seek_subimage(subimage, 0):
            raise InputError(f"cannot read {p}: it has no part {subimage}")
        spec = inp.spec()
        fmt = str(inp.format_name())
        if spec.deep:
            raise InputError(f"cannot read {p}: deep images are not supported")
        if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
            raise InputError(
                f"cannot read {p}: zero-size image "
                f"({spec.width}x{spec.height}, {spec.nchannels} channels)")
        if spec.depth > 1:
            raise InputError(f"cannot read {p}: volume images are not supported")
    except BaseException:
        inp.close()
        raise
    return inp, spec, fmt, subimage


def _read_pixels(name: str, subimage: int | None = None, keep_half: bool = False,
                 shown: str | None = None) -> tuple[np.ndarray, oiio.ImageSpec, str]:
    """Open and fully read ``name`` (one subimage): integer files as stored (uint8, uint16), float
    files as float32 (as stored, without a copy), half files as float16 under ``keep_half``.

    ``subimage`` None refuses a multi-part file; ``shown`` is the path messages name."""
    p = shown if shown is not None else name
    inp, spec, fmt, subimage = _open_input(name, subimage, p)
    try:
        native = _type_name(spec.format)
        uniform = len({str(t) for t in spec.channelformats}) <= 1
        keep = ("uint8", "uint16", "half") if keep_half else ("uint8", "uint16")
        read_type = native if native in keep and uniform else "float"
        try:
            data = inp.read_image(subimage, 0, 0, spec.nchannels, read_type)
        except Exception as exc:
            data = None
            err = str(exc)
        else:
            err = inp.geterror() if inp.has_error else ""
        if data is None or err:
            err = (err or oiio.geterror()).replace(name, p)
            msg = _one_line(err, "read failed")
            raise InputError(f"cannot read {p}: {msg} (truncated or corrupt file?)")
    finally:
        inp.close()
    data = np.asarray(data).reshape(spec.height, spec.width, spec.nchannels)
    if read_type in ("uint8", "uint16"):
        return data, spec, fmt  # decoded by _decode_integer
    if read_type == "half":
        return np.asarray(data, dtype=np.float16), spec, fmt
    return np.asarray(data, dtype=np.float32), spec, fmt  # float files stay float32: no 2× copy


# ---------------------------------------------------------------------------
# Writing


def _output_colorspace(info: ImageInfo, out_type: str) -> str:
    in_int = info.pixel_type in ("uint8", "uint16")
    out_int = out_type in ("uint8", "uint16")
    if in_int == out_int:
        return info.colorspace
    return _default_colorspace(out_type)


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


# Messages OpenImageIO's writers leave in their error state on every successful write
# (OpenImageIO 3.2's TIFF writer, for an image without Exif data); the read-back checks the file.
_BENIGN_ERRORS = frozenset({"failed TIFFWriteCustomDirectory() of the Exif data"})


class _WriteFailed(Exception):
    """An OpenImageIO call on the output failed; the message is OpenImageIO's."""


def _checked(out, ok, what: str) -> None:
    """Raise _WriteFailed unless ``ok`` and the writer holds no error (PNG and TGA writers report a
    failed write only through their error state, returning success)."""
    if ok and not out.has_error:
        return
    lines = [ln.strip() for ln in (out.geterror() or oiio.geterror()).splitlines()
             if ln.strip() and ln.strip() not in _BENIGN_ERRORS]
    if ok and not lines:
        return
    raise _WriteFailed(lines[0] if lines else f"{what} failed")


def _write_pixels(out, spec: oiio.ImageSpec, data: np.ndarray) -> None:
    """Write one (sub)image: scanlines whole, tiled images one row of tiles at a time.

    OpenImageIO's write_image of a tiled OpenEXR hangs for ever when a write fails (its parallel
    tile writer deadlocks on ENOSPC/EFBIG); a row of tiles per call fails cleanly.
    """
    if spec.tile_width > 0 and spec.tile_height > 0:
        th = spec.tile_height
        for y0 in range(0, spec.height, th):
            y1 = min(y0 + th, spec.height)
            ok = out.write_tiles(spec.x, spec.x + spec.width, spec.y + y0, spec.y + y1, spec.z, spec.z + 1,
                                 np.ascontiguousarray(data[y0:y1]))
            _checked(out, ok, "write")
    else:
        _checked(out, out.write_image(data), "write")


def _oiio_write_parts(target: str, fmt: str, parts: list[tuple[oiio.ImageSpec, np.ndarray]], mode: str) -> None:
    """Write ``parts`` to ``target`` with OpenImageIO, checking every call; raise _WriteFailed.

    ``mode``: "single" (one image), "mipmap" (MIP levels of one tiled image), "multipart" (subimages).
    """
    out = oiio.ImageOutput.create(fmt) if fmt else oiio.ImageOutput.create(target)
    if out is None:
        raise _WriteFailed(_one_line(oiio.geterror(), "no writer for this format"))
    failure: _WriteFailed | None = None
    try:
        if mode == "multipart":
            ok = out.open(target, tuple(spec for spec, _ in parts))
        else:
            ok = out.open(target, parts[0][0], "Create")
        _checked(out, ok, "open")
        for k, (spec, data) in enumerate(parts):
            if k:
                # A format without MIP levels of its own (TIFF) holds them as subimages, which its reader
                # presents as MIP levels when the file says "textureformat" (maketx does the same).
                append = "AppendMIPLevel" if mode == "mipmap" and out.supports("mipmap") else "AppendSubimage"
                _checked(out, out.open(target, spec, append), "open")
            _write_pixels(out, spec, data)
    except _WriteFailed as exc:
        failure = exc
    except (RuntimeError, TypeError, ValueError) as exc:  # binding errors
        failure = _WriteFailed(_one_line(str(exc), "write failed"))
    finally:
        closed = out.close()
    if failure is not None:
        raise failure
    _checked(out, closed, "close")


def _size_limit() -> int | None:
    """The process's file size limit (ulimit -f) in bytes, None when unlimited."""
    if resource is None:
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else int(soft)


def _copy_to(src_fd: int, dst: str) -> None:
    """Copy the whole of ``src_fd`` into the file ``dst`` with os.write (OSError on ENOSPC/EFBIG/EDQUOT)."""
    fd = os.open(dst, os.O_WRONLY | os.O_TRUNC)
    try:
        offset, size = 0, os.fstat(src_fd).st_size
        while offset < size:
            chunk = os.pread(src_fd, min(1 << 23, size - offset), offset)
            view = memoryview(chunk)
            while view:
                n = os.write(fd, view)
                view = view[n:]
            offset += len(chunk)
    finally:
        os.close(fd)


_PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def _verify(tmp: str, fmt: str, parts: list[tuple[oiio.ImageSpec, np.ndarray]], mode: str) -> None:
    """Check what was written: not empty, the format's end marker where it has one (PNG, JPEG),
    and a header that reads back with the size and channels written."""
    size = os.path.getsize(tmp)
    if size == 0:
        raise _WriteFailed("nothing was written (the file is empty)")
    if fmt in ("png", "jpeg"):
        with open(tmp, "rb") as f:
            f.seek(max(0, size - 12))
            tail = f.read()
        if not tail.endswith(_PNG_END if fmt == "png" else b"\xff\xd9"):
            raise _WriteFailed(f"the file is incomplete ({size} bytes, no end marker)")
    inp = oiio.ImageInput.open(tmp)
    if inp is None:
        raise _WriteFailed(f"the file does not read back ({_one_line(oiio.geterror(), 'unreadable')})")
    try:
        spec, want = inp.spec(), parts[0][0]
        if (spec.width, spec.height) != (want.width, want.height):
            raise _WriteFailed(f"the file reads back as {spec.width}x{spec.height}, not {want.width}x{want.height}")
        if mode == "multipart" and not inp.seek_subimage(len(parts) - 1, 0):
            raise _WriteFailed(f"the file reads back with fewer than {len(parts)} parts")
        if mode == "mipmap" and not inp.seek_subimage(0, len(parts) - 1):
            raise _WriteFailed(f"the file reads back with fewer than {len(parts)} MIP levels")
    finally:
        inp.close()
        oiio.geterror()  # leave no stale error behind


def _write_file(tmp: str, user_path: str, fmt: str, parts: list[tuple[oiio.ImageSpec, np.ndarray]],
                mode: str = "single") -> None:
    """Write ``parts`` into the temporary ``tmp`` and check the result; OutputError names ``user_path``."""
    try:
        if fmt in _ENCODE_IN_MEMORY and hasattr(os, "memfd_create") and os.path.isdir("/proc/self/fd"):
            limit = _size_limit()
            bound = 2 * sum(data.nbytes for _, data in parts) + (1 << 20)
            if limit is not None and bound > limit:
                # The encoder would exit the process if the limit stopped it: refuse first.
                raise _WriteFailed(f"a {_FORMAT_TITLES.get(fmt, fmt)} file of this size may need up to {bound} "
                                   f"bytes, over the file size limit (ulimit -f) of {limit} bytes")
            mem = os.memfd_create("pyramid-encode", getattr(os, "MFD_CLOEXEC", 0))
            try:
                _oiio_write_parts(f"/proc/self/fd/{mem}", fmt, parts, mode)
                _copy_to(mem, tmp)
            finally:
                os.close(mem)
        else:
            _oiio_write_parts(tmp, "", parts, mode)
        _verify(tmp, fmt, parts, mode)
    except _WriteFailed as exc:
        message = str(exc).replace(tmp, user_path)
        raise OutputError(f"cannot write {user_path}: {message}{_diagnosis(tmp)}") from None
    except OSError as exc:
        raise OutputError(f"cannot write {user_path}: {exc.strerror or exc}") from None


def _diagnosis(tmp: str) -> str:
    """Why a write may have failed, when the system says (OpenImageIO's messages do not)."""
    limit = _size_limit()
    with contextlib.suppress(OSError):
        if limit is not None and os.path.getsize(tmp) >= limit:
            return f" (the file size limit, ulimit -f, is {limit} bytes)"
    with contextlib.suppress(OSError):
        st = os.statvfs(os.path.dirname(os.path.abspath(tmp)))
        if st.f_bavail * st.f_frsize < (1 << 20):
            return " (the disk is full)"
    return ""


def _oiio_write(path: str, spec: oiio.ImageSpec, pixels: np.ndarray) -> None:
    """Write ``pixels`` to ``path`` with OpenImageIO (checked, see :func:`_write_file`); OutputError on failure."""
    _write_file(path, path, _format_from_path(path), [(spec, pixels)])


def _is_same_file(a: str, b: str) -> bool:
    try:
        if os.path.exists(a) and os.path.exists(b):
            return os.path.samefile(a, b)
    except OSError:
        pass
    return os.path.realpath(a) == os.path.realpath(b)


def write_image(path: str | os.PathLike[str], image: Image, *,
                pixel_type: str | None = None, colorspace: str | None = None,
                alpha: str | None = None, dither: bool = False,
                compression: str | None = None, force: bool = False,
                inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
    """Write an image atomically, encoded like its input unless told otherwise.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its extension picks the format.
    image : Image
        Linear pixels (premultiplied when ``image.premultiplied``) and the
        info of the input they came from.
    pixel_type : {"uint8", "uint16", "half", "float"}, optional
        Stored type; default the input's. Replaced by the nearest type the
        format can hold (see :func:`output_pixel_type`).
    colorspace : {"linear", "srgb"}, optional
        Encoding to store; default the input's when input and output are both
        integer or both float, else the output type's default (integer: sRGB,
        float: linear).
    alpha : {"straight", "premultiplied", "none"}, optional
        How to store alpha; default what the output format expects (EXR:
        premultiplied; TIFF: like a TIFF input, else straight for integers;
        other formats: straight). ``"none"`` writes alpha values as they are.
    dither : bool
        Add an ordered (Bayer 8x8, deterministic) dither of under half a step
        to colour channels before rounding to uint8.
    compression : str, optional
        OpenImageIO compression name, e.g. ``"zip"``, ``"piz"``,
        ``"dwaa:45"``; default the input's when the format is unchanged.
    force : bool
        Allow overwriting a path in ``inputs``.
    inputs : iterable of path
        Files that must not be overwritten.

    Raises
    ------
    OutputError
        Unknown extension, unwritable folder, write failure, or the output is
        one of ``inputs`` and ``force`` is false.
    UsageError
        An unknown ``pixel_type``, ``colorspace`` or ``alpha`` value.
    """
    spec, data = _encode(path, image, pixel_type=pixel_type, colorspace=colorspace, alpha=alpha, dither=dither,
                         compression=compression, force=force, inputs=inputs)
    out_path = os.fspath(path)
    _atomic_write(out_path, os.path.dirname(os.path.abspath(out_path)), spec, data)


def write_images(paths: list[str | os.PathLike[str]], images: list[Image], **options) -> None:
    """Write several files all-or-nothing (``pyramid levels``): every file is written and checked under
    its temporary name first, then all are renamed; a failure or interruption leaves every previous
    output untouched and no temporary behind.

    Parameters
    ----------
    paths, images
        One output path per image.
    options
        As for :func:`write_image` (pixel_type, colorspace, alpha, dither, compression, force, inputs).
    """
    out_paths = [os.fspath(p) for p in paths]
    if len(out_paths) != len(images):
        raise ValueError("write_images needs one path per image")
    for p in out_paths:  # refuse bad names and options before writing anything
        _check_output_path(p, options.get("force", False), options.get("inputs", ()))
        check_write_options(p, options.get("pixel_type"), options.get("compression"))
    with atomic_paths(out_paths) as tmps:
        for p, tmp, image in zip(out_paths, tmps, images, strict=True):
            spec, data = _encode(p, image, **options)  # one image's encoded copy at a time
            _write_file(tmp, p, _format_from_path(p), [(spec, data)])


def oiio_version() -> str:
    """The OpenImageIO version writing the files, e.g. ``"3.2.2.0"``."""
    return str(oiio.__version__)


def source_sha1(path: str | os.PathLike[str], extra: str = "") -> str:
    """maketx's ``oiio:SHA-1`` of a source file: its stored values as float32, hashed in 256-row blocks.

    See :func:`pyramid_cli.workflows.mip.pixel_sha1`; ``extra`` is what maketx appends (its filter name and a space).
    """
    from pyramid_cli.workflows.mip import pixel_sha1

    p = os.fspath(path)
    inp = oiio.ImageInput.open(p)
    if inp is None:
        raise InputError(f"cannot read {p}: {_one_line(oiio.geterror(), 'unreadable')}")
    try:
        spec = inp.spec()
        data = inp.read_image("float")
    finally:
        inp.close()
    if data is None:
        raise InputError(f"cannot read {p}: {_one_line(oiio.geterror(), 'read failed')}")
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
    average, constant = colors if colors is not None else (average_color(data), constant_color(data))
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
    round_up = all(b == ((a[0] + 1) // 2, (a[1] + 1) // 2) for a, b in pairs)
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
        raise OutputError(f"cannot write {out_path}: the {_FORMAT_TITLES.get(fmt, fmt)} format cannot hold MIP levels")
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
        As for :func:`write_image` (pixel_type, colorspace, alpha, dither, compression, force, inputs).
    """
    out_path = os.fspath(path)
    encoded = [_encode(out_path, im, **options) for im in images]
    fmt = _format_from_path(out_path)
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
    if not able:
        oiio.geterror()
        raise OutputError(f"cannot write {out_path}: the {_FORMAT_TITLES.get(fmt, fmt)} format cannot hold "
                          f"{'MIP levels' if mode == 'mipmap' else 'several images'}")
    if mode == "mipmap":
        _mip_metadata(encoded[0][0], encoded[0][1], meta or {}, bool(probe.supports("arbitrary_metadata")))
    with atomic_path(out_path) as tmp:
        _write_file(tmp, out_path, fmt, encoded, mode)


def _check_output_path(out_path: str, force: bool, inputs) -> str:
    """The output's format, after refusing an unknown extension, a folder, or an input without ``force``."""
    fmt = _format_from_path(out_path)
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


def check_write_options(path: str | os.PathLike[str], pixel_type: str | None = None,
                        compression: str | None = None) -> None:
    """Refuse (UsageError, exit 2) a --type or --compression the output's format would not honour.

    Without this OpenImageIO stores the nearest type or its default compression without a word.
    ``None`` means "not asked": the input's type (as the format allows) and compression apply.
    Cheap: call it before any work.
    """
    out_path = os.fspath(path)
    fmt = _format_from_path(out_path)
    if not fmt:
        return  # the write reports the unknown extension
    title = _FORMAT_TITLES.get(fmt, fmt)
    if pixel_type is not None:
        _check_choice("pixel type", pixel_type, PIXEL_TYPES)
        allowed = _FORMAT_TYPES.get(fmt)
        if allowed is not None and pixel_type not in allowed:
            raise UsageError(f"{out_path}: --type {pixel_type} cannot be stored in {title} files "
                             f"(they hold {' or '.join(allowed)})")
    if compression is None:
        return
    c = str(compression).strip().lower()
    name, _, level = c.partition(":")
    if fmt == "png":
        if not (c.isdigit() and 0 <= int(c) <= 9):
            raise UsageError(f"{out_path}: unknown --compression {compression} (PNG takes a zlib level 0-9)")
    elif fmt == "jpeg":
        q = level if name == "jpeg" else c
        if not (q.isdigit() and 1 <= int(q) <= 100):
            raise UsageError(f"{out_path}: unknown --compression {compression} "
                             "(JPEG takes a quality 1-100, or jpeg:QUALITY)")
    elif fmt in _COMPRESSIONS:
        ok = name in _COMPRESSIONS[fmt] and (not level or (name in _COMPRESSION_LEVELS and _is_number(level)))
        if not ok:
            levels = ", ".join(c for c in _COMPRESSIONS[fmt] if c in _COMPRESSION_LEVELS)
            raise UsageError(f"{out_path}: unknown --compression {compression} "
                             f"({title} takes {', '.join(_COMPRESSIONS[fmt])}; {levels} take :LEVEL)")
    else:
        raise UsageError(f"{out_path}: --compression has no effect on {title} files")


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _encode(path, image: Image, *, pixel_type=None, colorspace=None, alpha=None, dither=False, compression=None,
            force=False, inputs=()) -> tuple[oiio.ImageSpec, np.ndarray]:
    """The spec and encoded pixels :func:`write_image` would write (checks included)."""
    out_path = os.fspath(path)
    info = image.spec
    if pixel_type is not None:
        _check_choice("pixel type", pixel_type, PIXEL_TYPES)
    if colorspace is not None:
        _check_choice("colorspace", colorspace, COLORSPACES)
    if alpha is not None:
        _check_choice("alpha mode", alpha, ALPHA_MODES)

    fmt = _check_output_path(out_path, force, inputs)
    check_write_options(out_path, pixel_type, compression)

    pixels = np.asarray(image.pixels)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.ndim != 3 or 0 in pixels.shape:
        raise OutputError(f"cannot write {out_path}: bad pixel array shape {pixels.shape}")
    height, width, nch = pixels.shape
    names = list(info.channel_names)
    alpha_channel = info.alpha_channel
    if len(names) != nch:
        names = _default_names(nch)
        alpha_channel = names.index("A") if "A" in names else -1

    out_type, encoding, memory_premultiplied, mode = _write_rules(fmt, info, alpha_channel, pixel_type,
                                                                  colorspace, alpha)
    out_int = out_type in ("uint8", "uint16")

    if (out_type == "uint8" and encoding == "srgb" and mode == "none" and not dither
            and not (fmt in _NO_ALPHA_FORMATS and alpha_channel >= 0)):
        # The common 8-bit sRGB file without alpha: encoded by table, a channel at a time.
        colour = _colour_mask(nch, alpha_channel, names)
        if all(colour):  # one pass over the whole array: no strided per-channel copies (1.6× faster at 4K)
            return _output_spec(info, fmt, out_type, names, alpha_channel, nch, width, height, encoding, mode,
                                pixel_type, compression), _srgb8(pixels)
        data = np.empty(pixels.shape, dtype=np.uint8)
        for c in range(nch):
            data[..., c] = _srgb8(pixels[..., c]) if colour[c] else \
                _encode_integer(pixels[..., c:c + 1].astype(np.float64), out_type, False, colour[c:c + 1])[..., 0]
        return _output_spec(info, fmt, out_type, names, alpha_channel, nch, width, height, encoding, mode,
                            pixel_type, compression), data
    if not out_int and not _converts(fmt, alpha_channel, memory_premultiplied, encoding, mode):
        # Stored as they are: no copy (float16 stays float16 for a half file; OIIO converts float32).
        px = pixels if pixels.dtype in (np.float16, np.float32) else pixels.astype(np.float32)
    else:
        px = pixels.astype(np.float64 if out_int else np.float32)  # a copy: encoded in place below
    if fmt in _NO_ALPHA_FORMATS and alpha_channel >= 0:
        # No alpha in the file: premultiplied linear colour alone is the image
        # composited over black.
        if not memory_premultiplied:
            _premultiply(px, alpha_channel, _colour_mask(nch, alpha_channel, names))
        keep = [i for i in range(nch) if i != alpha_channel]
        px = px[..., keep]
        names = [names[i] for i in keep]
        alpha_channel = -1
        mode = "none"
        nch -= 1
    colour = _colour_mask(nch, alpha_channel, names)
    if mode != "none":
        if memory_premultiplied and (mode == "straight" or encoding == "srgb"):
            _unpremultiply(px, alpha_channel, colour)
        if encoding == "srgb":
            px[..., colour] = linear_to_srgb(px[..., colour])
        if mode == "premultiplied" and (encoding == "srgb" or not memory_premultiplied):
            _premultiply(px, alpha_channel, colour)
    elif encoding == "srgb":
        px[..., colour] = linear_to_srgb(px[..., colour])

    if out_int:
        data = _encode_integer(px, out_type, dither, colour)
    else:
        data = px if px.dtype == np.float16 and out_type == "half" else px.astype(np.float32, copy=False)
    data = np.ascontiguousarray(data)
    return _output_spec(info, fmt, out_type, names, alpha_channel, nch, width, height, encoding, mode,
                        pixel_type, compression), data


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
    _set_windows(spec, info, width, height)

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
    if isinstance(old_cs, str) and _classify_colorspace(old_cs) == encoding:
        spec.attribute("oiio:ColorSpace", old_cs)
    elif isinstance(old_cs, str) or encoding != _default_colorspace(out_type):
        spec.attribute("oiio:ColorSpace", _OIIO_COLORSPACE[encoding])
    if mode == "straight" or (mode == "none" and alpha_channel >= 0) or (
            alpha_channel >= 0 and fmt not in _ASSOCIATED_CAPABLE):
        # The values handed over are exactly what is to be stored: stop
        # OpenImageIO from unpremultiplying them again.
        spec.attribute("oiio:UnassociatedAlpha", 1)
    if compression is not None:
        if fmt == "png" and compression.isdigit():
            spec.attribute("png:compressionLevel", int(compression))  # zlib level 0-9
        elif fmt == "jpeg" and compression.strip().isdigit():
            spec.attribute("compression", f"jpeg:{int(compression)}")  # quality 1-100
        else:
            spec.attribute("compression", compression)
    if same_format and info.tile is not None and fmt in _TILED_FORMATS:
        # A tiled input is written back tiled, with its tile size.
        spec.tile_width, spec.tile_height = info.tile
    return spec


def _set_windows(spec: oiio.ImageSpec, info: ImageInfo, width: int, height: int) -> None:
    """The data and display windows of the input, which only still apply at the input's size."""
    same_size = (width, height) == (info.width, info.height)
    if same_size and (info.origin != (0, 0) or info.display_window is not None):
        spec.x, spec.y = info.origin
        if info.display_window is not None:
            spec.full_x, spec.full_y, spec.full_width, spec.full_height = info.display_window
        else:
            spec.full_x, spec.full_y = info.origin
            spec.full_width, spec.full_height = width, height


def _write_rules(fmt: str, info: ImageInfo, alpha_channel: int, pixel_type: str | None, colorspace: str | None,
                 alpha: str | None) -> tuple[str, str, bool, str]:
    """How a write stores the image: (pixel type, encoding, whether memory is premultiplied, alpha mode)."""
    out_type = output_pixel_type(fmt, pixel_type or info.pixel_type)
    encoding = colorspace or _output_colorspace(info, out_type)
    memory_premultiplied = alpha_channel >= 0 and info.alpha_mode != "none"
    mode = "none" if alpha_channel < 0 else (alpha or _output_alpha_mode(info, fmt, out_type))
    return out_type, encoding, memory_premultiplied, mode


def _converts(fmt: str, alpha_channel: int, memory_premultiplied: bool, encoding: str, mode: str) -> bool:
    """Does writing change the values (alpha dropped or re-associated, sRGB encoding)?"""
    if fmt in _NO_ALPHA_FORMATS and alpha_channel >= 0 or encoding == "srgb":
        return True
    return mode != "none" and (mode == "straight" and memory_premultiplied
                               or mode == "premultiplied" and not memory_premultiplied)


def stores_half_unchanged(path: str | os.PathLike[str], info: ImageInfo, *, pixel_type: str | None = None,
                          colorspace: str | None = None, alpha: str | None = None) -> bool:
    """Will :func:`write_image` store linear values as half without converting them?

    Then a float result may be rounded to half (nearest even) before writing, with the
    same file as a result: the GL read-back does that and moves half the bytes.
    """
    fmt = _format_from_path(os.fspath(path))
    if not fmt:
        return False
    out_type, encoding, memory_premultiplied, mode = _write_rules(fmt, info, info.alpha_channel, pixel_type,
                                                                  colorspace, alpha)
    return out_type == "half" and not _converts(fmt, info.alpha_channel, memory_premultiplied, encoding, mode)


def write_spec(path: str | os.PathLike[str], spec: oiio.ImageSpec, data: np.ndarray) -> None:
    """Write ``data`` exactly as ``spec`` says (no colour or alpha rules), atomically and checked like every
    other write: a failure is an OutputError naming ``path`` and leaves what was there untouched."""
    out_path = os.fspath(path)
    _atomic_write(out_path, os.path.dirname(os.path.abspath(out_path)), spec, np.ascontiguousarray(data))


def _atomic_write(out_path: str, folder: str, spec: oiio.ImageSpec, data: np.ndarray) -> None:
    with atomic_path(out_path) as tmp:
        try:
            _oiio_write(tmp, spec, data)
        except OutputError as exc:
            # Report the user's path, not the temporary one.
            raise OutputError(exc.message.replace(tmp, out_path)) from None


def describe_rules(info: ImageInfo) -> str:
    """One line saying which colour and alpha rule is in force for ``info``.

    Parameters
    ----------
    info : ImageInfo
        As returned in :attr:`Image.spec`.

    Returns
    -------
    str
        E.g. ``"in.png: png uint8, sRGB-encoded: decoded with the sRGB EOTF to
        linear light; straight alpha (channel A): premultiplied after
        decoding"``.
    """
    if info.colorspace == "srgb":
        colour = "sRGB-encoded: decoded with the sRGB EOTF to linear light"
    else:
        colour = "linear light: no decoding"
    if info.alpha_channel < 0:
        alpha = "no alpha"
    else:
        name = (info.channel_names[info.alpha_channel]
                if info.alpha_channel < len(info.channel_names) else str(info.alpha_channel))
        if info.alpha_mode == "straight":
            alpha = f"straight alpha (channel {name}): premultiplied after decoding"
        elif info.alpha_mode == "premultiplied":
            alpha = f"premultiplied alpha (channel {name}): used as stored"
        else:
            alpha = f"alpha (channel {name}) treated as an ordinary channel"
    return f"{info.path}: {info.format} {info.pixel_type}, {colour}; {alpha}"


# ---------------------------------------------------------------------------
# Streaming: a band of rows at a time (pyramid_cli.run.stream)


class ImageStream:
    """An image file read a band of rows at a time, each band decoded exactly as :func:`read_image` decodes
    the whole picture (the decoding is pixel by pixel). Use :func:`open_stream`; close it (or ``with``).

    Attributes
    ----------
    info : ImageInfo
        What :func:`read_image` would report.
    shape : tuple
        (rows, columns, channels).
    dtype : numpy dtype
        Of the bands :meth:`read` returns: float32, or float16 for a half file under ``keep_half`` without
        colour or alpha conversion.
    nonfinite : int
        NaN/Inf values seen so far (kept under ``nan="keep"``).
    """

    def __init__(self, path: str, *, colorspace: str = "auto", alpha: str = "auto", nan: str = "keep",
                 keep_half: bool = False):
        _check_choice("colorspace", colorspace, ("auto", *COLORSPACES))
        _check_choice("alpha mode", alpha, ("auto", *ALPHA_MODES))
        _check_choice("nan mode", nan, options.NAN_POLICIES)
        self.path = p = os.fspath(path)
        check_input_file(p)
        self._stack = contextlib.ExitStack()
        name = self._name = self._stack.enter_context(_readable_name(p))
        self._inp, spec, fmt, self._subimage = _open_input(name, None, p)
        self._stack.callback(self._inp.close)
        self._spec = spec
        self.info = _describe(spec, fmt, p, colorspace, alpha)
        native = _type_name(spec.format)
        uniform = len({str(t) for t in spec.channelformats}) <= 1
        keep = ("uint8", "uint16", "half") if keep_half else ("uint8", "uint16")
        self._read_type = native if native in keep and uniform else "float"
        self.nan = nan
        self.nonfinite = 0
        self.shape = (spec.height, spec.width, spec.nchannels)
        probe = {"uint8": np.uint8, "uint16": np.uint16, "half": np.float16}.get(self._read_type, np.float32)
        self.dtype = _decode(np.zeros((1, 1, spec.nchannels), dtype=probe), self.info).dtype
        self._block: tuple[int, np.ndarray] | None = None  # a row of tiles, for tiled files
        self.on_stored = None  # called with each band's rows as stored, before decoding (mipmap's SHA-1)

    def __enter__(self) -> ImageStream:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self._stack.close()

    def _stored(self, y0: int, y1: int) -> np.ndarray:
        spec, inp = self._spec, self._inp
        if spec.tile_width > 0 and spec.tile_height > 0:  # whole rows of tiles, kept for the next band
            th = spec.tile_height
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
        data = inp.read_scanlines(self._subimage, 0, spec.y + y0, spec.y + y1, spec.z, 0, spec.nchannels,
                                  self._read_type)
        self._check(data)
        return np.asarray(data).reshape(y1 - y0, spec.width, spec.nchannels)

    def _check(self, data) -> None:
        err = self._inp.geterror() if self._inp.has_error else ""
        if data is None or err:
            err = (err or oiio.geterror()).replace(self._name, self.path)
            raise InputError(f"cannot read {self.path}: {_one_line(err, 'read failed')} (truncated or corrupt file?)")

    def read(self, y0: int, y1: int) -> np.ndarray:
        """Decoded rows ``y0 .. y1 − 1`` (0 is the top row), (rows, columns, channels)."""
        data = self._stored(y0, y1)
        if self.on_stored is not None:
            self.on_stored(data)
        if self._read_type == "half":
            data = np.asarray(data, dtype=np.float16)
        elif self._read_type == "float":
            data = np.asarray(data, dtype=np.float32)
        px = _decode(data, self.info)
        self.nonfinite += _apply_nan_policy(px, self.nan, self.info, self.path, y0,
                                            floats=self._read_type not in ("uint8", "uint16"))
        return px


def open_stream(path: str | os.PathLike[str], **options) -> ImageStream:
    """An :class:`ImageStream` of ``path`` (options as :func:`read_image`: colorspace, alpha, nan, keep_half)."""
    return ImageStream(os.fspath(path), **options)


def streams_to(path: str | os.PathLike[str]) -> bool:
    """Can :func:`stream_writer` write ``path`` band by band? (Formats encoded in memory cannot.)"""
    fmt = _format_from_path(os.fspath(path))
    return bool(fmt) and fmt not in _ENCODE_IN_MEMORY


def _quantum(tile_rows: int, dither: bool) -> int:
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
        self._out = None
        self._pending: list[np.ndarray] = []  # rows waiting for a whole row of tiles, or 8 rows of dither

    def write(self, y0: int, pixels: np.ndarray) -> None:
        """Linear pixels of rows ``y0 ..`` (in order: ``y0`` is the first row not handed over yet), encoded as
        :func:`write_image` encodes the whole picture (rows are grouped so that dithering and tiles line up)."""
        if y0 != self.next:
            raise ValueError(f"rows are written in order: row {self.next} expected, not {y0}")
        if not len(pixels):
            return
        self.next += len(pixels)
        self._pending.append(pixels)
        try:
            if self._out is None:
                self._open(_encode(self.path, Image(pixels[:1], self.info), **self.options)[0])
            self._flush(final=self.next >= self.height)
        except _WriteFailed as exc:
            raise OutputError(f"cannot write {self.path}: {str(exc).replace(self.tmp, self.path)}"
                              f"{_diagnosis(self.tmp)}") from None

    def _open(self, band_spec: oiio.ImageSpec) -> None:
        spec = band_spec
        spec.height = spec.full_height = self.height
        _set_windows(spec, self.info, spec.width, self.height)
        self._header(spec)
        out = oiio.ImageOutput.create(self.tmp)
        if out is None:
            raise _WriteFailed(_one_line(oiio.geterror(), "no writer for this format"))
        self._out = out
        _checked(out, out.open(self.tmp, spec, "Create"), "open")
        self.spec = spec

    def _header(self, spec: oiio.ImageSpec) -> None:
        """What a subclass adds to the file's header before it opens (nothing here)."""

    def _flush(self, final: bool) -> None:
        s = self.spec
        tiled = s.tile_width > 0 and s.tile_height > 0
        quantum = _quantum(s.tile_height if tiled else 1, self.options.get("dither", False))
        rows = self.next - self.written
        whole = rows if final else rows // quantum * quantum
        if not whole:
            return
        pixels = np.concatenate(self._pending) if len(self._pending) > 1 else self._pending[0]
        self._pending = [pixels[whole:]] if whole < rows else []
        data = _encode(self.path, Image(pixels[:whole], self.info), **self.options)[1]
        start = self.written
        if tiled:
            for a in range(0, whole, quantum):
                b = min(a + quantum, whole)
                ok = self._out.write_tiles(s.x, s.x + s.width, s.y + start + a, s.y + start + b, s.z, s.z + 1,
                                           np.ascontiguousarray(data[a:b]))
                _checked(self._out, ok, "write")
        else:
            _checked(self._out, self._out.write_scanlines(s.y + start, s.y + start + whole, s.z, data), "write")
        self.written += whole

    def finish(self) -> None:
        """Close the file and check it reads back (OutputError naming the user's path)."""
        if self.written != self.height:
            raise ValueError(f"{self.written} of {self.height} rows written")
        try:
            out, self._out = self._out, None
            _checked(out, out.close(), "close")
            _verify(self.tmp, self.fmt, [(self.spec, None)], "single")
        except _WriteFailed as exc:
            raise OutputError(f"cannot write {self.path}: {str(exc).replace(self.tmp, self.path)}"
                              f"{_diagnosis(self.tmp)}") from None

    def abort(self) -> None:
        if self._out is not None:
            with contextlib.suppress(Exception):
                self._out.close()
            self._out = None


@contextlib.contextmanager
def stream_writers(paths: list[str | os.PathLike[str]], infos: list[ImageInfo], shapes: list[tuple[int, int, int]],
                   *, pixel_type: str | None = None, colorspace: str | None = None, alpha: str | None = None,
                   dither: bool = False, compression: str | None = None, force: bool = False,
                   inputs: Iterable[str | os.PathLike[str]] = ()):
    """Several images written band by band, all or nothing (:func:`write_images`' guarantee): one
    :class:`BandWriter` per path on a hidden temporary beside it.

    Each file is encoded as :func:`write_image` encodes it (same options, same pixels); they are renamed onto
    their paths only when every row of every file is written and each reads back; any failure or interruption
    removes the temporaries and leaves what was at the paths untouched
    (:func:`pyramid_cli.imageio.atomic.atomic_paths`).
    """
    out_paths = [os.fspath(p) for p in paths]
    opts = {"pixel_type": pixel_type, "colorspace": colorspace, "alpha": alpha, "dither": dither,
            "compression": compression, "force": force, "inputs": tuple(inputs)}
    fmts = [_check_band_output(p, opts) for p in out_paths]
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


def _check_band_output(path: str, opts: dict) -> str:
    """The format of ``path``, refused before any work as :func:`write_image` refuses it, or when its format
    is encoded whole (it cannot be written band by band)."""
    fmt = _check_output_path(path, opts["force"], opts["inputs"])
    check_write_options(path, opts["pixel_type"], opts["compression"])
    if not streams_to(path):
        raise OutputError(f"cannot write {path} band by band: {_FORMAT_TITLES.get(fmt, fmt)} is encoded whole")
    return fmt


@contextlib.contextmanager
def stream_writer(path: str | os.PathLike[str], info: ImageInfo, shape: tuple[int, int, int], **options):
    """One image written band by band, atomically (:func:`stream_writers` of one path): yields its
    :class:`BandWriter`. Options as :func:`write_image`."""
    with stream_writers([path], [info], [shape], **options) as (writer,):
        yield writer


def encoded_rows(path: str | os.PathLike[str], image: Image, **options) -> np.ndarray:
    """The values :func:`write_image` would store for ``image`` at ``path`` (a band of rows: dithering lines up
    when the band starts at a multiple of 8 rows), e.g. for a streamed texture's ``oiio:AverageColor``."""
    return _encode(os.fspath(path), image, **options)[1]


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

    def append_level(self, rows) -> None:
        """The next level (1, 2, …): ``rows(r0, r1)`` gives its linear pixels, a row of tiles at a time."""
        if self.written != self.height:
            raise ValueError(f"level 0: {self.written} of {self.height} rows written")
        self.levels = max(self.levels, 1) + 1
        h, w, _ = self.shapes[self.levels - 1]
        step = _quantum(self.tile, self.options.get("dither", False))
        try:
            spec = None
            for r0 in range(0, h, step):
                r1 = min(h, r0 + step)
                spec_k, data = _encode(self.path, Image(rows(r0, r1), self.info), **self.options)
                if spec is None:
                    spec = spec_k
                    spec.height = spec.full_height = h
                    _set_windows(spec, self.info, w, h)
                    _mark_mip_level(spec, self.fmt, self.tile, self.round_up, self.options.get("compression"))
                    append = "AppendMIPLevel" if self._out.supports("mipmap") else "AppendSubimage"
                    _checked(self._out, self._out.open(self.tmp, spec, append), "open")
                for a in range(0, r1 - r0, self.tile):
                    b = min(a + self.tile, r1 - r0)
                    ok = self._out.write_tiles(spec.x, spec.x + w, spec.y + r0 + a, spec.y + r0 + b, spec.z,
                                               spec.z + 1, np.ascontiguousarray(data[a:b]))
                    _checked(self._out, ok, "write")
        except _WriteFailed as exc:
            raise OutputError(f"cannot write {self.path}: {str(exc).replace(self.tmp, self.path)}"
                              f"{_diagnosis(self.tmp)}") from None

    def finish(self) -> None:
        """Close the file and check it reads back with every level (OutputError naming the user's path)."""
        if self.written != self.height or max(self.levels, 1) != len(self.shapes):
            raise ValueError(f"{max(self.levels, 1) if self.written == self.height else 0} of {len(self.shapes)} "
                             "MIP levels written")
        try:
            out, self._out = self._out, None
            _checked(out, out.close(), "close")
            _verify(self.tmp, self.fmt, [(self.spec, None)] * len(self.shapes), "mipmap")
        except _WriteFailed as exc:
            raise OutputError(f"cannot write {self.path}: {str(exc).replace(self.tmp, self.path)}"
                              f"{_diagnosis(self.tmp)}") from None


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
    fmt = _check_band_output(out_path, opts)
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
