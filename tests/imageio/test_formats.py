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
