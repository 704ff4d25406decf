"""The formats OpenImageIO writes and what each can store: pixel types, alpha, compression, tiles.

The tables every reader and writer of :mod:`pyramid_cli.imageio` consults, and the small helpers that name
things the way OpenImageIO does (format names from extensions, pixel type names).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable

import OpenImageIO as oiio

from pyramid_cli.core import options
from pyramid_cli.core.errors import InputError, UsageError

PIXEL_TYPES = options.PIXEL_TYPES
ALPHA_MODES = options.STORED_ALPHA

# Pixel types each format can store, for the formats that cannot store all
# four. Formats not listed are assumed to store any of them.
FORMAT_TYPES: dict[str, tuple[str, ...]] = {
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

# Formats whose OpenImageIO writer stores a half request as 32-bit float unless told: TIFF writes half only under
# its "tiff:half" hint. Most TIFF readers do not take half, so a half input is written as float, and half only when
# asked (--type half: the hint is given).
HALF_AS_FLOAT = ("tiff",)

# Formats that can store premultiplied (associated) alpha; all others store
# straight alpha only.
ASSOCIATED_CAPABLE = ("openexr", "tiff")

# Formats that hold no alpha channel at all: alpha is dropped on write, which
# leaves the premultiplied colour, i.e. the image composited over black.
NO_ALPHA_FORMATS = ("jpeg", "hdr")

# --compression values each format honours (OpenImageIO writes anything else as its default
# without a word, so anything else is refused). ``name:N`` sets a level or quality.
COMPRESSIONS: dict[str, tuple[str, ...]] = {
    "openexr": ("none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"),
    "tiff": ("none", "lzw", "zip", "packbits", "ccittrle"),
}
COMPRESSION_LEVELS = frozenset({"zip", "zips", "dwaa", "dwab", "lzw"})

# Formats whose OpenImageIO writer ends the whole process on a write error (libjpeg's default
# error handler calls exit()): they are encoded into memory first and copied to the file with
# os.write, which reports a full disk as an error.
ENCODE_IN_MEMORY = frozenset({"jpeg"})

# The row filters libpng may choose from for each PNG row (its PNG_FILTER_NONE | SUB | UP; the ``png:filter``
# hint of OpenImageIO's PNG writer, whose default lets libpng try all five). Measured at zlib level 6 on five
# pictures (a 4K crop of a photograph, a blurred 4K picture, 4K noise, a zone plate, an RGBA gradient): the files
# as small or smaller (the noise's 2.7 % larger), the writes 20-35 % faster (the photograph 5.05 -> 3.92 s, the
# blurred picture 1.00 -> 0.75 s); libvips writes with no filter (a third of the time, files 1.7x larger).
PNG_FILTERS = 0x08 | 0x10 | 0x20

# libpng's row filters by libvips's names for them (``pngsave``'s ``filter``), for ``--compression LEVEL:FILTERS``.
PNG_FILTER_NAMES = {"none": 0x08, "sub": 0x10, "up": 0x20, "avg": 0x40, "paeth": 0x80, "all": 0xF8}


def png_compression(text: str) -> tuple[int, int]:
    """A PNG's ``--compression``: ``LEVEL`` (zlib 0-9; rows filtered as :data:`PNG_FILTERS`) or ``LEVEL:FILTERS``,
    the row filters libpng may choose from, by :data:`PNG_FILTER_NAMES` joined with ``+`` (``6:none``: no filter,
    as libvips writes by default; ``9:all``: every filter, as OpenImageIO does). ``(level, png:filter bits)``;
    ValueError for anything else.

    No filter writes a smooth picture in about a quarter of the time, into a file about twice as large: a blurred
    4K picture at level 6 took 0.23 s for 4.0 MB, against 0.75 s for 2.1 MB with :data:`PNG_FILTERS` and 0.93 s
    for 2.3 MB with all five (docs/performance.md, "PNG row filters")."""
    level, colon, names = text.strip().lower().partition(":")
    if not (level.isdigit() and 0 <= int(level) <= 9) or (colon and not names):
        raise ValueError(text)
    bits = 0
    for name in names.split("+") if colon else ():
        if name not in PNG_FILTER_NAMES:
            raise ValueError(text)
        bits |= PNG_FILTER_NAMES[name]
    return int(level), bits or PNG_FILTERS

PNG_TAIL = 4096   # bytes at a PNG's end searched for its IEND chunk before its chunks are walked


def png_ends(path: str | os.PathLike[str]) -> bool:
    """Whether the PNG file ``path`` holds its closing IEND chunk, i.e. was not cut short.

    libpng reports a PNG that ends early on standard error itself ("libpng error: IDAT: Read error …"),
    from OpenImageIO's reader, before the read fails; a reader that checks first says it in one line. IEND is
    the last chunk: it is searched for in the file's last :data:`PNG_TAIL` bytes, and only where it is not there
    (a file cut short, or one with more than that after its IEND) are the chunks walked from the start
    (a length and a type each, then the data and a CRC skipped). An IEND without its CRC, or a file too short
    for all that, says False."""
    with open(path, "rb") as f:
        size = f.seek(0, os.SEEK_END)
        f.seek(max(0, size - PNG_TAIL))
        tail = f.read()
        if 0 <= tail.rfind(b"IEND") <= len(tail) - 8:  # the type, then its CRC
            return True
        at = 8  # the signature
        while at + 12 <= size:
            f.seek(at)
            head = f.read(8)
            if head[4:] == b"IEND":
                return True
            at += 12 + int.from_bytes(head[:4], "big")
        return False


def cut_png(fmt: str, path: str | os.PathLike[str], shown: str) -> InputError | None:
    """The error that refuses an input of format ``fmt`` at ``path`` (named ``shown``) when it is a PNG that was
    cut short (:func:`png_ends`), before anything decodes it; else None."""
    if fmt != "png" or png_ends(path):
        return None
    return InputError(f"cannot read {shown}: the PNG ends before its last chunk (IEND): truncated file?")


# Formats that can be tiled: a tiled input is written back tiled.
TILED_FORMATS = ("openexr", "tiff")

_FORMAT_TITLES = {"openexr": "OpenEXR", "png": "PNG", "jpeg": "JPEG", "tiff": "TIFF", "hdr": "HDR"}


def format_title(fmt: str) -> str:
    """How messages name a format: ``"OpenEXR"`` for ``"openexr"``, the OpenImageIO name where it has no title."""
    return _FORMAT_TITLES.get(fmt, fmt)


def one_line(message: str, fallback: str) -> str:
    """The first non-blank line of an OpenImageIO message, ``fallback`` when there is none."""
    lines = [ln.strip() for ln in str(message).splitlines() if ln.strip()]
    return lines[0] if lines else fallback


def check_choice(name: str, value: str, choices: Iterable[str]) -> None:
    """Refuse (UsageError) a ``value`` of option ``name`` that is not one of ``choices``."""
    choices = tuple(choices)
    if value not in choices:
        raise UsageError(f"bad {name} {value!r}: expected one of {', '.join(choices)}")


def pixel_type_name(t: oiio.TypeDesc) -> str:
    """``"uint8"``, ``"uint16"``, ``"half"`` or ``"float"`` for an OpenImageIO type (any other type: ``"float"``)."""
    base = t.basetype
    if base == oiio.UINT8:
        return "uint8"
    if base == oiio.UINT16:
        return "uint16"
    if base == oiio.HALF:
        return "half"
    return "float"


def format_from_path(path: str) -> str:
    """The OpenImageIO format name of ``path``'s extension (``"openexr"`` for ``.exr``), ``""`` if unknown."""
    return _format_of_extension(os.path.splitext(path)[1].lower().lstrip("."))


@functools.lru_cache(maxsize=64)  # the tile writers ask for every band and tile: parse OIIO's list once per extension
def _format_of_extension(ext: str) -> str:
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
    allowed = FORMAT_TYPES.get(fmt)
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


def oiio_version() -> str:
    """The OpenImageIO version writing the files, e.g. ``"3.2.2.0"``."""
    return str(oiio.__version__)
