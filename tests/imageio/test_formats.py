"""What each format stores (pyramid_cli.imageio.formats): format names, pixel types, colour-space names."""

import OpenImageIO as oiio
import pytest

from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio import formats


def test_output_pixel_type_table():
    assert pio.output_pixel_type("png", "half") == "uint16"
    assert pio.output_pixel_type("png", "float") == "uint16"
    assert pio.output_pixel_type("jpeg", "float") == "uint8"
    assert pio.output_pixel_type("jpeg", "uint16") == "uint8"
    assert pio.output_pixel_type("openexr", "uint8") == "half"
    assert pio.output_pixel_type("tiff", "half") == "half"


def test_format_from_path_by_extension_whatever_its_case():
    assert formats.format_from_path("a/b.exr") == "openexr"
    assert formats.format_from_path("B.PNG") == "png"
    assert formats.format_from_path("c.jpg") == formats.format_from_path("c.jpeg") == "jpeg"
    assert formats.format_from_path("d.xyz") == "" and formats.format_from_path("noext") == ""
    assert formats.format_title("openexr") == "OpenEXR" and formats.format_title("bmp") == "bmp"


def test_pixel_type_names_of_oiio_types():
    assert formats.pixel_type_name(oiio.TypeDesc("uint8")) == "uint8"
    assert formats.pixel_type_name(oiio.TypeDesc("uint16")) == "uint16"
    assert formats.pixel_type_name(oiio.TypeDesc("half")) == "half"
    assert formats.pixel_type_name(oiio.TypeDesc("float")) == "float"
    assert formats.pixel_type_name(oiio.TypeDesc("uint32")) == "float"   # anything else is read as float


def test_check_choice_and_one_line():
    formats.check_choice("alpha mode", "straight", formats.ALPHA_MODES)
    with pytest.raises(UsageError, match="bad alpha mode 'sideways'"):
        formats.check_choice("alpha mode", "sideways", formats.ALPHA_MODES)
    assert formats.one_line("\n  first\nsecond\n", "none") == "first"
    assert formats.one_line(" \n", "none") == "none"
    assert formats.oiio_version() == oiio.__version__


def test_a_png_ends_with_its_iend_chunk_or_was_cut_short(tmp_path):
    """``png_ends``: a whole PNG ends; one cut anywhere after its signature does not; one with more than
    PNG_TAIL bytes after its IEND still ends (its chunks are walked)."""
    import numpy as np

    path = tmp_path / "a.png"
    pixels = np.random.default_rng(0).integers(0, 256, (300, 400, 3), dtype=np.uint8)
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), oiio.ImageSpec(400, 300, 3, "uint8")) and out.write_image(pixels) and out.close()
    whole = path.read_bytes()
    assert len(whole) > 4 * formats.PNG_TAIL  # several IDAT chunks, so the cuts below fall inside them
    assert formats.png_ends(path)
    for cut in (9, 40, len(whole) // 3, len(whole) - 13, len(whole) - 1):
        path.write_bytes(whole[:cut])
        assert not formats.png_ends(path), cut
    path.write_bytes(whole + b"\0" * (2 * formats.PNG_TAIL))
    assert formats.png_ends(path)


@pytest.mark.parametrize("text, parsed", [
    ("6", (6, formats.PNG_FILTERS)),
    ("0", (0, formats.PNG_FILTERS)),
    ("6:none", (6, 0x08)),
    ("9:ALL", (9, 0xF8)),
    (" 3:sub+up ", (3, 0x30)),
    ("6:paeth+avg", (6, 0xC0)),
])
def test_png_compression_is_a_zlib_level_and_libvips_s_filter_names(text, parsed):
    assert formats.png_compression(text) == parsed


@pytest.mark.parametrize("text", ["", "10", "-1", "zip", "6:", "6:bogus", "6:none+", ":none", "none", "6:none:up"])
def test_png_compression_refuses_what_it_does_not_name(text):
    with pytest.raises(ValueError):
        formats.png_compression(text)
