"""Reading and writing images with OpenImageIO, in linear premultiplied light.

Everything the rest of the tool filters is an :class:`Image`: float32 pixels (or,
when asked, a half file's own float16 values) of shape ``(H, W, C)`` (row 0 is
the top row of the file, nothing is ever flipped) in linear light, with colour
premultiplied by alpha when the image has an alpha channel, plus an
:class:`ImageInfo` that remembers how the file stored them so that
:func:`write_image` can store the result the same way.

Rules
-----
Colour spaces
    Named by OpenColorIO (:mod:`~pyramid_cli.imageio.ocio`): a file is in the
    space its ``oiio:ColorSpace`` names, else the one the config's file rules
    give, else sRGB (8/16-bit integers) or linear Rec.709 (half/float). Pixels
    are filtered in linear light, converted by the config's own transforms on
    colour channels only, never on alpha; the sRGB curve on Rec.709 is
    decoded and encoded by exact tables (the piecewise sRGB EOTF, not a 2.2
    power). Data spaces are filtered as stored. An output is stored in the
    input's space when its format holds it, else in what the format
    conventionally holds, and labelled with the space its pixels are in.
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

Modules
-------
:mod:`~pyramid_cli.imageio.formats` (what each format stores), :mod:`~pyramid_cli.imageio.image` (the image
model), :mod:`~pyramid_cli.imageio.colour` (sRGB, premultiplication, 8/16-bit codes),
:mod:`~pyramid_cli.imageio.ocio` (colour spaces through the OpenColorIO config),
:mod:`~pyramid_cli.imageio.read` (decoding and input safety), :mod:`~pyramid_cli.imageio.encode` (the
encoding rules), :mod:`~pyramid_cli.imageio.write` (the checked writer), :mod:`~pyramid_cli.imageio.atomic`
(atomic replacement), :mod:`~pyramid_cli.imageio.texture` (MIP-mapped textures and multi-part files),
:mod:`~pyramid_cli.imageio.bands` (a band of rows at a time), :mod:`~pyramid_cli.imageio.codecs` (OpenEXR's
codec threads and their memory), :mod:`~pyramid_cli.imageio.raw` (stored values
for ``pyramid diff``). This package re-exports their public API, each name loaded from its module on
first use (PEP 562), so that ``pyramid diff`` of two files loads neither the band streams nor the texture
writer, and ``import pyramid_cli.imageio.raw`` only what it needs.
"""


from __future__ import annotations

import os
from importlib import import_module
from typing import TYPE_CHECKING

from pyramid_cli.core.machine import usable_cores

# OpenImageIO sizes its thread pools (OpenEXR's codec threads among them) from the host's cores when it loads,
# which no module has done yet: it reads OPENIMAGEIO_THREADS then. A process whose affinity or cgroup CPU quota
# (a container's --cpus) allows fewer cores gets pools of that many threads (its children, in the same cgroup,
# inherit the setting); one the user set is kept, and elsewhere the environment is left alone.
_cores = usable_cores()
if _cores < (os.cpu_count() or 1):
    os.environ.setdefault("OPENIMAGEIO_THREADS", str(_cores))
del _cores

if TYPE_CHECKING:  # what each name is, for readers and checkers; loaded on first use below
    from pyramid_cli.core.geometry import check_size
    from pyramid_cli.imageio.atomic import ensure_output_dir
    from pyramid_cli.imageio.bands import (
        BandWriter,
        ImageStream,
        open_stream,
        output_codec_memory,
        stream_writer,
        stream_writers,
        streams_to,
    )
    from pyramid_cli.imageio.codecs import exr_threads, limited_exr_threads
    from pyramid_cli.imageio.colour import count_nonfinite, linear_to_srgb, srgb_to_linear
    from pyramid_cli.imageio.encode import (
        Encoder,
        check_write_options,
        describe_output,
        encoded_rows,
        pixels_in,
        stores_half_unchanged,
    )
    from pyramid_cli.imageio.formats import oiio_version, output_pixel_type
    from pyramid_cli.imageio.image import Image, ImageInfo, describe_rules, info_for_array
    from pyramid_cli.imageio.ocio import check_names as check_colorspaces
    from pyramid_cli.imageio.read import (
        check_input_file,
        check_pyramid,
        check_same_channels,
        count_parts,
        read_image,
        read_parts,
        read_shape,
    )
    from pyramid_cli.imageio.texture import MipBandWriter, mip_stream_writer, source_sha1, write_levels
    from pyramid_cli.imageio.write import write_image, write_images, write_spec

# name → its module
_HOMES = {
    "check_size": "pyramid_cli.core.geometry",
    "ensure_output_dir": "pyramid_cli.imageio.atomic",
    **dict.fromkeys(["BandWriter", "ImageStream", "open_stream", "output_codec_memory", "stream_writer",
                     "stream_writers", "streams_to"], "pyramid_cli.imageio.bands"),
    **dict.fromkeys(["exr_threads", "limited_exr_threads"], "pyramid_cli.imageio.codecs"),
    **dict.fromkeys(["count_nonfinite", "linear_to_srgb", "srgb_to_linear"], "pyramid_cli.imageio.colour"),
    **dict.fromkeys(["Encoder", "check_write_options", "describe_output", "encoded_rows", "pixels_in",
                     "stores_half_unchanged"], "pyramid_cli.imageio.encode"),
    **dict.fromkeys(["oiio_version", "output_pixel_type"], "pyramid_cli.imageio.formats"),
    **dict.fromkeys(["Image", "ImageInfo", "describe_rules", "info_for_array"], "pyramid_cli.imageio.image"),
    "check_colorspaces": "pyramid_cli.imageio.ocio",
    **dict.fromkeys(["check_input_file", "check_pyramid", "check_same_channels", "count_parts", "read_image",
                     "read_parts", "read_shape"], "pyramid_cli.imageio.read"),
    **dict.fromkeys(["MipBandWriter", "mip_stream_writer", "source_sha1", "write_levels"],
                    "pyramid_cli.imageio.texture"),
    **dict.fromkeys(["write_image", "write_images", "write_spec"], "pyramid_cli.imageio.write"),
}


_ALIASES = {"check_colorspaces": "check_names"}  # exported under another name than its module's


def __getattr__(name: str):
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(home), _ALIASES.get(name, name))
    globals()[name] = value  # found directly from now on
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})


__all__ = [
    "BandWriter",
    "Encoder",
    "Image",
    "ImageInfo",
    "ImageStream",
    "MipBandWriter",
    "check_colorspaces",
    "check_input_file",
    "check_pyramid",
    "check_same_channels",
    "check_size",
    "check_write_options",
    "count_nonfinite",
    "count_parts",
    "describe_output",
    "describe_rules",
    "encoded_rows",
    "ensure_output_dir",
    "exr_threads",
    "info_for_array",
    "limited_exr_threads",
    "linear_to_srgb",
    "mip_stream_writer",
    "oiio_version",
    "open_stream",
    "output_pixel_type",
    "output_codec_memory",
    "pixels_in",
    "read_image",
    "read_parts",
    "read_shape",
    "source_sha1",
    "srgb_to_linear",
    "stores_half_unchanged",
    "stream_writer",
    "stream_writers",
    "streams_to",
    "write_image",
    "write_images",
    "write_levels",
    "write_spec",
]
