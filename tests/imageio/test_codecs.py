"""OpenEXR's codecs (``pyramid_cli.imageio.codecs``): what an open file's codec holds with its first thread and
each further one, and the limit on the threads."""

import OpenImageIO as oiio
import pytest

from helpers.images import noise, write
from pyramid_cli import imageio as io
from pyramid_cli.imageio.codecs import (
    EXR_CODEC_MEMORY,
    MIB,
    CodecMemory,
    exr_codec_memory,
    exr_threads,
    limited_exr_threads,
)


def spec(compression: str | None, width: int = 1536, channels: int = 4, pixel_type: str = "half", tile: int = 0):
    s = oiio.ImageSpec(width, 100, channels, pixel_type)
    if compression is not None:
        s.attribute("compression", compression)
    if tile:
        s.tile_width = s.tile_height = tile
    return s


def expected(name: str, chunk_pixels: int, value_bytes: int = 2, channels: int = 4) -> CodecMemory:
    chunk = chunk_pixels * channels * value_bytes
    (a, ac), (b, bc) = EXR_CODEC_MEMORY[name]
    return CodecMemory(a + int(ac * chunk + 0.5), b + int(bc * chunk + 0.5))


@pytest.mark.parametrize("compression, name, rows", [("zip", "zip", 16), ("zips", "zips", 1), ("none", "none", 1),
                                                     ("piz", "piz", 32), ("dwaa:45", "dwaa", 32), ("DWAB", "dwab", 256),
                                                     (None, "zip", 16), ("b44a", "b44a", 32)])
def test_a_file_holds_fixed_bytes_and_chunks_of_its_rows(compression, name, rows):
    assert exr_codec_memory(spec(compression), "openexr") == expected(name, rows * 1536)


def test_the_dwa_codecs_hold_most_and_grow_with_each_thread():
    """What was measured (docs/performance.md): a 3840-wide half RGBA DWAB file held 56 MiB on one thread and
    DWAA's compressor about 13 MiB a thread at any width; zip held 1.4 MiB, then about 2 MiB a thread."""
    dwab, dwaa, zip_ = (exr_codec_memory(spec(c, 3840), "openexr") for c in ("dwab", "dwaa", "zip"))
    assert 56 * MIB <= dwab.first <= 60 * MIB
    assert 13 * MIB <= dwaa.further <= 18 * MIB and 16.5 * MIB <= dwaa.first <= 20 * MIB
    assert 1.3 * MIB <= zip_.first <= 2 * MIB and 2.1 * MIB <= zip_.further <= 3 * MIB
    assert dwab.at(1) == dwab.first and dwab.at(3) == dwab.first + 2 * dwab.further and dwab.at(0) == dwab.first


def test_an_unknown_compression_is_counted_as_the_largest():
    unknown = exr_codec_memory(spec("something new"), "openexr")
    for name in EXR_CODEC_MEMORY:
        known = exr_codec_memory(spec(name), "openexr")
        assert unknown.first >= known.first and unknown.further >= known.further


def test_tiles_are_chunks_and_float_values_take_four_bytes():
    assert exr_codec_memory(spec("zip", tile=64, pixel_type="float", channels=3), "openexr") == \
        expected("zip", 64 * 64, 4, 3)


def test_other_formats_hold_nothing():
    assert exr_codec_memory(spec("zip"), "tiff") == CodecMemory(0, 0)


def test_streams_and_outputs_say_what_their_codecs_hold(tmp_path):
    src = write(tmp_path / "in.exr", noise(20, 300, seed=1), "half", compression="piz")
    with io.open_stream(src, keep_half=True) as st:
        assert st.codec_memory() == expected("piz", 32 * 300)
        assert io.output_codec_memory(tmp_path / "o.exr", st.info, 4, (10, 150)) == expected("piz", 32 * 150)
        assert io.output_codec_memory(tmp_path / "o.exr", st.info, 4, (10, 150), compression="dwab") == \
            expected("dwab", 256 * 150)
        assert io.output_codec_memory(tmp_path / "o.exr", st.info, 4, (10, 150), tile=64) == \
            expected("piz", 64 * 64)
        assert io.output_codec_memory(tmp_path / "o.png", st.info, 4, (10, 150)) == CodecMemory(0, 0)


def test_codec_memories_add_up():
    assert CodecMemory(1, 2) + CodecMemory(10, 20) == CodecMemory(11, 22)


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
