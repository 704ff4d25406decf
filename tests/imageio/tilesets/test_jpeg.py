"""imageio.tilesets.jpeg: JPEG tiles as libjpeg-turbo writes them, through imagecodecs or OpenImageIO."""

from __future__ import annotations

import builtins

import numpy as np
import OpenImageIO as oiio
import pytest

from pyramid_cli.imageio.tilesets.jpeg import (
    abbreviated,
    jpeg_bytes,
    jpeg_tables,
    libjpeg,
    rows_together,
    shared_tables,
)


def segment(marker: int, body: bytes) -> bytes:
    return bytes([0xFF, marker]) + (len(body) + 2).to_bytes(2, "big") + body


def test_only_an_exif_app1_segment_is_dropped():
    """jpeg_bytes drops the APP1 segment that says Exif and keeps every other: JFIF's APP0, an XMP APP1, an ICC
    APP2, and all from the first segment that is not APPn on (the tables, the frame, the scan)."""
    soi, rest = b"\xff\xd8", segment(0xDB, b"\x00" * 65) + b"\xff\xda\x00\x02scan\xff\xd9"
    jfif = segment(0xE0, b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00")
    exif = segment(0xE1, b"Exif\x00\x00II*\x00\x08\x00\x00\x00\x00\x00")
    xmp = segment(0xE1, b"http://ns.adobe.com/xap/1.0/\x00<x/>")
    icc = segment(0xE2, b"ICC_PROFILE\x00\x01\x01abc")
    assert jpeg_bytes(soi + jfif + exif + rest) == soi + jfif + rest
    assert jpeg_bytes(memoryview(soi + exif + xmp + icc + rest)) == soi + xmp + icc + rest
    assert jpeg_bytes(soi + jfif + rest) == soi + jfif + rest  # nothing to drop
    assert jpeg_bytes(soi + rest + exif) == soi + rest + exif  # after the tables: data, never looked at


def test_openimageio_s_tile_less_its_exif_is_imagecodecs_s(tmp_path):
    """A tile OpenImageIO writes, less its Exif segment, is what libjpeg() makes of it (RGB 4:2:0 at Q 75, grey
    4:4:4 at Q 95, a one-pixel grey tile)."""
    pytest.importorskip("imagecodecs")
    rng = np.random.default_rng(3)
    path = str(tmp_path / "tile.jpg")
    for shape, q in (((37, 53, 3), 75), ((20, 9, 1), 95), ((1, 1, 1), 75)):
        px = rng.integers(0, 256, shape, dtype=np.uint8)
        spec = oiio.ImageSpec(shape[1], shape[0], shape[2], oiio.UINT8)
        spec.attribute("compression", f"jpeg:{q}")
        spec.attribute("jpeg:subsampling", "4:4:4" if q >= 90 else "4:2:0")
        out = oiio.ImageOutput.create("jpeg")
        assert out.open(path, spec) and out.write_image(px) and out.close()
        data = open(path, "rb").read()
        encode = libjpeg(q)
        assert encode is not None and b"Exif" in data[:64]
        assert jpeg_bytes(data) == bytes(encode(px)), (shape, q)


def test_a_tile_of_a_band_is_encoded_where_it_lies(monkeypatch):
    """A tile's columns of a band (rows apart, each row's pixels together) go to libjpeg-turbo as they are, with
    the band's row stride: no copy, the bytes of the copy's file. Pixels not together in a row are copied first."""
    imagecodecs = pytest.importorskip("imagecodecs")
    given = []
    real = imagecodecs.jpeg8_encode

    def seen(data, **kw):
        given.append(data)
        return real(data, **kw)

    monkeypatch.setattr(imagecodecs, "jpeg8_encode", seen)
    rng = np.random.default_rng(5)
    for channels in (3, 1):
        band = rng.integers(0, 256, (40, 300, channels), dtype=np.uint8)
        tile = band[3:35, 254:300]
        want = bytes(real(np.ascontiguousarray(tile[:, :, 0] if channels == 1 else tile), level=75,
                          subsampling=(2, 2)))
        assert bytes(libjpeg(75)(tile)) == want
        assert np.shares_memory(given[-1], band), channels
    sparse = band[:, ::2]  # every other column: copied
    assert bytes(libjpeg(75)(sparse)) == bytes(real(np.ascontiguousarray(sparse[:, :, 0]), level=75,
                                                   subsampling=(2, 2)))
    assert not np.shares_memory(given[-1], band)


def test_rows_together_are_kept_where_they_lie():
    """rows_together gives a tile's columns of a band (and a grey one's plane, and its (h, w, 1) view, as a pyramidal
    TIFF's codec takes it) as they lie; pixels apart within a row, as a contiguous copy of the same values."""
    band = np.arange(6 * 40 * 3, dtype=np.uint8).reshape(6, 40, 3)
    grey = band[:, :, :1].copy()
    for tile in (band[:, 8:24], grey[:, 8:24, 0], grey[:, 8:24]):
        assert rows_together(tile) is tile
        assert rows_together(tile).reshape(tile.shape[:2] + (-1,)).base is not None  # the TIFF's reshape: a view
    for apart in (band[:, ::2], band[:, 8:24, 0]):  # every other pixel; one channel of three
        kept = rows_together(apart)
        assert kept.flags.c_contiguous and not np.shares_memory(kept, band)
        np.testing.assert_array_equal(kept, apart)


def test_without_imagecodecs_openimageio_encodes(monkeypatch):
    """Without imagecodecs (no viewers extra) there is no libjpeg() encoder: the tile writers use OpenImageIO."""
    real = builtins.__import__

    def no_imagecodecs(name, *args, **kw):
        if name == "imagecodecs":
            raise ImportError("no imagecodecs here")
        return real(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_imagecodecs)
    assert libjpeg(75) is None


@pytest.mark.parametrize(("shape", "q"), [((32, 48, 3), 75), ((16, 16, 1), 90), ((1, 1, 3), 75)])
def test_a_tile_without_the_tables_it_shares_decodes_as_it_did(shape, q):
    """A TIFF's tiles share one JPEGTables (libtiff's layout): abbreviated() drops a tile's tables and JFIF segment
    only where they are the shared ones, and libjpeg-turbo, given the tables, decodes the same pixels."""
    imagecodecs = pytest.importorskip("imagecodecs")
    rng = np.random.default_rng(5)
    px = rng.integers(0, 256, shape, dtype=np.uint8)
    full = bytes(libjpeg(q)(px))
    tables = jpeg_tables(bytes(libjpeg(q)(np.zeros(shape, np.uint8))))
    assert tables.startswith(b"\xff\xd8\xff\xdb") and tables.endswith(b"\xff\xd9")
    short = abbreviated(full, tables)
    assert len(short) == len(full) - len(tables) + 4 - 18  # less the tables (their SOI and EOI aside) and JFIF
    assert b"JFIF" not in short and short.startswith(b"\xff\xd8") and short.endswith(b"\xff\xd9")
    np.testing.assert_array_equal(imagecodecs.jpeg8_decode(short, tables=tables), imagecodecs.jpeg8_decode(full))
    other = jpeg_tables(bytes(libjpeg(q - 10)(px)))  # another quality: other tables, the tile kept whole
    assert abbreviated(full, other) == full


def test_shared_tables_store_a_tile_as_abbreviated_does():
    """shared_tables() swaps the header of tiles encoded like its sample (same tables, same size) and falls back to
    abbreviated() for any other: the same bytes either way."""
    pytest.importorskip("imagecodecs")
    rng = np.random.default_rng(7)
    encode = libjpeg(75)
    tables, store = shared_tables(bytes(encode(np.zeros((64, 64, 3), np.uint8))))
    for shape in ((64, 64, 3), (17, 64, 3)):  # a tile of the sample's size, and another frame: the fallback
        tile = bytes(encode(rng.integers(0, 256, shape, dtype=np.uint8)))
        assert store(tile) == abbreviated(tile, tables) != tile
    other = bytes(libjpeg(60)(np.zeros((64, 64, 3), np.uint8)))
    assert store(other) == other  # other tables: kept whole
