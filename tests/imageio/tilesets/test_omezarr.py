"""OME-Zarr multiscales (pyramid_cli.imageio.tilesets.omezarr), fed levels from the float64 reference and read
back by the real client, ``ome-zarr``'s reader, with ``ome-zarr-models`` validating the metadata."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

from helpers.images import write as write_raw
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import OutputError, UsageError
from pyramid_cli.imageio.encode import encoded_rows
from pyramid_cli.imageio.tilesets import TileOptions, layout_of, omezarr, writer_class

zarr = pytest.importorskip("zarr")
# ome-zarr's reader and ome-zarr-models are imported by the tests that read with them: ome_zarr alone takes 2.5 s
# to import (dask.array, scikit-image), which every test worker would pay when it collects this file.

RNG = np.random.default_rng(27)


def reference_levels(pixels: np.ndarray, count: int) -> list[np.ndarray]:
    """Levels 0..count−1 of ``pixels`` by the float64 oracle (what the band pipeline hands the writer)."""
    import pyramid_cli as pyr

    return [np.asarray(lv, np.float32) for lv in pyr.pyramid(pixels, levels=count - 1, backend="reference")]


def feed(w, levels: list[np.ndarray]) -> None:
    """Every row of every level in bands of 5, 3, 2, 1, … rows, levels interleaved as the band pipeline does."""
    pos = [0] * len(levels)
    while any(p < len(lv) for p, lv in zip(pos, levels, strict=True)):
        for k, lv in enumerate(levels):
            n = max(1, 5 - 2 * k)
            if pos[k] < len(lv):
                w.rows(k, pos[k], np.ascontiguousarray(lv[pos[k]:pos[k] + n]))
                pos[k] += n


def load(path) -> tuple[dict, list[np.ndarray]]:
    """What ome-zarr's reader finds: the image node's metadata and every level as numpy (c, y, x)."""
    reader, ome_io = pytest.importorskip("ome_zarr.reader"), pytest.importorskip("ome_zarr.io")
    nodes = list(reader.Reader(ome_io.parse_url(str(path)))())
    assert nodes, f"ome-zarr found no image at {path}"
    return nodes[0].metadata, [np.asarray(d) for d in nodes[0].data]


def stored(level: np.ndarray, info) -> np.ndarray:
    """The values a TIFF of ``info``'s input stores for ``level``, as (c, y, x)."""
    return np.moveaxis(encoded_rows("x.tif", pio.Image(level, info)), 2, 0)


def picture(tmp_path, name: str, h: int, w: int, c: int, pixel_type: str):
    """A file of random values and what read_image makes of it (linear, premultiplied float32 and its info)."""
    if pixel_type in ("uint8", "uint16"):
        codes = RNG.integers(0, np.iinfo(pixel_type).max + 1, (h, w, c)).astype(pixel_type)
    else:
        codes = RNG.random((h, w, c)).astype(np.float32)
        if c == 2:
            codes[..., 0] *= codes[..., 1]  # premultiplied Y, A
    names = {1: None, 2: ["Y", "A"], 3: None}[c]
    path = write_raw(tmp_path / name, codes, pixel_type, names=names, alpha=1 if c == 2 else None)
    img = pio.read_image(path)
    return codes, img


CASES = {  # name: (file, h, w, c, pixel type, tile size) — the picture's size decides the level count
    "srgb8": ("in.png", 37, 53, 3, "uint8", 16),
    "one-pixel": ("in.png", 1, 1, 3, "uint8", 16),
    "one-row": ("in.png", 1, 300, 3, "uint8", 16),
    "float-2ch": ("in.exr", 23, 19, 2, "float", 8),
    "uint16": ("in.tif", 21, 30, 1, "uint16", 8),
    "half": ("in.exr", 9, 12, 3, "half", 4),
}


@pytest.fixture(scope="module", params=list(CASES))
def written(request, tmp_path_factory):
    tmp = tmp_path_factory.mktemp(request.param)
    name, h, w, c, pixel_type, tile = CASES[request.param]
    codes, img = picture(tmp, name, h, w, c, pixel_type)
    out = tmp / "scan.ome.zarr"
    cls = writer_class(layout_of(str(out)))
    writer = cls(str(out), img.spec, (h, w), c, TileOptions(tile_size=tile))
    writer.check()
    levels = reference_levels(img.pixels, len(writer.sizes))
    feed(writer, levels)
    report = writer.finish()
    return request.param, codes, img, levels, out, report, writer.sizes


def test_every_level_reads_back_as_fed(written):
    case, codes, img, levels, out, _, sizes = written
    meta, data = load(out)
    assert len(data) == len(levels) == len(sizes)
    for k, (got, level) in enumerate(zip(data, levels, strict=True)):
        want = stored(level, img.spec)
        assert got.shape == (level.shape[2], *sizes[k])
        assert got.dtype == (np.float16 if case == "half" else want.dtype)
        np.testing.assert_array_equal(got, want.astype(got.dtype), err_msg=f"level {k}")
    if codes.dtype != np.float32:  # level 0 holds the file's own codes
        np.testing.assert_array_equal(data[0], np.moveaxis(codes, 2, 0).astype(data[0].dtype))


def test_levels_run_until_one_fits_a_chunk(written):
    case, *_, report, sizes = written
    tile = CASES[case][5]
    assert max(sizes[-1]) <= tile and (len(sizes) == 1 or max(sizes[-2]) > tile)
    assert [lv["size"] for lv in report["levels"]] == [[w, h] for h, w in sizes]
    assert all(lv["rule"] == "ceil-half" and lv["scale"] == 2 ** lv["level"] for lv in report["levels"])


def test_axes_transforms_and_channels_validate(written):
    case, _, img, levels, out, _, _ = written
    meta, _ = load(out)
    assert [(a["name"], a["type"]) for a in meta["axes"]] == [("c", "channel"), ("y", "space"), ("x", "space")]
    for k, transforms in enumerate(meta["coordinateTransformations"]):
        s, t = 2.0 ** k, (2.0 ** k - 1) / 2
        assert transforms[0] == {"type": "scale", "scale": [1.0, s, s]}
        assert transforms[1:] == ([{"type": "translation", "translation": [0.0, t, t]}] if k else [])
    assert meta["channel_names"] == list(img.spec.channel_names)
    models = pytest.importorskip("ome_zarr_models.v05.image")
    image = models.Image.from_zarr(zarr.open_group(str(out), mode="r"))  # raises on any NGFF 0.5 violation
    ms = image.attributes.ome.multiscales[0]
    assert [d.path for d in ms.datasets] == [str(k) for k in range(len(levels))]
    assert ms.name == "scan"
    arrays = json.loads((out / "0" / "zarr.json").read_text())
    assert arrays["dimension_names"] == ["c", "y", "x"]
    assert arrays["chunk_grid"]["configuration"]["chunk_shape"][0] == 1
    assert not [n for n in os.listdir(out.parent) if n.startswith(".")]  # no staging left


def test_rgb_channels_have_their_colours(tmp_path):
    _, img = picture(tmp_path, "in.png", 3, 4, 3, "uint8")
    out = tmp_path / "rgb.zarr"
    w = omezarr.OmeZarrWriter(str(out), img.spec, (3, 4), 3, TileOptions())
    feed(w, reference_levels(img.pixels, len(w.sizes)))
    w.finish()
    omero = zarr.open_group(str(out), mode="r").attrs["ome"]["omero"]
    assert [c["color"] for c in omero["channels"]] == ["FF0000", "00FF00", "0000FF"]
    assert omero["channels"][0]["window"] == {"min": 0, "max": 255, "start": 0, "end": 255}
    assert omero["rdefs"]["model"] == "color"


def partial(path, img, size=(37, 53)):
    """A writer of ``path`` that has written some chunk rows of every level (tile 8)."""
    w = omezarr.OmeZarrWriter(str(path), img.spec, size, 3, TileOptions(tile_size=8))
    levels = reference_levels(img.pixels, len(w.sizes))
    for k, lv in enumerate(levels):
        w.rows(k, 0, lv[: max(1, len(lv) // 2)])
    return w


def test_abort_leaves_nothing_and_keeps_a_previous_output(tmp_path):
    _, img = picture(tmp_path, "in.png", 37, 53, 3, "uint8")
    out = tmp_path / "scan.ome.zarr"
    w = partial(out, img)
    w.abort()
    assert sorted(os.listdir(tmp_path)) == ["in.png"]
    # a complete output, then an interrupted run over it: the first stays, readable, as it was
    w = omezarr.OmeZarrWriter(str(out), img.spec, (37, 53), 3, TileOptions(tile_size=8))
    feed(w, reference_levels(img.pixels, len(w.sizes)))
    w.finish()
    _, before = load(out)
    w = partial(out, img)
    w.abort()
    assert sorted(os.listdir(tmp_path)) == ["in.png", "scan.ome.zarr"]
    _, after = load(out)
    assert all(np.array_equal(a, b) for a, b in zip(before, after, strict=True))


def test_a_write_error_is_one_output_error_and_abort_cleans_up(tmp_path):
    _, img = picture(tmp_path, "in.png", 20, 20, 3, "uint8")
    w = omezarr.OmeZarrWriter(str(tmp_path / "o.zarr"), img.spec, (20, 20), 3, TileOptions(tile_size=8))
    levels = reference_levels(img.pixels, len(w.sizes))
    w.rows(0, 0, levels[0][:1])  # the arrays exist now

    class Full:
        def __setitem__(self, key, value):
            raise OSError(28, "No space left on device")

    w.arrays[0] = Full()
    with pytest.raises(OutputError, match=r"cannot write .*o\.zarr: No space left on device"):
        w.rows(0, 1, levels[0][1:])
        w.finish()
    w.abort()
    assert sorted(os.listdir(tmp_path)) == ["in.png"]


@pytest.mark.parametrize("options, message", [
    (TileOptions(overlap=1), "do not overlap"),
    (TileOptions(suffix="jpeg"), "not tile files"),
    (TileOptions(compression="jpeg"), "unknown --compression jpeg"),
    (TileOptions(compression="none:3"), "unknown --compression"),
    (TileOptions(write={"colorspace": "ACEScg"}), "o.zarr: --tocolorspace ACEScg: OME-Zarr has no colour"),
])
def test_options_it_cannot_honour_are_refused(tmp_path, options, message):
    info = pio.info_for_array("x.exr", 3)
    w = omezarr.OmeZarrWriter(str(tmp_path / "o.zarr"), info, (4, 4), 3, options)
    with pytest.raises(UsageError, match=message):
        w.check()
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("compression, codec", [("blosc:3", "blosc"), ("gzip", "gzip"), ("none", None),
                                                (None, "zstd")])
def test_compression_is_honoured(tmp_path, compression, codec):
    out = omezarr.write_levels(str(tmp_path / "c.zarr"), [np.zeros((4, 4, 1), np.uint8), np.ones((2, 2, 1), np.uint8)],
                               compression=compression)
    codecs = json.loads((tmp_path / "c.zarr" / "0" / "zarr.json").read_text())["codecs"]
    assert [c["name"] for c in codecs[1:]] == ([codec] if codec else [])
    assert out[1][:].tolist() == [[[1, 1], [1, 1]]]


@pytest.mark.parametrize("name, channels, dtype", [("slide", ["R", "G", "B"], np.uint8), (None, ["Y"], np.float32),
                                                    ("scan", ["R", "G", "B", "A"], np.uint16)])
def test_the_metadata_is_what_ome_zarr_s_writer_writes(name, channels, dtype):
    """write_metadata gives the JSON that ome-zarr's ``write_multiscales_metadata`` (NGFF 0.5) gives for the same
    levels, name and metadata, and keeps other keys of an ``ome`` attribute already on the group, as it does."""
    import warnings

    with warnings.catch_warnings():  # ome-zarr 0.18 warns of its own deprecated Scaler default at import
        warnings.simplefilter("ignore", DeprecationWarning)
        writer = pytest.importorskip("ome_zarr.writer")
        fmt = pytest.importorskip("ome_zarr.format")
    datasets = [{"path": str(k), "coordinateTransformations": omezarr.level_transforms(k)} for k in range(4)]
    about = {"description": "d", "method": "pyramid_cli", "version": "0", "args": {"analysis": "box4"}}
    omero = omezarr.channel_metadata(channels, np.dtype(dtype), [(-0.5, 2.0)] * len(channels))
    groups = [zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3) for _ in range(2)]
    for g in groups:
        g.attrs["ome"] = {"kept": [1, 2]}
    writer.write_multiscales_metadata(groups[0], [dict(d) for d in datasets], fmt=fmt.FormatV05(), axes=omezarr.AXES,
                                      name=name, metadata={**about, "omero": omero})
    omezarr.write_metadata(groups[1], datasets, name, about, omero)
    theirs, ours = (json.dumps(g.attrs.asdict()) for g in groups)
    assert ours == theirs and '"kept"' in ours


def test_missing_zarr_is_a_usage_error_naming_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "zarr", None)
    with pytest.raises(UsageError, match=r"pip install 'bilinear-pyramid\[viewers\]'"):
        omezarr.OmeZarrWriter(str(tmp_path / "o.zarr"), pio.info_for_array("x.exr", 1), (4, 4), 1, TileOptions())


def test_pyr_pyramid_writes_into_a_zarr_group_or_path(tmp_path):
    import pyramid_cli as pyr

    a = RNG.random((13, 10, 2)).astype(np.float32)
    want = list(pyr.pyramid(a, levels=2, backend="reference"))
    group = zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)
    for out in (group, tmp_path / "p.ome.zarr"):
        got = list(pyr.pyramid(a, levels=2, backend="reference", out=out))
        assert [g.shape for g in got] == [(2, 13, 10), (2, 7, 5), (2, 4, 3)]
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g[:], np.moveaxis(w, 2, 0))
    assert group.attrs["ome"]["multiscales"][0]["axes"][0] == {"name": "c", "type": "channel"}
    _, data = load(tmp_path / "p.ome.zarr")
    np.testing.assert_array_equal(data[2], np.moveaxis(want[2], 2, 0))
