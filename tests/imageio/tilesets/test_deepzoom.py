"""Deep Zoom and static IIIF folders against ``vips dzsave`` (run here through pyvips): the same levels, tile
names, tile sizes with their overlaps and descriptors; PNG tiles hold exactly the encoded levels, JPEG tiles are
libvips's JPEG; nothing is left behind by an abort or a full disk, and the previous output survives both."""

from __future__ import annotations

import os
import resource
import signal

import numpy as np
import OpenImageIO as oiio
import pytest

import pyramid_cli as pyr
from helpers.disks import mounted
from helpers.stored import png_row_filters, read_raw
from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.imageio.read import read_image
from pyramid_cli.imageio.tilesets import TileOptions, writer_class
from pyramid_cli.imageio.tilesets.deepzoom import DeepZoomWriter, IIIF2Writer, IIIF3Writer

pyvips = pytest.importorskip("pyvips")

SIZES = [(37, 53), (1, 1), (1, 300), (255, 255), (256, 256), (510, 509)]  # (rows, cols)


def picture(h, w, c=3, seed=0):
    """8-bit pixels with smooth parts and noise (JPEG neither trivial nor hopeless)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    base = 127 + 100 * np.sin(x[..., None] / 9.0 + np.arange(c)) * np.cos(y[..., None] / 13.0)
    return np.clip(base + rng.normal(0, 12, (h, w, c)), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    """size → (8-bit pixels, the input read as the run layer reads it, its levels as far as Deep Zoom goes)."""
    d = tmp_path_factory.mktemp("src")
    out = {}
    for h, w in SIZES:
        px = picture(h, w, seed=h * 1000 + w)
        path = str(d / f"in{h}x{w}.png")
        assert oiio.ImageBuf(px).write(path)
        img = read_image(path)
        out[(h, w)] = (px, img, list(pyr.pyramid(img.pixels, backend="reference", dtype=np.float32)))
    return out


def feed(writer, levels, band=7):
    """Every row of every level, ``band`` rows at a time, levels interleaved as the band pipeline does."""
    pos = [0] * len(levels)
    while any(p < lv.shape[0] for p, lv in zip(pos, levels, strict=True)):
        for k, lv in enumerate(levels):
            if pos[k] < lv.shape[0]:
                n = min(band, lv.shape[0] - pos[k])
                writer.rows(k, pos[k], np.ascontiguousarray(lv[pos[k]:pos[k] + n], dtype=np.float32))
                pos[k] += n


def write(cls, out, img, levels, band=7, **options):
    w = cls(str(out), img.spec, img.pixels.shape[:2], img.pixels.shape[2], TileOptions(**options))
    w.check()
    assert [lv.shape[:2] for lv in levels[:len(w.sizes)]] == w.sizes
    try:
        feed(w, levels[:len(w.sizes)], band)
        return w, w.finish()
    except BaseException:
        w.abort()
        raise


def tree(root):
    """relative path → (width, height) of each tile, the text of each descriptor."""
    found = {}
    for folder, _, files in os.walk(root):
        for f in files:
            p = os.path.join(folder, f)
            rel = os.path.relpath(p, root)
            if f.endswith((".json", ".dzi")):
                found[rel] = open(p).read()
            elif f != "vips-properties.xml":  # libvips's own metadata, which we do not write
                inp = oiio.ImageInput.open(p)
                found[rel] = (inp.spec().width, inp.spec().height)
                inp.close()
    return found


def vips_image(px):
    return pyvips.Image.new_from_array(px, interpretation="srgb" if px.shape[2] >= 3 else "b-w")


def leftovers(folder):
    return sorted(n for n in os.listdir(folder) if n.startswith("."))


# ---------------------------------------------------------------- the tree is dzsave's
@pytest.mark.parametrize("size", SIZES)
def test_deep_zoom_is_dzsaves_tree(sources, tmp_path, size):
    px, img, levels = sources[size]
    (tmp_path / "ours").mkdir()
    w, report = write(DeepZoomWriter, tmp_path / "ours" / "pic.dzi", img, levels)
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"))
    ours = tree(tmp_path / "ours")
    vips = tree(tmp_path / "vips")
    assert ours == vips  # the .dzi byte for byte; every tile's name and size (overlaps included)
    assert [lv["level"] for lv in report["levels"]] == list(range(len(w.sizes) - 1, -1, -1))
    assert report["levels"][-1]["size"] == [1, 1] and report["format"] == "jpeg"
    assert not leftovers(tmp_path / "ours")


@pytest.mark.parametrize("cls", [IIIF3Writer, IIIF2Writer])
@pytest.mark.parametrize("size, tile", [((37, 53), 16), ((1, 300), 64), ((256, 256), 64), ((510, 509), 128),
                                        ((510, 509), None)])
def test_iiif_is_dzsaves_tree(sources, tmp_path, cls, size, tile):
    px, img, levels = sources[size]
    options = {} if tile is None else {"tile_size": tile}
    _, report = write(cls, tmp_path / "ours" / "pic", img, levels, **options)
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"), layout=cls.layout, **options)
    ours, vips = tree(tmp_path / "ours" / "pic"), tree(tmp_path / "vips" / "pic")
    assert ours == vips  # info.json byte for byte (id https://example.com/iiif/pic), regions, sizes
    assert report["id"] == "https://example.com/iiif/pic"
    assert len(report["levels"]) == len(eval_scale_factors(ours["info.json"]))


def eval_scale_factors(text):
    import json

    return json.loads(text)["tiles"][0]["scaleFactors"]


def test_iiif_id_and_options_as_dzsave(sources, tmp_path):
    px, img, levels = sources[(255, 255)]
    _, report = write(IIIF3Writer, tmp_path / "ours" / "pic", img, levels, tile_size=100, suffix="png",
                      iiif_id="http://localhost:8000")
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"), layout="iiif3", tile_size=100, suffix=".png",
                          id="http://localhost:8000")
    assert tree(tmp_path / "ours" / "pic") == tree(tmp_path / "vips" / "pic")
    assert report["id"] == "http://localhost:8000/pic" and report["format"] == "png"


def test_deep_zoom_options_as_dzsave(sources, tmp_path):
    px, img, levels = sources[(37, 53)]
    write(DeepZoomWriter, tmp_path / "ours" / "pic.dzi", img, levels, tile_size=8, overlap=3, suffix="png")
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"), tile_size=8, overlap=3, suffix=".png")
    assert tree(tmp_path / "ours") == tree(tmp_path / "vips")
    tiles = list((tmp_path / "ours").rglob("*.png"))
    assert tiles and set().union(*map(png_row_filters, tiles)) <= {0, 1, 2}  # formats.PNG_FILTERS, as every PNG


def test_deep_zoom_png_tiles_take_the_compression_s_row_filters(sources, tmp_path):
    """``--compression 6:none`` reaches every PNG tile: rows unfiltered, as ``vips dzsave`` writes them (read from
    its own tiles), and libvips reads each of ours as OpenImageIO does."""
    px, img, levels = sources[(37, 53)]
    write(DeepZoomWriter, tmp_path / "ours" / "pic.dzi", img, levels, tile_size=8, overlap=3, suffix="png",
          compression="6:none")
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"), tile_size=8, overlap=3, suffix=".png")
    ours, theirs = list((tmp_path / "ours").rglob("*.png")), list((tmp_path / "vips").rglob("*.png"))
    assert ours and set().union(*map(png_row_filters, ours)) == {0} == set().union(*map(png_row_filters, theirs))
    for tile in ours:
        assert np.array_equal(pyvips.Image.new_from_file(str(tile)).numpy().reshape(read_raw(tile)[0].shape),
                              read_raw(tile)[0]), tile


@pytest.mark.parametrize("suffix, within", [("webp", 12), ("tif", 0)])
def test_webp_and_tif_tiles(sources, tmp_path, suffix, within):
    """The other tile formats: dzsave's names and sizes; TIFF exactly the stored values, WebP (Q 75) close."""
    px, img, levels = sources[(37, 53)]
    w, report = write(DeepZoomWriter, tmp_path / "ours" / "pic.dzi", img, levels, tile_size=16, suffix=suffix)
    vips_image(px).dzsave(str(tmp_path / "vips" / "pic"), tile_size=16, suffix=f".{suffix}")
    assert tree(tmp_path / "ours") == tree(tmp_path / "vips") and report["format"] == suffix
    x0, y0, x1, y1 = w.tile_box(0, 1, 1)
    got = oiio.ImageBuf(os.path.join(w.tile_folder, w.tile_name(0, 1, 1))).get_pixels(oiio.UINT8)
    assert np.abs(got.astype(int) - w.encode(levels[0])[y0:y1, x0:x1]).mean() <= within


# ---------------------------------------------------------------- the pixels are the levels'
@pytest.mark.parametrize("cls, options, band", [(DeepZoomWriter, {"tile_size": 16, "overlap": 2}, 7),
                                                (DeepZoomWriter, {"tile_size": 5, "overlap": 3}, 1),
                                                pytest.param(DeepZoomWriter, {"tile_size": 1, "overlap": 1}, 1000,
                                                             marks=pytest.mark.slow),  # 2,700 tiles of 1 to 3 px
                                                (IIIF3Writer, {"tile_size": 32}, 8)])
def test_png_tiles_hold_the_encoded_levels_exactly(sources, tmp_path, cls, options, band):
    """Whatever the bands (a row at a time, whole levels), the tiles hold the stored values of their pixels."""
    _, img, levels = sources[(37, 53)]
    w, report = write(cls, tmp_path / ("pic.dzi" if cls is DeepZoomWriter else "pic"), img, levels, band,
                      suffix="png", **options)
    checked = 0
    for k in range(len(w.sizes)):
        stored = w.encode(levels[k])
        assert stored.dtype == np.uint8
        cols, rows = w.grid(k)
        for r in range(rows):
            for c in range(cols):
                x0, y0, x1, y1 = w.tile_box(k, c, r)
                tile = oiio.ImageBuf(os.path.join(w.tile_folder, w.tile_name(k, c, r))).get_pixels(oiio.UINT8)
                np.testing.assert_array_equal(tile, stored[y0:y1, x0:x1])
                checked += 1
    assert checked == sum(a * b for a, b in (lv["tiles"] for lv in report["levels"]))


def test_tiles_larger_than_the_encoders_first_buffer_are_written_whole(tmp_path):
    """Noise PNG tiles of about 190 KB (each encoder thread reads a tile back in one call into a buffer it grows
    from 64 KiB) hold every stored value, and the small edge tiles written after them only their own bytes."""
    px = np.random.default_rng(4).integers(0, 256, (300, 300, 3), dtype=np.uint8)
    path = str(tmp_path / "noise.png")
    assert oiio.ImageBuf(px).write(path)
    img = read_image(path)
    levels = list(pyr.pyramid(img.pixels, backend="reference", dtype=np.float32))
    w, _ = write(DeepZoomWriter, tmp_path / "pic.dzi", img, levels, band=64, suffix="png")
    sizes = []
    for k in range(len(w.sizes)):
        stored = w.encode(levels[k])
        cols, rows = w.grid(k)
        for r in range(rows):
            for c in range(cols):
                x0, y0, x1, y1 = w.tile_box(k, c, r)
                tile = os.path.join(w.tile_folder, w.tile_name(k, c, r))
                sizes.append(os.path.getsize(tile))
                np.testing.assert_array_equal(oiio.ImageBuf(tile).get_pixels(oiio.UINT8), stored[y0:y1, x0:x1])
    assert max(sizes) > 2 << 16 and min(sizes) < 1 << 10  # the buffer grew twice; small tiles came after


def test_jpeg_tiles_are_libvips_jpeg_of_the_levels(sources, tmp_path):
    """Each JPEG tile decodes close to the level's stored values, and its entropy-coded data is what libvips's
    JPEG writer makes of the same pixels (Q 75, 4:2:0; Q 90: 4:4:4)."""
    _, img, levels = sources[(255, 255)]
    for q in (None, 90):
        out = tmp_path / f"q{q}" / "pic.dzi"
        w, _ = write(DeepZoomWriter, out, img, levels, **({} if q is None else {"quality": q}))
        for k, r in ((0, 0), (0, 1), (2, 0)):  # a whole tile, an edge tile of 2 rows, a small level's tile
            stored = w.encode(levels[k])
            x0, y0, x1, y1 = w.tile_box(k, 0, r)
            path = tmp_path / f"q{q}" / "pic_files" / w.tile_name(k, 0, r)
            want = stored[y0:y1, x0:x1]
            got = oiio.ImageBuf(str(path)).get_pixels(oiio.UINT8)
            assert got.shape == want.shape and np.abs(got.astype(int) - want).mean() < 10  # noise at sigma 12
            ours = path.read_bytes()
            vips = vips_image(np.ascontiguousarray(want)).jpegsave_buffer(Q=q or 75, keep="none")
            assert ours[ours.index(b"\xff\xdb"):] == vips[vips.index(b"\xff\xdb"):]


# ---------------------------------------------------------------- choices and refusals
def test_alpha_defaults_to_png_and_jpeg_is_refused(tmp_path):
    px = picture(20, 30, c=4)
    px[..., 3] = np.linspace(0, 255, 30, dtype=np.uint8)[None, :]
    assert oiio.ImageBuf(px).write(str(tmp_path / "a.png"))
    img = read_image(str(tmp_path / "a.png"))
    w = DeepZoomWriter(str(tmp_path / "o.dzi"), img.spec, (20, 30), 4, TileOptions())
    w.check()
    assert w.suffix == "png"
    with pytest.raises(UsageError, match=r"o\.dzi: JPEG tiles hold no alpha"):
        DeepZoomWriter(str(tmp_path / "o.dzi"), img.spec, (20, 30), 4, TileOptions(suffix="jpeg")).check()


@pytest.mark.parametrize("cls, options, says", [
    (DeepZoomWriter, {"suffix": "gif"}, "tiles are jpeg, png, webp or tif"),
    (DeepZoomWriter, {"suffix": "png", "quality": 80}, "--quality has no effect on png tiles"),
    (DeepZoomWriter, {"quality": 0}, "--quality 0: must be 1 to 100"),
    (DeepZoomWriter, {"tile_size": 0}, "--tile-size 0"),
    (DeepZoomWriter, {"compression": "zip"}, "--compression has no effect on jpeg tiles"),
    (DeepZoomWriter, {"write": {"pixel_type": "uint16"}}, r"o\.dzi \(jpeg tiles\): --type uint16"),
    (IIIF3Writer, {"overlap": 1}, "IIIF tiles do not overlap"),
])
def test_what_the_tiles_cannot_hold_is_refused(sources, tmp_path, cls, options, says):
    _, img, _ = sources[(37, 53)]
    with pytest.raises(UsageError, match=says):
        cls(str(tmp_path / "o.dzi"), img.spec, (37, 53), 3, TileOptions(**options)).check()


def test_rows_out_of_order_are_a_bug_said_at_once(sources, tmp_path):
    _, img, levels = sources[(37, 53)]
    w = DeepZoomWriter(str(tmp_path / "o.dzi"), img.spec, (37, 53), 3, TileOptions())
    w.rows(1, 0, levels[1][:4])
    with pytest.raises(ValueError, match="level 1: rows 5..7"):
        w.rows(1, 5, levels[1][5:7])
    w.abort()
    assert os.listdir(tmp_path) == []


def test_the_registry_names_these_writers():
    assert writer_class("dz") is DeepZoomWriter and writer_class("iiif3") is IIIF3Writer
    assert writer_class("iiif") is IIIF2Writer
    assert DeepZoomWriter.level_count((510, 509), TileOptions()) == 10
    assert IIIF3Writer.level_count((700, 1100), TileOptions()) == 3
    assert IIIF3Writer.level_count((512, 512), TileOptions()) == 1


# ---------------------------------------------------------------- nothing half-written, nothing lost
def previous(out_dzi):
    """A previous Deep Zoom output at ``out_dzi``: its descriptor's and one tile's bytes."""
    files = out_dzi.with_name(out_dzi.stem + "_files")
    (files / "0").mkdir(parents=True)
    (files / "0" / "0_0.jpeg").write_bytes(b"old tile")
    out_dzi.write_bytes(b"old descriptor")
    return {str(p.relative_to(out_dzi.parent)): p.read_bytes()
            for p in out_dzi.parent.rglob("*") if p.is_file()}


def contents(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def test_abort_leaves_nothing_and_keeps_the_previous_output(sources, tmp_path):
    _, img, levels = sources[(510, 509)]
    out = tmp_path / "pic.dzi"
    old = previous(out)
    w = DeepZoomWriter(str(out), img.spec, (510, 509), 3, TileOptions())
    w.check()
    for k, lv in enumerate(levels):  # every level but the last one's rows: tiles written, not finished
        w.rows(k, 0, lv[:max(1, lv.shape[0] - 1)].astype(np.float32))
    w.abort()
    assert contents(tmp_path) == old and not leftovers(tmp_path)


def test_finish_replaces_the_previous_output(sources, tmp_path):
    _, img, levels = sources[(37, 53)]
    out = tmp_path / "pic.dzi"
    previous(out)
    write(DeepZoomWriter, out, img, levels)
    assert out.read_bytes().startswith(b"<?xml") and not leftovers(tmp_path)
    assert (tmp_path / "pic_files" / "0" / "0_0.jpeg").read_bytes() != b"old tile"


@pytest.mark.parametrize("encoder", ["imagecodecs", "openimageio"])
def test_a_tile_the_encoder_fails_on_is_one_line_naming_the_output(sources, tmp_path, monkeypatch, encoder):
    from pyramid_cli.imageio.tilesets import deepzoom
    from pyramid_cli.imageio.write import WriteFailed

    def fail(out, ok, what):
        raise WriteFailed(f"{what} failed: no room in the codec")

    def failing(quality):
        def encode(tile):
            raise RuntimeError("no room in the codec")
        return encode

    if encoder == "openimageio":
        monkeypatch.setattr(deepzoom, "libjpeg", lambda quality: None)
        monkeypatch.setattr(deepzoom, "checked", fail)
    else:
        monkeypatch.setattr(deepzoom, "libjpeg", failing)
    _, img, levels = sources[(37, 53)]
    out = tmp_path / "pic.dzi"
    old = previous(out)
    says = "open failed" if encoder == "openimageio" else "encode failed"
    with pytest.raises(OutputError, match=rf"^cannot write .*pic\.dzi: \d+/\d+_\d+\.jpeg: {says}: no room in the "
                                          r"codec$"):
        write(DeepZoomWriter, out, img, levels)
    assert contents(tmp_path) == old and not leftovers(tmp_path)


@pytest.mark.parametrize("channels, quality", [(3, None), (3, 90), (1, None), (1, 95)])
def test_jpeg_tiles_are_the_same_bytes_whichever_library_encodes_them(tmp_path, monkeypatch, channels, quality):
    """imagecodecs's libjpeg-turbo (the viewers extra) and OpenImageIO's, less its empty Exif segment, write every
    tile of a Deep Zoom the same, byte for byte: 4:2:0 below Q 90, 4:4:4 from it, grey and RGB, edge tiles of one
    pixel's width included."""
    from pyramid_cli.imageio.tilesets import deepzoom

    pytest.importorskip("imagecodecs")
    px = picture(300, 257, channels, seed=9)
    path = str(tmp_path / "in.png")
    assert oiio.ImageBuf(px).write(path)
    img = read_image(path)
    levels = list(pyr.pyramid(img.pixels, backend="reference", dtype=np.float32))
    options = {} if quality is None else {"quality": quality}
    write(DeepZoomWriter, tmp_path / "a" / "pic.dzi", img, levels, **options)
    monkeypatch.setattr(deepzoom, "libjpeg", lambda quality: None)
    write(DeepZoomWriter, tmp_path / "b" / "pic.dzi", img, levels, **options)
    files = {}
    for side in ("a", "b"):
        root = tmp_path / side / "pic_files"
        files[side] = {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*.jpeg")}
    assert files["a"] == files["b"] and len(files["a"]) > 10
    assert all(b"Exif" not in data[:64] for data in files["a"].values())


@pytest.mark.parametrize("cls", [DeepZoomWriter, IIIF3Writer])
def test_a_full_disk_is_one_line_and_keeps_the_previous_output(sources, tmp_path, cls):
    _, img, levels = sources[(510, 509)]
    with mounted(tmp_path / "small", "size=96k") as disk:
        out = disk / "pic.dzi"
        old = previous(out)
        with pytest.raises(OutputError) as e:
            write(cls, out if cls is DeepZoomWriter else disk / "pic", img, levels, suffix="png")
        msg = e.value.message
        assert "\n" not in msg and "the disk is full" in msg and str(disk / "pic") in msg
        assert contents(disk) == old and not leftovers(disk)


def test_a_file_size_limit_too_small_for_a_tile_is_refused_first(sources, tmp_path):
    _, img, _ = sources[(37, 53)]
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, hard))
    try:
        with pytest.raises(OutputError, match=r"pic\.dzi: a tile may need up to \d+ bytes, over the file size limit"):
            DeepZoomWriter(str(tmp_path / "pic.dzi"), img.spec, (37, 53), 3, TileOptions()).check()
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, handler)
