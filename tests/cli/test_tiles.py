"""``pyramid tiles``: options in, one run per input, --json, -v, refusals as one line and their exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers.cli import invoke
from helpers.fake_tiles import RecordingWriter
from helpers.images import write
from pyramid_cli.cli.tiles import LAYOUT_NAMES
from pyramid_cli.imageio import tilesets

pytestmark = pytest.mark.cli


@pytest.fixture
def recording(monkeypatch):
    monkeypatch.setattr(tilesets, "writer_class", lambda layout: RecordingWriter)
    RecordingWriter.made = []
    return RecordingWriter.made


@pytest.fixture(scope="module")
def src(tmp_path_factory):
    d = tmp_path_factory.mktemp("tiles")
    rng = np.random.default_rng(0)
    write(d / "rgb.png", (rng.random((21, 34, 3)) * 255).astype(np.uint8), "uint8")
    write(d / "rgba.png", (rng.random((9, 12, 4)) * 255).astype(np.uint8), "uint8")
    return d


def test_the_layouts_are_the_writers():
    assert set(LAYOUT_NAMES) == set(tilesets.LAYOUTS)


def test_help_has_examples():
    r = invoke("tiles", "--help")
    assert r.exit_code == 0 and "pyramid tiles scan.tif scan.dzi" in r.output and "--tile-size" in r.output


def test_json_and_verbose(recording, src, tmp_path):
    out = tmp_path / "scan.dzi"
    r = invoke("tiles", src / "rgb.png", out, "--json", "-v", "--backend", "cpu", "--analysis", "box4",
               "--tile-size", "16", "--overlap", "2", "--quality", "90", "--compression", "deflate", "--type", "uint8")
    assert r.exit_code == 0, r.output
    doc = json.loads(r.stdout)
    assert doc["path"] == str(out) and doc["input"] == str(src / "rgb.png") and doc["analysis"] == "box4"
    assert doc["backend"].startswith("cpu") and [lv["size"] for lv in doc["levels"]][:2] == [[34, 21], [17, 11]]
    (w,) = recording
    o = w.options
    assert (o.tile_size, o.overlap, o.quality, o.compression, o.suffix) == (16, 2, 90, "deflate", "jpeg")
    assert o.write == {"pixel_type": "uint8", "dither": False}
    assert "layout dz, 7 level(s)" in r.stderr and "streams in bands" in r.stderr and "sRGB" in r.stderr


def test_alpha_makes_png_tiles_and_refuses_jpeg(recording, src, tmp_path):
    r = invoke("tiles", src / "rgba.png", tmp_path / "a.dzi", "-v", "--backend", "cpu")
    assert r.exit_code == 0, r.output
    assert recording[0].options.suffix == "png" and "PNG tiles" in r.stderr
    r = invoke("tiles", src / "rgba.png", tmp_path / "a.dzi", "--format", "jpg", "--backend", "cpu")
    assert r.exit_code == 2 and "JPEG tiles hold no alpha" in r.stderr and len(r.stderr.splitlines()) == 1


def test_a_batch_with_a_shard_and_json(recording, src, tmp_path):
    r = invoke("tiles", src / "*.png", "-o", tmp_path / "{stem}.ome.zarr", "--shard", "1/2", "--json",
               "--backend", "cpu")
    assert r.exit_code == 0, r.output
    (doc,) = json.loads(r.stdout)
    assert doc["path"].endswith("rgb.ome.zarr") and recording[0].options.suffix is None


@pytest.mark.parametrize("args, code, says", [
    (("{src}/missing.png", "{tmp}/x.dzi"), 3, "missing.png"),
    (("{src}/rgb.png", "{tmp}/x.png"), 2, "cannot tell the layout"),
    (("{src}/rgb.png", "{tmp}/x.zarr", "--format", "png"), 2, "stores no tile files"),
    (("{src}/rgb.png", "{tmp}/file/x.dzi"), 4, "x.dzi"),
    (("{src}/rgb.png", "{tmp}/x.dzi", "--tile-size", "0"), 2, "tile-size"),
])
def test_refusals_are_one_line(recording, src, tmp_path, args, code, says):
    (tmp_path / "file").write_text("a file, not a folder")
    r = invoke("tiles", *[a.format(src=src, tmp=tmp_path) for a in args], "--backend", "cpu")
    assert r.exit_code == code, r.output
    assert says in r.stderr and "Traceback" not in r.output
    assert all(w.state == "aborted" for w in recording)
