"""The image model: linear pixels (:class:`Image`) and how their file stored them (:class:`ImageInfo`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio.formats import format_from_path

# Channel names taken for alpha when a file does not say which channel it is.
ALPHA_NAMES = ("A", "a", "alpha", "Alpha", "ALPHA")

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
        The colour space of the stored values: ``"linear"`` or ``"srgb"`` for the Rec.709 pair, else the
        colour config's name (:mod:`pyramid_cli.imageio.ocio`).
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
    linear_space : str
        The linear space :attr:`Image.pixels` are in (``"linear"``: linear Rec.709; data stays as stored).
    colorconfig : str or None
        The OpenColorIO config the names belong to (None: ``$OCIO``, else OpenImageIO's built-in one).
    colorspace_source : str
        How the input's space was found: ``"option"``, ``"metadata"``, ``"file rule"`` or ``"default"``.
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
    linear_space: str = "linear"
    colorconfig: str | None = None
    colorspace_source: str = ""


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
    nonfinite : int
        NaN and infinite values :func:`~pyramid_cli.imageio.read_image` kept in :attr:`pixels` (``nan="keep"``),
        counted as it read them; 0 for pixels made otherwise.
    """

    pixels: np.ndarray
    spec: ImageInfo
    nonfinite: int = field(default=0, compare=False)

    @property
    def premultiplied(self) -> bool:
        """Whether colour channels in :attr:`pixels` are multiplied by alpha."""
        return self.spec.alpha_channel >= 0 and self.spec.alpha_mode != "none"


def default_channel_names(nchannels: int) -> list[str]:
    """Channel names for a count without names: Y, YA, RGB, RGBA, else channel0, channel1, …"""
    return {1: ["Y"], 2: ["Y", "A"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}.get(
        nchannels, [f"channel{i}" for i in range(nchannels)])


def info_for_array(path: str | os.PathLike[str], nchannels: int, channel_names: list[str] | None = None) -> ImageInfo:
    """How to store linear float pixels that came from no file: named by channel count (Y, YA, RGB,
    RGBA), alpha (a channel named A) taken as premultiplied, as :func:`~pyramid_cli.imageio.read.read_image`
    returns it."""
    names = list(channel_names) if channel_names else default_channel_names(nchannels)
    if len(names) != nchannels:
        raise UsageError(f"{len(names)} channel names for {nchannels} channels")
    alpha = next((i for i, n in enumerate(names) if n in ALPHA_NAMES), -1)
    p = os.fspath(path)
    return ImageInfo(path=p, format=format_from_path(p), pixel_type="float", channel_names=names,
                     alpha_channel=alpha, colorspace="linear", alpha_mode="premultiplied" if alpha >= 0 else "none")


def describe_rules(info: ImageInfo) -> str:
    """One line saying which colour and alpha rule is in force for ``info``
    (:func:`~pyramid_cli.imageio.encode.describe_output` says an output's).

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
    from pyramid_cli.imageio.ocio import describe

    found = f" ({info.colorspace_source})" if info.colorspace_source else ""
    if info.colorspace == "srgb":
        colour = f"sRGB-encoded{found}: decoded with the sRGB EOTF to linear light"
    elif info.colorspace == info.linear_space:
        colour = f"{describe(info.colorspace, info.colorspace_source, info.colorconfig)}: linear light, no decoding"
    else:
        colour = (f"{describe(info.colorspace, info.colorspace_source, info.colorconfig)}: converted to "
                  f"{describe(info.linear_space, '', info.colorconfig)} by the colour config")
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
