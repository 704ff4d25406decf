"""Raw reads for ``pyramid diff``: stored values, every subimage and MIP level.

This module is part of the I/O layer, :mod:`pyramid_cli.imageio`, the only package that
imports OpenImageIO. :mod:`pyramid_cli.imageio.read` reads images
into linear, premultiplied light for filtering; ``pyramid diff`` compares files
the way OpenImageIO's ``idiff`` does, which needs what the file stores:

* integer files (8/16/32-bit) as code values scaled to 0-1 (``code / 255``,
  ``code / 65535``), with no sRGB decoding, which is what ``idiff`` reads
  (OpenImageIO's conversion to float; straight-alpha PNG and TIFF colour is
  premultiplied by OpenImageIO on read, in the stored encoding, as in idiff);
* half and float files as stored;
* every subimage (EXR part) and every MIP level, for ``idiff -a``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import OpenImageIO as oiio

from pyramid_cli.core.errors import InputError
from pyramid_cli.imageio.formats import cut_png
from pyramid_cli.imageio.write import write_spec

__all__ = ["RawLevel", "count_levels", "image_extensions", "read_level", "write_display_png", "write_float"]


@dataclass(frozen=True)
class RawLevel:
    """One subimage at one MIP level, as stored.

    Attributes
    ----------
    pixels : numpy.ndarray
        float32 ``(H, W, C)``; integer code values divided by their maximum.
    channel_names : list of str
    pixel_type : str
        The stored type: ``"uint8"``, ``"uint16"``, ``"half"``, ``"float"``...
    subimage, miplevel : int
    """

    pixels: np.ndarray
    channel_names: list[str]
    pixel_type: str
    subimage: int
    miplevel: int


def _one_line(text: str, fallback: str) -> str:
    lines = [s.strip() for s in str(text).splitlines() if s.strip()]
    return lines[-1] if lines else fallback


def _open(path: str) -> oiio.ImageInput:
    if not os.path.lexists(path):
        raise InputError(f"cannot read {path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"cannot read {path}: it is a directory")
    try:
        # No "oiio:UnassociatedAlpha" hint: like idiff, take OpenImageIO's default read, which
        # premultiplies straight-alpha files (PNG, TIFF) by their alpha in the stored encoding.
        inp = oiio.ImageInput.open(path)
    except Exception as exc:  # binding errors become one line
        raise InputError(f"cannot read {path}: {_one_line(str(exc), 'open failed')}") from None
    if inp is None:
        raise InputError(f"cannot read {path}: {_one_line(oiio.geterror(), 'not an image OpenImageIO can read')}")
    cut = cut_png(str(inp.format_name()), path, path)
    if cut is not None:
        inp.close()
        raise cut
    return inp


def image_extensions() -> frozenset[str]:
    """File extensions (lower case, no dot) that OpenImageIO reads as images."""
    found: set[str] = set()
    for entry in oiio.get_string_attribute("extension_list").split(";"):
        fmt, _, exts = entry.partition(":")
        if fmt in ("null", "term"):
            continue
        found.update(e.lower() for e in exts.split(",") if e)
    return frozenset(found)


def count_levels(path: str) -> list[int]:
    """The number of MIP levels of each subimage of ``path``.

    Parameters
    ----------
    path : str
        Any file OpenImageIO can read.

    Returns
    -------
    list of int
        One entry per subimage (its MIP level count, at least 1).

    Raises
    ------
    InputError
        Missing, unreadable or corrupt file.
    """
    inp = _open(path)
    try:
        counts = []
        sub = 0
        while inp.seek_subimage(sub, 0):
            m = 1
            while inp.seek_subimage(sub, m):
                m += 1
            counts.append(m)
            sub += 1
        return counts or [1]
    finally:
        inp.close()


def read_level(path: str, subimage: int = 0, miplevel: int = 0) -> RawLevel:
    """Read one subimage and MIP level of ``path`` as stored (see the module notes).

    Parameters
    ----------
    path : str
        Any file OpenImageIO can read.
    subimage, miplevel : int
        Which part and level (0, 0: the first image of the file).

    Returns
    -------
    RawLevel

    Raises
    ------
    InputError
        Missing, unreadable, truncated or corrupt file; deep or volume data; no such
        subimage or level.
    """
    inp = _open(path)
    try:
        if not inp.seek_subimage(subimage, miplevel):
            raise InputError(f"cannot read {path}: it has no subimage {subimage} MIP level {miplevel}")
        spec = inp.spec()
        if spec.deep:
            raise InputError(f"cannot read {path}: deep images are not supported")
        if spec.depth > 1:
            raise InputError(f"cannot read {path}: volume images are not supported")
        if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
            raise InputError(f"cannot read {path}: zero-size image")
        try:
            data = inp.read_image(subimage, miplevel, 0, spec.nchannels, "float")
            err = inp.geterror() if inp.has_error else ""
        except Exception as exc:
            data, err = None, str(exc)
        if data is None or err:
            msg = _one_line(err or oiio.geterror(), "read failed")
            raise InputError(f"cannot read {path}: {msg} (truncated or corrupt file?)")
        names = list(spec.channelnames) or [f"c{i}" for i in range(spec.nchannels)]
        pixels = np.asarray(data, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
        return RawLevel(pixels=pixels, channel_names=names, pixel_type=str(spec.format),
                        subimage=subimage, miplevel=miplevel)
    finally:
        inp.close()


def _write(path: str, spec: oiio.ImageSpec, pixels: np.ndarray) -> None:
    write_spec(path, spec, pixels)  # every write is checked in one place (a lying PNG writer, a full disk)


def write_float(path: str, pixels: np.ndarray, channel_names: list[str]) -> None:
    """Write float32 ``pixels`` (``(H, W, C)``) to ``path`` atomically, as idiff's ``-o`` does.

    Formats that hold floats (EXR, TIFF, HDR) store them as float; others (PNG,
    JPEG) store the values clamped to 0-1 as code values, without sRGB encoding.

    Raises
    ------
    OutputError
        The file cannot be written.
    """
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, "float")
    spec.channelnames = tuple(channel_names[:c]) if len(channel_names) >= c else tuple(f"c{i}" for i in range(c))
    _write(path, spec, pixels.astype(np.float32))


def write_display_png(path: str, display: np.ndarray) -> None:
    """Write display colours in [0, 1] (``(H, W, 1|3|4)``, already encoded for the
    screen) to an 8-bit PNG, atomically.

    Raises
    ------
    OutputError
        The file cannot be written.
    """
    h, w, c = display.shape
    codes = np.clip(np.rint(np.nan_to_num(display, nan=0.0) * 255.0), 0, 255).astype(np.uint8)
    spec = oiio.ImageSpec(w, h, c, "uint8")
    _write(path, spec, codes)
