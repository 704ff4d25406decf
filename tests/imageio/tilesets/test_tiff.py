"""Pyramidal TIFF and OME-TIFF writers, read back by their real clients: tifffile (every level), OpenImageIO
(plain TIFF: one subimage per level; OME-TIFF: level 0 only, it does not follow SubIFDs), OpenSlide (the
generic tiled TIFF), and compared with ``vips tiffsave --tile --pyramid``'s level structure."""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import pytest

import pyramid_cli as pyr
from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.imageio.image import ImageInfo
from pyramid_cli.imageio.tilesets import TileOptions, layout_of, writer_class
from pyramid_cli.imageio.tilesets.jpeg import abbreviated, jpeg_tables

tifffile = pytest.importorskip("tifffile")

TILE = 16


def _info(kind: str, **attributes) -> ImageInfo:
    names = {1: ["Y"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}
    if kind == "rgb8":
        return ImageInfo("in.png", "png", "uint8", names[3], -1, "srgb", "none", attributes=attributes)
    if kind == "rgba8":
        return ImageInfo("in.png", "png", "uint8", names[4], 3, "srgb", "straight", attributes=attributes)
    if kind == "rgbh":
        return ImageInfo("in.exr", "openexr", "half", names[3], -1, "linear", "none", attributes=attributes)
    if kind == "rgba16":
        return ImageInfo("in.png", "png", "uint16", names[4], 3, "srgb", "straight", attributes=attributes)
    if kind == "y8":
        return ImageInfo("in.png", "png", "uint8", names[1], -1, "srgb", "none", attributes=attributes)
    assert kind == "y32"
    return ImageInfo("in.exr", "openexr", "float", names[1], -1, "linear", "none", attributes=attributes)


def _picture(h: int, w: int, c: int, seed: int = 0) -> np.ndarray:
    """Linear premultiplied pixels: smooth ramps plus noise (JPEG-friendly where the noise is small)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    px = np.stack([(0.5 + 0.4 * np.sin(x / 7 + y / 11 + i)) for i in range(c)], axis=-1)
    px += rng.normal(0, 0.02, px.shape).astype(np.float32)
    px = np.clip(px, 0, 1).astype(np.float32)
    if c == 4:
        px[..., 3] = np.clip(0.2 + x / max(w, 2), 0, 1)
        px[..., :3] *= px[..., 3:]
    return px


def _write(path, kind: str, levels_of, shape, tile: int = TILE, **options):
    """Write a pyramid of ``shape`` through the layout of ``path``, rows interleaved as the band pipeline hands
    them (8 rows of level 0, then what each coarser level has completed); the writer and the levels fed."""
    h, w, c = shape
    cls = writer_class(layout_of(os.fspath(path)))
    writer = cls(os.fspath(path), _info(kind), (h, w), c, TileOptions(tile_size=tile, **options))
    writer.check()
    levels = levels_of(_picture(h, w, c), len(writer.sizes))
    assert [lv.shape[:2] for lv in levels] == writer.sizes
    done = [0] * len(levels)
    for y in range(0, h, 8):
        writer.rows(0, y, levels[0][y:y + 8])
        done[0] = min(h, y + 8)
        for k in range(1, len(levels)):
            finer = levels[k - 1].shape[0]
            ready = levels[k].shape[0] if done[k - 1] == finer else done[k - 1] // 2
            if ready > done[k]:
                writer.rows(k, done[k], levels[k][done[k]:ready])
                done[k] = ready
    return writer, writer.finish(), levels


def _pyramid(px, count):
    return list(pyr.pyramid(px, levels=count - 1, backend="reference"))


CASES = [((37, 53, 3), "rgb8"), ((1, 1, 3), "rgb8"), ((1, 300, 3), "rgb8"), ((300, 1, 3), "rgb8"),
         ((3, 300, 3), "rgb8"), ((37, 53, 4), "rgba16"), ((37, 53, 1), "y32"), ((37, 53, 3), "rgbh")]


@pytest.mark.parametrize("name", ["p.tif", "p.ome.tif"])
@pytest.mark.parametrize(("shape", "kind"), CASES)
def test_every_level_reads_back_as_stored(tmp_path, name, shape, kind):
    path = tmp_path / name
    writer, report, levels = _write(path, kind, _pyramid, shape)
    assert sorted(os.listdir(tmp_path)) == [name]  # nothing left beside it
    with tifffile.TiffFile(path) as tif:
        series = tif.series[0]
        assert len(series.levels) == len(writer.sizes)
        for k, level in enumerate(series.levels):
            got = level.asarray().reshape(levels[k].shape)
            np.testing.assert_array_equal(got, writer.encode(levels[k]))
            # half as half, but as float in OME-TIFF (OME-XML has no 16-bit float type)
            half = np.float32 if tif.is_ome else np.float16
            assert got.dtype == {"rgb8": np.uint8, "rgba16": np.uint16, "y32": np.float32, "rgbh": half}[kind]
            page = level.keyframe
            assert (page.tilewidth, page.tilelength) == (TILE, TILE)
            assert page.subfiletype == (1 if k else 0)
            assert page.photometric == (2 if shape[2] >= 3 else 1)
            assert page.extrasamples == ((2,) if shape[2] == 4 else ())  # unassociated: straight 8/16-bit alpha
        assert tif.is_ome == name.endswith(".ome.tif")
        if tif.is_ome:  # reduced levels as SubIFDs of the one full-resolution IFD
            assert len(tif.pages) == 1 and len(tif.pages[0].subifds or ()) == len(writer.sizes) - 1
            assert '<Image ID="Image:0" Name="p">' in tif.ome_metadata
        else:  # reduced levels as further pages
            assert len(tif.pages) == len(writer.sizes) and not tif.pages[0].description
    assert [lv["size"] for lv in report["levels"]] == [[w, h] for h, w in writer.sizes]
    assert [lv["scale"] for lv in report["levels"]] == [2 ** k for k in range(len(writer.sizes))]
    assert report["levels"][0]["tiles"] == [-(-shape[1] // TILE), -(-shape[0] // TILE)]


def test_level_count_as_vips():
    count = writer_class("tiff").level_count
    opts = TileOptions(tile_size=128)
    sizes = [(1, 1), (128, 128), (128, 129), (257, 257), (1000, 777), (2, 1000), (1, 100000), (300, 1)]
    assert [count(s, opts) for s in sizes] == [1, 1, 2, 2, 4, 2, 1, 1]  # as measured with vips 8.18
    assert count((1000, 777), TileOptions()) == 3  # 256 by default: 1000 → 500 → 250


def _psnr(a, b) -> float:
    return float(10 * np.log10(255 ** 2 / np.mean((a.astype(float) - b) ** 2)))


@pytest.mark.parametrize("name", ["j.tif", "j.ome.tif"])
def test_jpeg_tiles_within_jpeg_error(tmp_path, name):
    imagecodecs = pytest.importorskip("imagecodecs")
    path = tmp_path / name
    writer, report, levels = _write(path, "rgb8", _pyramid, (37, 53, 3), compression="jpeg", quality=90)
    assert report["compression"] == "jpeg"
    with tifffile.TiffFile(path) as tif:
        for k, level in enumerate(tif.series[0].levels):
            assert level.keyframe.compression == 7
            want = writer.encode(levels[k])
            alone = imagecodecs.jpeg8_decode(imagecodecs.jpeg8_encode(want, level=90, subsampling=(2, 2)))
            # as close as the level encoded whole at the same quality and chroma subsampling, give or take 1 dB
            assert _psnr(level.asarray(), want) > _psnr(alone, want) - 1


def _segments(path) -> list[list[bytes]]:
    """Every level's stored tiles, as the file holds them (compressed), read through tifffile."""
    out = []
    with tifffile.TiffFile(path) as tif, open(path, "rb") as fh:
        for level in tif.series[0].levels:
            page, tiles = level.keyframe, []
            for at, size in zip(page.dataoffsets, page.databytecounts, strict=True):
                fh.seek(at)
                tiles.append(fh.read(size))
            out.append(tiles)
    return out


@pytest.mark.parametrize("name", ["j.tif", "j.ome.tif"])
@pytest.mark.parametrize(("shape", "kind"), [((75, 101, 3), "rgb8"), ((75, 101, 1), "y8"), ((20, 300, 3), "rgb8")])
def test_jpeg_levels_compressed_as_they_come_are_the_bytes_tifffile_makes(tmp_path, monkeypatch, name, shape, kind):
    """Every level's JPEG tiles, compressed on the pool as their rows complete (tifffile's codec called alone), are
    the bytes tifffile makes of the same tiles, less the tables they share, which the pages hold once as
    JPEGTables, as libtiff (``vips tiffsave``) writes them: the same pixels, a smaller file."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    w, _, _ = _write(tmp_path / "a" / name, kind, _pyramid, shape, compression="jpeg", quality=83)
    assert len(w.sizes) > 1 and w._packs()
    monkeypatch.setattr(type(w), "_packs", lambda self: False)
    _write(tmp_path / "b" / name, kind, _pyramid, shape, compression="jpeg", quality=83)
    a, b = tmp_path / "a" / name, tmp_path / "b" / name
    ours, theirs = _segments(a), _segments(b)
    assert len(ours) == len(theirs) == len(w.sizes)
    with tifffile.TiffFile(a) as ta, tifffile.TiffFile(b) as tb:
        for k, (mine, full) in enumerate(zip(ours, theirs, strict=True)):
            tables = ta.series[0].levels[k].keyframe.jpegtables
            assert tables == jpeg_tables(full[0]) and tb.series[0].levels[k].keyframe.jpegtables is None
            assert mine == [abbreviated(t, tables) for t in full] and all(b"JFIF" not in t[:32] for t in mine)
            got = ta.series[0].levels[k].asarray()
            np.testing.assert_array_equal(got, tb.series[0].levels[k].asarray())
            if not name.endswith(".ome.tif"):  # libtiff's decoding, given the tables, through OpenImageIO
                inp = oiio.ImageInput.open(str(a))
                assert inp.seek_subimage(k, 0)
                np.testing.assert_array_equal(inp.read_image(oiio.UINT8).reshape(got.shape), got)
                inp.close()
    assert a.stat().st_size < b.stat().st_size


@pytest.mark.parametrize(("codec", "tag", "kind", "name"), [
    ("deflate:9", "ADOBE_DEFLATE", "rgba16", "c.tif"), ("zstd", "ZSTD", "rgbh", "c.tif"),
    ("lzw", "LZW", "y32", "c.ome.tif"), ("packbits", "PACKBITS", "rgb8", "c.tif")])
def test_lossless_codecs_keep_values(tmp_path, codec, tag, kind, name):
    path = tmp_path / name
    c = {"rgba16": 4, "y32": 1}.get(kind, 3)
    writer, _, levels = _write(path, kind, _pyramid, (37, 53, c), compression=codec)
    with tifffile.TiffFile(path) as tif:
        for k, level in enumerate(tif.series[0].levels):
            assert level.keyframe.compression.name == tag
            np.testing.assert_array_equal(level.asarray().reshape(levels[k].shape), writer.encode(levels[k]))


def test_resolution_per_level_icc_profile_and_ome_physical_size(tmp_path):
    icc = np.arange(200, dtype=np.uint8)
    for name in ("r.tif", "r.ome.tif"):
        path = tmp_path / name
        cls = writer_class(layout_of(str(path)))
        info = _info("rgb8", XResolution=300.0, YResolution=150.0, ResolutionUnit="in", ICCProfile=icc)
        info.attribute_types["ICCProfile"] = "uint8[200]"
        writer = cls(str(path), info, (37, 53), 3, TileOptions(tile_size=TILE))
        writer.check()
        for k, lv in enumerate(_pyramid(_picture(37, 53, 3), len(writer.sizes))):
            writer.rows(k, 0, lv)
        writer.finish()
        with tifffile.TiffFile(path) as tif:
            for k, level in enumerate(tif.series[0].levels):
                page = level.keyframe
                assert page.get_resolution() == pytest.approx((300 / 2 ** k, 150 / 2 ** k))
                assert page.resolutionunit == 2
                assert page.iccprofile == icc.tobytes()
            if tif.is_ome:
                assert 'PhysicalSizeX="84.666' in tif.ome_metadata and 'PhysicalSizeY="169.333' in tif.ome_metadata


def test_openimageio_reads_pages_as_subimages(tmp_path):
    path = tmp_path / "o.tif"
    writer, _, levels = _write(path, "rgba16", _pyramid, (37, 53, 4))
    straight = oiio.ImageSpec()
    straight.attribute("oiio:UnassociatedAlpha", 1)  # the stored values, not premultiplied on reading
    for k, level in enumerate(levels):
        buf = oiio.ImageBuf(str(path), k, 0, straight)
        assert not buf.has_error, buf.geterror()
        assert (buf.spec().height, buf.spec().width, buf.spec().tile_width) == (*level.shape[:2], TILE)
        np.testing.assert_array_equal(buf.get_pixels(oiio.UINT16), writer.encode(level))
    inp = oiio.ImageInput.open(str(path))
    assert inp.seek_subimage(len(levels) - 1, 0) and not inp.seek_subimage(len(levels), 0)  # one page a level
    assert not inp.seek_subimage(0, 1)  # pages, not MIP levels
    inp.close()
    ome = tmp_path / "o.ome.tif"
    writer, _, levels = _write(ome, "rgba16", _pyramid, (37, 53, 4))
    inp = oiio.ImageInput.open(str(ome), straight)  # OpenImageIO does not follow SubIFDs: level 0 only
    try:
        assert not inp.seek_subimage(1, 0) and not inp.seek_subimage(0, 1) and inp.seek_subimage(0, 0)
        np.testing.assert_array_equal(inp.read_image(oiio.UINT16), writer.encode(levels[0]))
    finally:
        inp.close()


@pytest.mark.parametrize(("kind", "codec"), [("rgb8", None), ("rgba8", None), ("rgb8", "jpeg")])
def test_openslide_opens_the_pyramid(tmp_path, kind, codec):
    openslide = pytest.importorskip("openslide")
    c = 4 if kind == "rgba8" else 3
    path = tmp_path / "s.tif"
    # 32-pixel tiles: OpenSlide 4.0.1 (its libtiff) fails on uncompressed 16-pixel tiles at the bottom edge,
    # vips tiffsave's as ours
    writer, _, levels = _write(path, kind, _pyramid, (37, 53, c), tile=32, compression=codec)
    slide = openslide.OpenSlide(str(path))
    try:
        assert slide.properties["openslide.vendor"] == "generic-tiff"
        assert slide.level_count == len(writer.sizes)
        assert slide.level_dimensions == tuple((w, h) for h, w in writer.sizes)
        for k, level in enumerate(levels):
            got = np.asarray(slide.read_region((0, 0), k, slide.level_dimensions[k])).astype(int)
            want = writer.encode(level).astype(int)
            if codec == "jpeg":  # its libjpeg-turbo against tifffile's decoding of the same tiles
                with tifffile.TiffFile(path) as tif:
                    want = tif.series[0].levels[k].asarray().astype(int)
                assert np.abs(got[..., :3] - want).max() <= 2
                continue
            if c == 3:
                np.testing.assert_array_equal(got[..., :3], want)
                assert (got[..., 3] == 255).all()
                continue
            # OpenSlide premultiplies (cairo) and openslide-python unpremultiplies: compare premultiplied values
            np.testing.assert_array_equal(got[..., 3], want[..., 3])
            a = want[..., 3:]
            assert np.abs(got[..., :3] * a - want[..., :3] * a).max() <= 255
    finally:
        slide.close()


@pytest.mark.parametrize("shape", [(37, 53, 3), (300, 1, 3)])
def test_levels_as_vips_tiffsave_pyramid(tmp_path, shape):
    """Same level count, tile, pages, photometric and default compression as ``vips tiffsave --tile --pyramid``;
    the sizes are ⌈n/2⌉ where vips's are ⌊n/2⌋ (300×1: one level, as vips)."""
    pyvips = pytest.importorskip("pyvips")
    path = tmp_path / "ours.tif"
    writer, _, levels = _write(path, "rgb8", _pyramid, shape)
    image = pyvips.Image.new_from_array(writer.encode(levels[0]), interpretation="srgb")
    image.tiffsave(str(tmp_path / "vips.tif"), tile=True, pyramid=True, tile_width=TILE, tile_height=TILE)
    with tifffile.TiffFile(path) as ours, tifffile.TiffFile(tmp_path / "vips.tif") as theirs:
        a, b = ours.pages, theirs.pages
        for p, q in zip(a, b, strict=False):
            assert (p.subfiletype, p.photometric, p.compression, p.tilewidth, p.planarconfig, p.dtype) == \
                   (q.subfiletype, q.photometric, q.compression, q.tilewidth, q.planarconfig, q.dtype)
        assert len(a) == len(b) == len(writer.sizes)
        floor = ceil = shape[:2]
        for p, q in zip(a, b, strict=True):  # vips: ⌊n/2⌋; ours: ⌈n/2⌉
            assert (q.shape[:2], p.shape[:2]) == (floor, ceil)
            floor, ceil = (floor[0] // 2, floor[1] // 2), ((ceil[0] + 1) // 2, (ceil[1] + 1) // 2)


@pytest.mark.parametrize(("options", "kind", "says"), [
    ({"tile_size": 1}, "rgb8", "multiple of 16"),
    ({"tile_size": 24}, "rgb8", "multiple of 16"),
    ({"overlap": 1}, "rgb8", "do not overlap"),
    ({"suffix": "jpeg"}, "rgb8", "--compression"),
    ({"compression": "webp2"}, "rgb8", "unknown --compression"),
    ({"compression": "lzw:3"}, "rgb8", "unknown --compression"),
    ({"quality": 80}, "rgb8", "jpeg only"),
    ({"compression": "jpeg", "quality": 0}, "rgb8", "1 to 100"),
    ({"compression": "jpeg"}, "rgba8", "without alpha"),
    ({"compression": "jpeg"}, "rgba16", "8-bit"),
    ({}, "rgb8", "is a directory"),
])
def test_refused_before_any_work(tmp_path, options, kind, says):
    c = 4 if kind.startswith("rgba") else 3
    path = tmp_path / "x.tif"
    if says == "is a directory":
        path.mkdir()
    writer = writer_class("tiff")(str(path), _info(kind), (37, 53), c,
                                  TileOptions(**{"tile_size": TILE, **options}))
    with pytest.raises(UsageError if says != "is a directory" else OutputError, match=says):
        writer.check()
    assert os.listdir(tmp_path) == ([] if says != "is a directory" else ["x.tif"])


@pytest.mark.parametrize("codec", [None, "jpeg"])  # the reduced levels kept as values, or compressed as they come
def test_abort_leaves_the_previous_output(tmp_path, codec):
    path = tmp_path / "a.tif"
    path.write_bytes(b"previous")
    writer = writer_class("tiff")(str(path), _info("rgb8"), (37, 53), 3, TileOptions(tile_size=TILE,
                                                                                    compression=codec))
    levels = _pyramid(_picture(37, 53, 3), len(writer.sizes))
    writer.rows(0, 0, levels[0][:20])
    writer.rows(1, 0, levels[1][:18])  # a row of tiles of level 1 complete (compressed, with JPEG), one not
    writer.abort()
    assert os.listdir(tmp_path) == ["a.tif"] and path.read_bytes() == b"previous"
    fresh = writer_class("ome-tiff")(str(tmp_path / "b.ome.tif"), _info("rgb8"), (37, 53), 3, TileOptions())
    fresh.abort()  # before any row: nothing to remove
    assert os.listdir(tmp_path) == ["a.tif"]


def test_a_failing_file_is_an_output_error_and_aborts_clean(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    path = tmp_path / "f.tif"
    writer = writer_class("tiff")(str(path), _info("rgb8"), (37, 53), 3, TileOptions(tile_size=TILE))
    levels = _pyramid(_picture(37, 53, 3), len(writer.sizes))
    monkeypatch.setattr(tifffile.TiffWriter, "write", full)
    with pytest.raises(OutputError, match=f"cannot write {path}: No space left on device"):
        for y in range(0, 37, 8):
            writer.rows(0, y, levels[0][y:y + 8])
        writer.finish()
    writer.abort()
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("codec", [None, "jpeg"])  # the reduced levels kept as values, or compressed as they come
def test_a_failing_spill_is_an_output_error(tmp_path, monkeypatch, codec):
    from pyramid_cli.imageio.tilesets import tiff

    def full(*args):
        raise OSError(28, "No space left on device")

    path = tmp_path / "g.ome.tif"
    writer = writer_class("ome-tiff")(str(path), _info("rgb8"), (37, 53), 3,
                                      TileOptions(tile_size=TILE, compression=codec))
    levels = _pyramid(_picture(37, 53, 3), len(writer.sizes))
    writer.rows(0, 0, levels[0])
    monkeypatch.setattr(tiff.os, "pwrite", full)
    with pytest.raises(OutputError, match="No space left on device .in the temporary file of its reduced levels"):
        writer.rows(1, 0, levels[1])
        writer.finish()
    monkeypatch.undo()
    writer.abort()
    assert os.listdir(tmp_path) == []
