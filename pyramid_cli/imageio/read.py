"""Decoding image files into linear premultiplied pixels, and refusing what cannot be read.

Input safety first (:func:`check_input_file`: no FIFO, device or folder is ever opened), then the stored
values are decoded by the rules of :mod:`pyramid_cli.imageio` (colour encoding, alpha, NaN policy).
"""

from __future__ import annotations

import contextlib
import os
import stat
from typing import Any

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core import options
from pyramid_cli.core.errors import DataError, InputError
from pyramid_cli.core.geometry import halved
from pyramid_cli.imageio.atomic import is_utf8
from pyramid_cli.imageio.colour import (
    colour_mask,
    count_nonfinite,
    decode_integer,
    integer_table,
    premultiply,
    srgb_to_linear,
    unpremultiply,
)
from pyramid_cli.imageio.formats import (
    ALPHA_MODES,
    check_choice,
    cut_png,
    one_line,
    pixel_type_name,
)
from pyramid_cli.imageio.image import ALPHA_NAMES, Image, ImageInfo, default_channel_names
from pyramid_cli.imageio.ocio import check_names, convert, input_space, kind, working_space


def _find_alpha(spec: oiio.ImageSpec, names: list[str]) -> int:
    if 0 <= spec.alpha_channel < spec.nchannels:
        return int(spec.alpha_channel)
    for i, name in enumerate(names):
        if name in ALPHA_NAMES:
            return i
    return -1


def read_image(path: str | os.PathLike[str], *, colorspace: str = "auto",
               alpha: str = "auto", nan: str = "keep", subimage: int | None = None,
               keep_half: bool = False, hash_source: bool = False, colorconfig: str | None = None) -> Image:
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
    colorspace : str
        The colour space of the stored values: any name the colour config
        resolves (a space, alias or role; ``"linear"`` and ``"srgb"`` are the
        Rec.709 pair), or ``"auto"``: the ``oiio:ColorSpace`` metadata, then
        the config's file rules, then the pixel type (integer: sRGB,
        half/float: linear). Pixels come back in linear light
        (:func:`pyramid_cli.imageio.ocio.working_space`); data spaces as stored.
    colorconfig : str, optional
        An OpenColorIO config file; default ``$OCIO``, else OpenImageIO's
        built-in config.
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
        An unknown ``colorspace``, ``alpha`` or ``nan`` value, or a colour
        config that does not load.
    """
    check_names(colorspace, colorconfig=colorconfig)
    check_choice("alpha mode", alpha, ("auto", *ALPHA_MODES))
    check_choice("nan mode", nan, options.NAN_POLICIES)
    p = os.fspath(path)

    check_input_file(p)
    with readable_name(p) as name:
        data, spec, fmt = _read_pixels(name, subimage, keep_half, shown=p)
    pixel_hash = None
    if hash_source:  # before the conversions below, some of which work in place
        from pyramid_cli.workflows.mip import sha1_state

        pixel_hash = sha1_state(data)
    info = describe_spec(spec, fmt, p, colorspace, alpha, pixel_hash, colorconfig)
    pixels = decode_stored(data, info)
    bad = apply_nan_policy(pixels, nan, info, p, floats=data.dtype.kind == "f")
    return Image(pixels=pixels, spec=info, nonfinite=bad if nan == "keep" else 0)


def describe_spec(spec: oiio.ImageSpec, fmt: str, p: str, colorspace: str, alpha: str,
              pixel_hash: Any = None, colorconfig: str | None = None) -> ImageInfo:
    """What :func:`read_image` says of a file from its header (the encoding and alpha mode it decodes by)."""
    names = [str(n) for n in spec.channelnames] or default_channel_names(spec.nchannels)
    pixel_type = pixel_type_name(spec.format)
    alpha_channel = _find_alpha(spec, names)

    attributes: dict[str, Any] = {}
    attribute_types: dict[str, str] = {}
    for attr in spec.extra_attribs:
        attributes[attr.name] = attr.value
        attribute_types[attr.name] = str(attr.type)

    encoding, source = input_space(attributes.get("oiio:ColorSpace"), p, pixel_type in ("uint8", "uint16"),
                                   colorspace, colorconfig)

    if alpha_channel < 0:
        alpha_mode = "none"
    elif alpha == "auto":
        unassociated = spec.get_int_attribute("oiio:UnassociatedAlpha", 0)
        alpha_mode = "straight" if unassociated else "premultiplied"
    else:
        alpha_mode = alpha

    channel_types = [pixel_type_name(t) for t in spec.channelformats]
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
        linear_space=working_space(encoding, colorconfig),
        colorconfig=colorconfig,
        colorspace_source=source,
    )


def decode_stored(px: np.ndarray, info: ImageInfo) -> np.ndarray:
    """Stored values (as :func:`_read_pixels` returns them) → linear premultiplied float32 (or kept half).

    Pixel by pixel: a band of rows decodes exactly as the whole image does."""
    alpha_channel, alpha_mode = info.alpha_channel, info.alpha_mode
    colour = colour_mask(px.shape[2], alpha_channel, info.channel_names)
    has_alpha = alpha_channel >= 0 and alpha_mode != "none"
    # "srgb": the exact sRGB tables; "ocio": the config converts to the linear space filtered in
    how = decoding(info)
    if px.dtype in (np.uint8, np.uint16):
        if how != "ocio":
            return decode_integer(px, how == "srgb", colour, alpha_channel if has_alpha else -1,
                                  alpha_mode == "straight")
        px = decode_integer(px, False, colour, -1, False)  # code / max, converted below
    if px.dtype == np.float16 and (how != "none" or has_alpha and alpha_mode == "straight"):
        px = px.astype(np.float32)  # converted below: not in half precision
    if how != "none":
        if has_alpha and alpha_mode == "premultiplied":
            # The file premultiplied the encoded values: divide them back out
            # before decoding, premultiply again in linear light below.
            unpremultiply(px, alpha_channel, colour)
        if how == "srgb":
            px[..., colour] = srgb_to_linear(px[..., colour])
        else:
            px[..., colour] = convert(px[..., colour], info.colorspace, info.linear_space, info.colorconfig)
        if has_alpha:
            premultiply(px, alpha_channel, colour)
    elif has_alpha and alpha_mode == "straight":
        premultiply(px, alpha_channel, colour)
    return px if px.dtype == np.float16 else px.astype(np.float32, copy=False)


def code_table(info: ImageInfo, dtype, channels: int) -> np.ndarray | None:
    """The float32 value of every code of ``dtype`` when :func:`decode_stored` decodes rows of ``channels``
    channels code by code through one table: 8- or 16-bit codes of sRGB or linear light (or data), every channel
    colour, no alpha to premultiply. ``table[codes]`` is then exactly the decoded rows, so a consumer may keep
    the codes (a quarter or half the bytes) and read them through the table itself; None otherwise."""
    dtype = np.dtype(dtype)
    if dtype not in (np.uint8, np.uint16) or info.alpha_channel >= 0 and info.alpha_mode != "none":
        return None
    how = decoding(info)
    if how == "ocio" or not all(colour_mask(channels, info.alpha_channel, info.channel_names)):
        return None
    return integer_table(dtype.name, how == "srgb")


def decoding(info: ImageInfo) -> str:
    """How stored values become linear: ``"none"``, ``"srgb"`` (the exact tables) or ``"ocio"``."""
    if info.colorspace == info.linear_space:
        return "none"
    if info.colorspace == "srgb" and info.linear_space == "linear":
        return "srgb"
    return "none" if kind(info.colorspace, info.colorconfig) == "data" else "ocio"


def apply_nan_policy(pixels: np.ndarray, nan: str, info: ImageInfo, p: str, row: int = 0,
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
def readable_name(p: str):
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
    with readable_name(p) as name:
        inp = oiio.ImageInput.open(name)
        if inp is None:
            raise InputError(f"cannot read {p}: {one_line(oiio.geterror(), 'open failed')}")
        try:
            return len(_part_names(inp))
        finally:
            inp.close()


def _part_names(inp) -> list[str]:
    """The name of every subimage of an open file (``part k`` where it has none); leaves it at subimage 0."""
    names: list[str] = []
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
        want = halved((h, w))
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


def open_input(name: str, subimage: int | None, p: str):
    """An open ImageInput positioned on one checked subimage: ``(input, spec, format name, subimage)``.

    ``subimage`` None refuses a multi-part file; InputError (naming ``p``) for what cannot be read."""
    config = oiio.ImageSpec()
    # Ask for the stored values: without this hint OpenImageIO premultiplies
    # straight-alpha files itself, in the encoded (non-linear) space.
    config.attribute("oiio:UnassociatedAlpha", 1)
    try:
        inp = oiio.ImageInput.open(name, config)
    except Exception as exc:  # binding errors become one line
        raise InputError(f"cannot read {p}: {one_line(str(exc), 'open failed')}") from None
    if inp is None:
        msg = one_line(oiio.geterror().replace(name, p), "not an image file OpenImageIO can read")
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
        cut = cut_png(fmt, name, p)
        if cut is not None:
            raise cut
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
    inp, spec, fmt, subimage = open_input(name, subimage, p)
    try:
        native = pixel_type_name(spec.format)
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
            msg = one_line(err, "read failed")
            raise InputError(f"cannot read {p}: {msg} (truncated or corrupt file?)")
    finally:
        inp.close()
    data = np.asarray(data).reshape(spec.height, spec.width, spec.nchannels)
    if read_type in ("uint8", "uint16"):
        return data, spec, fmt  # decoded by decode_integer
    if read_type == "half":
        return np.asarray(data, dtype=np.float16), spec, fmt
    return np.asarray(data, dtype=np.float32), spec, fmt  # float files stay float32: no 2× copy
