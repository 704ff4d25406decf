"""Levels read and written as stored, without colour or alpha rules (pyramid_cli.imageio.raw)."""

import numpy as np

from pyramid_cli.imageio import raw


def test_float_levels_round_trip(tmp_path):
    pixels = np.random.default_rng(3).random((5, 7, 2)).astype(np.float32)
    path = str(tmp_path / "a.exr")
    raw.write_float(path, pixels, ["Y", "A"])
    assert raw.count_levels(path) == [1]
    level = raw.read_level(path)
    np.testing.assert_array_equal(np.asarray(level.pixels).reshape(pixels.shape), pixels)
    assert "exr" in raw.image_extensions()
