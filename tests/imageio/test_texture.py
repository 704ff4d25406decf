"""MIP-mapped textures and multi-part files (pyramid_cli.imageio.texture). maketx's own files against ours:
tests/system/test_maketx.py."""

import numpy as np
import OpenImageIO as oiio
import pytest

from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio import texture


def levels(n: int = 6) -> list[pio.Image]:
    """32×16 (rows × columns) and its halvings: six levels make the whole chain down to 1×1, as OpenEXR wants."""
    info = pio.info_for_array("t.exr", 4)
    rng = np.random.default_rng(5)
    return [pio.Image(rng.random((max(1, 32 >> k), max(1, 16 >> k), 4)).astype(np.float32), info) for k in range(n)]


def read_levels(path, mip: bool):
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    out, k = [], 0
    while inp.seek_subimage(0 if mip else k, k if mip else 0):
        out.append((inp.spec().copy(), np.asarray(inp.read_image("float"))))
        k += 1
    inp.close()
    return out


def test_write_levels_mipmap_is_a_tiled_mip_mapped_exr(tmp_path):
    images = levels()
    texture.write_levels(tmp_path / "t.exr", images, tile=4, pixel_type="float")
    back = read_levels(tmp_path / "t.exr", mip=True)
    assert len(back) == 6
    for (spec, px), im in zip(back, images, strict=True):
        assert (spec.tile_width, spec.tile_height) == (4, 4)
        np.testing.assert_array_equal(px, im.pixels)
    assert back[0][0].getattribute("oiio:AverageColor")


def test_write_levels_multipart_names_each_part(tmp_path):
    images = levels(2)
    texture.write_levels(tmp_path / "p.exr", images, mode="multipart", pixel_type="float")
    back = read_levels(tmp_path / "p.exr", mip=False)
    assert [spec.getattribute("name") for spec, _ in back] == ["level0", "level1"]
    for (_, px), im in zip(back, images, strict=True):
        np.testing.assert_array_equal(px, im.pixels)


def test_a_format_without_levels_is_refused_and_nothing_written(tmp_path):
    with pytest.raises(OutputError, match="cannot hold MIP levels"):
        texture.write_levels(tmp_path / "t.png", levels(2))
    assert list(tmp_path.iterdir()) == []


def test_the_streamed_texture_equals_the_one_written_whole(tmp_path):
    images = levels()
    texture.write_levels(tmp_path / "whole.exr", images, tile=4)
    avg = [float(v) for v in images[0].pixels.reshape(-1, 4).mean(axis=0)]
    shapes = [im.pixels.shape for im in images]
    with texture.mip_stream_writer(tmp_path / "bands.exr", images[0].spec, shapes, tile=4,
                                   colors=(avg, None)) as writer:
        writer.write(0, images[0].pixels[:12])
        writer.write(12, images[0].pixels[12:])
        for im in images[1:]:
            writer.append_level(lambda r0, r1, px=im.pixels: px[r0:r1])
    whole, streamed = read_levels(tmp_path / "whole.exr", True), read_levels(tmp_path / "bands.exr", True)
    assert len(whole) == len(streamed) == 6
    for (_, a), (_, b) in zip(whole, streamed, strict=True):
        np.testing.assert_array_equal(a, b)
