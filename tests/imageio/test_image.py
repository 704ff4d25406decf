"""The image model (pyramid_cli.imageio.image): Image, ImageInfo, default channel names, the rules line."""

import numpy as np
import pytest

from helpers.images import write as write_raw
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import UsageError
from pyramid_cli.imageio import image


def test_describe_rules(tmp_path):
    src = np.zeros((2, 2, 4), np.uint8)
    write_raw(tmp_path / "a.png", src, "uint8", alpha=3, oiio__UnassociatedAlpha=1)
    line = pio.describe_rules(pio.read_image(tmp_path / "a.png").spec)
    assert "\n" not in line and "a.png" in line
    assert "sRGB" in line and "straight" in line
    write_raw(tmp_path / "b.exr", np.zeros((2, 2, 3), np.float32), "half")
    line = pio.describe_rules(pio.read_image(tmp_path / "b.exr").spec)
    assert "linear" in line and "no alpha" in line


def test_default_channel_names_by_count():
    assert image.default_channel_names(1) == ["Y"]
    assert image.default_channel_names(2) == ["Y", "A"]
    assert image.default_channel_names(4) == ["R", "G", "B", "A"]
    assert image.default_channel_names(5) == [f"channel{i}" for i in range(5)]


def test_info_for_array_takes_a_channel_named_alpha_as_premultiplied():
    info = image.info_for_array("out/x.exr", 4)
    assert (info.format, info.pixel_type, info.colorspace) == ("openexr", "float", "linear")
    assert (info.alpha_channel, info.alpha_mode) == (3, "premultiplied")
    assert image.Image(np.zeros((1, 1, 4), np.float32), info).premultiplied
    plain = image.info_for_array("x.png", 3, ["X", "Y", "Z"])
    assert (plain.alpha_channel, plain.alpha_mode, plain.format) == (-1, "none", "png")
    assert not image.Image(np.zeros((1, 1, 3), np.float32), plain).premultiplied
    with pytest.raises(UsageError, match="2 channel names for 3 channels"):
        image.info_for_array("x.exr", 3, ["R", "G"])
