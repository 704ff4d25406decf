"""The tile set writers' interface: options, the ⌈n/2⌉ level sizes, the stored values, the calls a writer gets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pyramid_cli.imageio.encode import encoded_rows
from pyramid_cli.imageio.image import Image, ImageInfo
from pyramid_cli.imageio.tilesets.base import TileOptions, TileSetWriter, ceil_levels


class Recorder(TileSetWriter):
    """A writer that keeps what it is given: levels until one fits in 4×4."""

    layout = "test"

    def __init__(self, *args):
        self.calls: list = []
        super().__init__(*args)

    @classmethod
    def level_count(cls, size, options):
        n, (h, w) = 1, size
        while h > 4 or w > 4:
            h, w, n = (h + 1) // 2, (w + 1) // 2, n + 1
        return n

    def _rows(self, level, y0, pixels, owned=False):
        self.calls.append(("rows", level, y0, pixels.shape))

    def _finish(self):
        self.calls.append(("finish",))
        return {"layout": self.layout}

    def _abort(self):
        self.calls.append(("abort",))


def srgb8(channels=3):
    names = ["R", "G", "B", "A"][:channels]
    return ImageInfo(path="in.png", format="png", pixel_type="uint8", channel_names=names,
                     alpha_channel=3 if channels == 4 else -1, colorspace="srgb",
                     alpha_mode="straight" if channels == 4 else "none")


def test_ceil_levels_halve_rounding_up():
    assert ceil_levels((5, 3), 4) == [(5, 3), (3, 2), (2, 1), (1, 1)]
    assert ceil_levels((1, 300), 3) == [(1, 300), (1, 150), (1, 75)]
    assert ceil_levels((7, 7), 1) == [(7, 7)]


def test_tile_options_default_to_the_layouts_and_are_frozen():
    o = TileOptions()
    assert (o.tile_size, o.overlap, o.suffix, o.quality, o.compression, o.iiif_id, o.write) == \
        (None, None, None, None, None, None, {})
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.tile_size = 3  # type: ignore[misc]


def test_a_writer_has_its_levels_and_hands_on_its_calls():
    w = Recorder("out.test", srgb8(), (37, 9), 3, TileOptions())
    assert w.sizes == [(37, 9), (19, 5), (10, 3), (5, 2), (3, 1)]
    assert w.check() is None
    w.rows(1, 8, np.zeros((8, 5, 3), np.float32))
    assert w.finish() == {"layout": "test"}
    w.abort()
    assert w.calls == [("rows", 1, 8, (8, 5, 3)), ("finish",), ("abort",)]


@pytest.mark.parametrize("channels", [3, 4])
def test_encode_gives_the_values_a_file_of_encode_as_stores(channels):
    info = srgb8(channels)
    px = np.random.default_rng(1).random((6, 5, channels)).astype(np.float32)
    if channels == 4:
        px[..., :3] *= px[..., 3:]  # premultiplied, as the rows come
    w = Recorder("out.test", info, (6, 5), channels, TileOptions(write={"dither": False}))
    got = w.encode(px)
    assert got.dtype == np.uint8 and got.shape == px.shape
    np.testing.assert_array_equal(got, encoded_rows("x.tif", Image(px, info)))
    if channels == 3:  # 8-bit sRGB: the sRGB curve of the linear values
        want = np.where(px <= 0.0031308, 12.92 * px, 1.055 * np.power(px, 1 / 2.4) - 0.055)
        assert np.abs(got.astype(float) - want * 255).max() <= 0.5 + 1e-3


def test_encode_looks_at_nothing_on_disk_where_encode_as_is(tmp_path, monkeypatch):
    """``encode_as`` only names a format: a folder of that name in the working folder changes nothing."""
    from pyramid_cli.imageio.tilesets import writer_class

    monkeypatch.chdir(tmp_path)
    for name in ("x.tif", "x.jpg", "x.png", "x.jpeg"):
        (tmp_path / name).mkdir()
    px = np.full((4, 4, 3), 0.5, np.float32)
    w = Recorder("out.test", srgb8(), (4, 4), 3, TileOptions())
    assert (w.encode(px) == 188).all()
    dz = writer_class("dz")(str(tmp_path / "o.dzi"), srgb8(), (4, 4), 3, TileOptions(suffix="jpeg"))
    try:
        dz.check()
        for k, (h, w_) in enumerate(dz.sizes):  # 4×4, 2×2, 1×1
            dz.rows(k, 0, px[:h, :w_])
        assert [level["size"] for level in dz.finish()["levels"]] == [[4, 4], [2, 2], [1, 1]]
    except BaseException:
        dz.abort()
        raise
