"""A band of rows at a time (pyramid_cli.imageio.bands): streams read and write what the whole-image calls
read and write. Streaming whole commands: tests/run/test_stream.py."""

import numpy as np
import pytest

from helpers.images import noise
from helpers.images import write as write_raw
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio import bands


def test_a_stream_reads_the_bands_read_image_reads(tmp_path):
    src = np.random.default_rng(1).integers(0, 256, (11, 5, 4)).astype(np.uint8)
    path = write_raw(tmp_path / "in.png", src, "uint8", alpha=3, oiio__UnassociatedAlpha=1)
    whole = pio.read_image(path)
    with bands.open_stream(path) as stream:
        assert stream.shape == (11, 5, 4) and stream.dtype == np.float32
        assert stream.info.alpha_mode == whole.spec.alpha_mode == "straight"
        parts = [stream.read(y, min(y + 4, 11)) for y in range(0, 11, 4)]
    np.testing.assert_array_equal(np.concatenate(parts), whole.pixels)


def test_a_stream_writer_writes_the_file_write_image_writes(tmp_path):
    px = np.random.default_rng(2).random((10, 6, 3)).astype(np.float32)
    info = pio.info_for_array("x.png", 3)
    pio.write_image(tmp_path / "whole.png", pio.Image(px, info), dither=True)
    with bands.stream_writer(tmp_path / "bands.png", info, px.shape, dither=True) as writer:
        for y in range(0, 10, 3):
            writer.write(y, px[y:y + 3])
    a, b = pio.read_image(tmp_path / "whole.png"), pio.read_image(tmp_path / "bands.png")
    np.testing.assert_array_equal(a.pixels, b.pixels)


def test_rows_go_in_order_and_a_short_write_leaves_nothing(tmp_path):
    info = pio.info_for_array("x.exr", 1)
    with pytest.raises(ValueError, match="row 0 expected"), \
            bands.stream_writer(tmp_path / "a.exr", info, (4, 4, 1)) as writer:
        writer.write(2, np.zeros((2, 4, 1), np.float32))
    with pytest.raises(ValueError, match="2 of 4 rows"), \
            bands.stream_writer(tmp_path / "a.exr", info, (4, 4, 1)) as writer:
        writer.write(0, np.zeros((2, 4, 1), np.float32))
    assert list(tmp_path.iterdir()) == []


def test_formats_encoded_whole_do_not_stream(tmp_path):
    assert bands.streams_to("a.exr") and bands.streams_to("a.png")
    assert not bands.streams_to("a.jpg") and not bands.streams_to("a.unknown")
    with pytest.raises(OutputError, match="band by band"), \
            bands.stream_writer(tmp_path / "a.jpg", pio.info_for_array("a.jpg", 3), (2, 2, 3)):
        pass
    assert bands.band_quantum(1, False) == 1 and bands.band_quantum(1, True) == 8
    assert bands.band_quantum(64, True) == 64 and bands.band_quantum(12, True) == 24


@pytest.mark.parametrize("pixel_type, channels, alpha, table", [
    ("uint8", 3, None, True), ("uint16", 1, None, True), ("uint8", 4, 3, False), ("float", 3, None, False),
])
def test_code_table_decodes_every_stored_row_as_read_does(tmp_path, pixel_type, channels, alpha, table):
    """read_stored gives the rows as stored, and code_table (where decoding is one table for every code and
    channel: no alpha, integer codes) looks them up into exactly what read gives."""
    from pyramid_cli.imageio.read import code_table

    top = {"uint8": 255, "uint16": 65535}.get(pixel_type, 1)
    rng = np.random.default_rng(5)
    stored = (rng.integers(0, top + 1, (9, 300, channels)).astype(pixel_type) if top > 1
              else rng.uniform(0, 1, (9, 300, channels)).astype(np.float32))
    src = write_raw(tmp_path / ("in.png" if top > 1 else "in.exr"), stored, pixel_type, alpha=alpha)
    with pio.open_stream(src) as st:
        codes, decoded = st.read_stored(2, 7), None
        t = code_table(st.info, st.stored_dtype, channels)
        assert (t is not None) == table
        if table:
            assert codes.dtype == st.stored_dtype and np.array_equal(codes, stored[2:7])
            assert t[0] == 0  # what a zero border reads
    with pio.open_stream(src) as st:
        st.read(0, 2)
        decoded = st.read(2, 7)
    if table:
        np.testing.assert_array_equal(t[codes], decoded)


def _stream_and_encoder(path, out: str, nan: str = "keep", **options):
    stream = bands.open_stream(path, keep_half=True, nan=nan)
    return stream, pio.Encoder(out, stream.info, stream.shape[2], check_path=False, **options)


@pytest.mark.parametrize("name, pixel_type, channels, out, options, nan, kept", [
    ("in.png", "uint8", 3, "o.tx", {}, "keep", True),                        # sRGB codes by table and back
    ("in.png", "uint8", 1, "o.png", {}, "keep", True),
    ("in.tif", "uint16", 3, "o.tif", {}, "keep", True),
    ("in.exr", "half", 4, "o.exr", {}, "keep", True),                        # premultiplied alpha, untouched
    ("in.exr", "half", 3, "o.exr", {}, "zero", False),                       # NaN would become 0
    ("in.png", "uint8", 4, "o.tx", {}, "keep", False),                       # straight alpha premultiplied
    ("in.png", "uint8", 3, "o.tx", {"dither": True}, "keep", False),
    ("in.png", "uint8", 3, "o.tx", {"pixel_type": "uint16"}, "keep", False),  # other codes
    ("in.png", "uint8", 3, "o.exr", {}, "keep", False),                      # stored as half
    ("in.exr", "half", 3, "o.exr", {"colorspace": "ACEScg"}, "keep", False),  # OCIO converts (a matrix)
    ("in.exr", "float", 3, "o.exr", {}, "keep", False),                      # too many values to try
])
def test_keeps_stored_says_when_the_encoder_gives_back_what_was_read(tmp_path, name, pixel_type, channels, out,
                                                                      options, nan, kept):
    """Where it says so, every pixel of a picture (not only the values it tried) comes back as stored."""
    rng = np.random.default_rng(7)
    if pixel_type in ("uint8", "uint16"):
        px = rng.integers(0, np.iinfo(pixel_type).max + 1, (37, 29, channels)).astype(pixel_type)
    else:
        px = rng.standard_normal((37, 29, channels)).astype(np.float32) * 4
    path = write_raw(tmp_path / name, px, pixel_type)
    stream, enc = _stream_and_encoder(path, str(tmp_path / out), nan, **options)
    with stream:
        assert stream.keeps_stored(enc) == kept
        stored = stream.read_stored(0, 37)
        back = enc.values(stream.decode(stored.copy()))
    if kept:
        assert back.dtype == stored.dtype and np.array_equal(back, stored)


def test_rows_written_as_stored_make_the_file_written_from_pixels(tmp_path):
    px = np.random.default_rng(8).integers(0, 256, (40, 33, 3)).astype(np.uint8)
    path = write_raw(tmp_path / "in.png", px, "uint8")
    stream, enc = _stream_and_encoder(path, str(tmp_path / "x.tif"))
    with stream:
        stored, decoded = stream.read_stored(0, 40), stream.read(0, 40)
        info = stream.info
    for name, rows in (("a.tif", decoded), ("b.tif", stored)):
        with bands.stream_writer(tmp_path / name, info, px.shape) as writer:
            for y in range(0, 40, 16):
                (writer.write if name == "a.tif" else writer.write_stored)(y, rows[y:y + 16])
    a, b = pio.read_image(tmp_path / "a.tif"), pio.read_image(tmp_path / "b.tif")
    np.testing.assert_array_equal(a.pixels, b.pixels)
    assert a.spec.pixel_type == b.spec.pixel_type == "uint8"


@pytest.mark.parametrize("shape, tile", [((300, 16, 4), 64), ((16, 16, 3), 0)])
def test_a_small_exr_written_band_by_band_is_whole_when_checked(tmp_path, shape, tile):
    """OpenImageIO's OpenEXR writer writes the file's last bytes when it is let go, not at close: the check after
    close saw an empty file (a small MIP map, all zeros, failed as "nothing was written")."""
    info = pio.info_for_array("x.exr", shape[2])
    rows = np.zeros(shape, np.float16)
    if tile:
        sizes = [shape]
        while sizes[-1][:2] != (1, 1):
            sizes.append((max(1, sizes[-1][0] // 2), max(1, sizes[-1][1] // 2), shape[2]))
        with pio.mip_stream_writer(tmp_path / "m.exr", info, sizes, tile=tile, colors=([0.0] * shape[2], None)) as w:
            w.write(0, rows)
            for size in sizes[1:]:
                w.append_level(lambda r0, r1, size=size: np.zeros((r1 - r0,) + size[1:], np.float16))
        back = pio.read_image(tmp_path / "m.exr")
    else:
        with bands.stream_writer(tmp_path / "s.exr", info, shape) as w:
            w.write(0, rows)
        back = pio.read_image(tmp_path / "s.exr")
    assert back.pixels.shape == shape and not back.pixels.any()


@pytest.mark.parametrize("tile", [0, 16])
def test_a_stream_opened_again_in_place_reads_the_same_rows(tmp_path, tile):
    """``reopen`` (OpenEXR counts a file's codec threads when it opens: run.codec_budget.Codecs.within) starts over on a
    new handle, a tiled file's kept row of tiles included; the object, its shape and its counts stay."""
    src = noise(40, 33, seed=4)
    path = write_raw(tmp_path / "in.exr", src, "half", tile=tile)
    with bands.open_stream(path, keep_half=True) as stream:
        first = stream.read(0, 20)
        before = stream._inp
        stream.reopen()
        assert stream._inp is not before and stream.shape == (40, 33, 4)
        np.testing.assert_array_equal(stream.read(0, 20), first)
        np.testing.assert_array_equal(stream.read(20, 40), src[20:].astype(np.float16))


@pytest.mark.parametrize("rows, chunk, height, pieces", [
    ((0, 40), 16, 300, [(0, 32), (32, 40)]),
    ((40, 80), 16, 300, [(40, 48), (48, 80)]),
    ((0, 64), 16, 300, [(0, 64)]),
    ((5, 10), 16, 300, [(5, 10)]),
    ((290, 300), 16, 300, [(290, 300)]),
    ((256, 280), 256, 2160, [(256, 280)]),
    ((200, 600), 256, 2160, [(200, 256), (256, 512), (512, 600)]),
    ((7, 9), 1, 300, [(7, 9)]),
])
def test_a_band_is_read_in_pieces_cut_at_its_chunks_edges(rows, chunk, height, pieces):
    assert bands.chunk_pieces(*rows, chunk, height) == pieces


@pytest.mark.parametrize("name, pixel_type, tile, attrs, chunk", [
    ("zip.exr", "half", 0, {"compression": "zip"}, 16),
    ("dwab.exr", "half", 0, {"compression": "dwab"}, 256),
    ("piz.exr", "float", 0, {"compression": "piz"}, 32),
    ("tiled.exr", "half", 16, {"compression": "zip"}, 16),
    ("strips.tif", "uint16", 0, {"compression": "zip", "tiff__RowsPerStrip": 24}, 24),
    ("rows.png", "uint8", 0, {}, 1),
])
def test_bands_read_no_chunk_in_two_reads_and_give_the_whole_read_s_rows(tmp_path, monkeypatch, name, pixel_type,
                                                                        tile, attrs, chunk):
    """OpenImageIO decodes every chunk a read touches (an OpenEXR or TIFF file's chunk of scanlines, a row of
    tiles): a read that runs from inside one chunk into the next decodes the first again. Bands of any size are read
    in reads that lie in one chunk or cover whole ones (a tiled file's row of tiles is kept), each row once, and give
    what a whole read gives, whatever the caller does to the rows it was given."""
    h, w = 300, 37
    src = noise(h, w, seed=5)
    if pixel_type in ("uint8", "uint16"):
        src = (src * (255 if pixel_type == "uint8" else 65535)).round().astype(pixel_type)
    path = write_raw(tmp_path / name, src, pixel_type, tile=tile, **attrs)
    whole = pio.read_image(path).pixels
    reads = []
    real = bands.ImageStream._scanlines
    monkeypatch.setattr(bands.ImageStream, "_scanlines", lambda self, a, b: reads.append((a, b)) or real(self, a, b))
    with bands.open_stream(path) as stream:
        assert stream.chunk_rows == chunk
        steps = [5, 40, 7, 64, 13, 100, 1]
        parts, y = [], 0
        while y < h:
            band = stream.read(y, min(h, y + steps[len(parts) % len(steps)]))
            parts.append(band.copy())
            band[...] = -1  # a caller may decode in place: what a later band reads is not these rows
            y += len(band)
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    if tile:
        assert not reads
        return
    assert [a for a, _ in reads] == sorted(a for a, _ in reads) and sum(b - a for a, b in reads) == h, reads
    one_chunk = [a // chunk == (b - 1) // chunk for a, b in reads]
    whole_chunks = [a % chunk == 0 and (b % chunk == 0 or b == h) for a, b in reads]
    assert all(o or c for o, c in zip(one_chunk, whole_chunks, strict=True)), reads
