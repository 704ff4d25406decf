"""OpenEXR's codec threads (``pyramid_cli.imageio.codecs``): the line buffers each holds, and the limit."""

import OpenImageIO as oiio
import pytest

from helpers.images import noise, write
from pyramid_cli import imageio as io
from pyramid_cli.imageio.codecs import CHUNKS_PER_THREAD, exr_thread_bytes, exr_threads, limited_exr_threads


def spec(compression: str | None, width: int = 1536, channels: int = 4, pixel_type: str = "half", tile: int = 0):
    s = oiio.ImageSpec(width, 100, channels, pixel_type)
    if compression is not None:
        s.attribute("compression", compression)
    if tile:
        s.tile_width = s.tile_height = tile
    return s


@pytest.mark.parametrize("compression, rows", [("zip", 16), ("zips", 1), ("none", 1), ("piz", 32), ("dwaa:45", 32),
                                               ("DWAB", 256), (None, 16), ("something new", 256)])
def test_a_thread_holds_a_few_chunks_of_rows(compression, rows):
    assert exr_thread_bytes(spec(compression), "openexr") == CHUNKS_PER_THREAD * rows * 1536 * 4 * 2


def test_tiles_are_chunks_and_float_values_take_four_bytes():
    assert exr_thread_bytes(spec("zip", tile=64, pixel_type="float", channels=3), "openexr") == \
        CHUNKS_PER_THREAD * 64 * 64 * 3 * 4


def test_other_formats_hold_nothing_per_thread():
    assert exr_thread_bytes(spec("zip"), "tiff") == 0


def test_streams_and_outputs_say_what_their_threads_hold(tmp_path):
    src = write(tmp_path / "in.exr", noise(20, 300, seed=1), "half", compression="piz")
    with io.open_stream(src, keep_half=True) as st:
        assert st.codec_thread_bytes() == CHUNKS_PER_THREAD * 32 * 300 * 4 * 2
        assert io.output_thread_bytes(tmp_path / "o.exr", st.info, 4, (10, 150)) == CHUNKS_PER_THREAD * 32 * 150 * 8
        assert io.output_thread_bytes(tmp_path / "o.exr", st.info, 4, (10, 150), compression="dwab") == \
            CHUNKS_PER_THREAD * 256 * 150 * 8
        assert io.output_thread_bytes(tmp_path / "o.png", st.info, 4, (10, 150)) == 0


def test_the_limit_holds_inside_the_block_and_is_undone_after():
    before = oiio.get_int_attribute("exr_threads")
    pool = oiio.get_int_attribute("threads")
    with limited_exr_threads(1):
        assert exr_threads() == 1 and oiio.get_int_attribute("threads") == 1
    assert oiio.get_int_attribute("exr_threads") == before and oiio.get_int_attribute("threads") == pool
    with limited_exr_threads(None), limited_exr_threads(exr_threads() + 5):  # no limit, or none needed
        assert oiio.get_int_attribute("exr_threads") == before
    with pytest.raises(RuntimeError), limited_exr_threads(1):
        raise RuntimeError
    assert oiio.get_int_attribute("exr_threads") == before
