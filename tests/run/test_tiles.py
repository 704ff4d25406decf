"""``pyramid tiles``' run layer (issue 27): every level streamed into one writer, held to the float64 reference."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from helpers.fake_tiles import TRAILER, RecordingWriter
from helpers.images import write
from pyramid_cli import imageio as io
from pyramid_cli.core.errors import InputError, OutputError, UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.imageio import tilesets
from pyramid_cli.imageio.tilesets import TileOptions
from pyramid_cli.reference.pyramids import levels_reference
from pyramid_cli.run import tiles as run_tiles
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.tiles import TileSettings, tile_file, tile_files, tile_format, tiles


@pytest.fixture
def recording(monkeypatch):
    """Every layout written by :class:`RecordingWriter`; the writers made so far."""
    monkeypatch.setattr(tilesets, "writer_class", lambda layout: RecordingWriter)
    RecordingWriter.made = []
    return RecordingWriter.made


def premultiplied(h, w, seed=0):
    rng = np.random.default_rng(seed)
    px = rng.random((h, w, 4))
    px[..., :3] *= px[..., 3:]
    return px


def assert_reference(writer, pixels, analysis="quadratic", border="clamp"):
    ref = levels_reference(pixels, len(writer.sizes) - 1, analysis, border)
    assert [lv.shape[:2] for lv in ref] == writer.sizes
    for k, (got, want) in enumerate(zip(writer.levels, ref, strict=True)):
        np.testing.assert_allclose(got, want, rtol=0, atol=2e-6, err_msg=f"level {k}")


@pytest.mark.parametrize("size, analysis, border, memory", [
    ((133, 53), "quadratic", "clamp", "600K"),    # odd sizes at most levels, in several bands
    ((64, 45), "box4", "mirror", None),           # whole budget: one band
    ((1, 1), "quadratic", "clamp", None),         # one level: no plan
    ((1, 1000), "cubic", "zero", None),           # a row: 11 levels
])
def test_every_level_is_the_reference_at_every_pixel(recording, session, tmp_path, size, analysis, border, memory):
    px = premultiplied(*size)
    report = tiles(px, tmp_path / "x.dzi", analysis=analysis, border=border, memory=memory, session=session,
                   tile_size=8)
    (writer,) = recording
    assert writer.state == "finished"
    assert_reference(writer, px, analysis, border)
    assert report["input"] == "array" and report["analysis"] == analysis and report["border"] == border
    assert len(report["levels"]) == len(writer.sizes) and report["seconds"] >= 0
    if memory is not None:  # streamed in several bands, the levels interleaved as they were made
        assert report["band"] < writer.sizes[1][0]
        first_of_level1 = next(i for i, c in enumerate(writer.calls) if c[0] == 1)
        last_of_level0 = max(i for i, c in enumerate(writer.calls) if c[0] == 0)
        assert first_of_level1 < last_of_level0


def test_a_very_wide_row_streams(recording, session, tmp_path):
    px = np.random.default_rng(1).random((1, 100000, 1))
    report = tiles(px, tmp_path / "wide.dzi", session=session)
    (writer,) = recording
    assert len(report["levels"]) == 18 and writer.sizes[-1] == (1, 1)
    assert_reference(writer, px)


def test_the_reference_backend_runs_whole_and_refuses_memory(recording, tmp_path):
    px = premultiplied(9, 7)
    with Session("reference") as s:
        report = tiles(px, tmp_path / "x.dzi", session=s)
        assert report["band"] is None
        assert_reference(recording[0], px)
        with pytest.raises(UsageError, match="reference"):
            tiles(px, tmp_path / "x.dzi", session=s, memory="1G")


def test_a_file_level_0_is_the_decoded_input(recording, session, tmp_path):
    src = tmp_path / "in.png"
    codes = (np.random.default_rng(2).random((23, 31, 3)) * 255).astype(np.uint8)
    write(src, codes, "uint8")
    out = tmp_path / "out.dzi"
    report = tile_file(str(src), str(out), TileSettings(), session)
    (writer,) = recording
    decoded = io.read_image(str(src)).pixels
    np.testing.assert_array_equal(writer.levels[0], decoded)
    assert_reference(writer, decoded.astype(np.float64))
    assert out.read_bytes() == TRAILER and report["format"] == "jpeg" and report["input"] == str(src)


class Failing(RecordingWriter):
    error: BaseException = OutputError("cannot write x.dzi: No space left on device")

    def _rows(self, level, y0, pixels, owned=False):
        if level == 2:
            raise self.error
        super()._rows(level, y0, pixels)


@pytest.mark.parametrize("error", [OutputError("cannot write x: No space left on device"), KeyboardInterrupt()])
def test_any_failure_aborts_and_keeps_the_previous_output(monkeypatch, session, tmp_path, error):
    monkeypatch.setattr(tilesets, "writer_class", lambda layout: Failing)
    monkeypatch.setattr(Failing, "error", error)
    Failing.made = []
    out = tmp_path / "x.dzi"
    out.write_bytes(b"previous")
    with pytest.raises(type(error)):
        tiles(premultiplied(40, 40), str(out), session=session, memory="1M", tile_size=8)
    assert Failing.made[0].state == "aborted"
    assert out.read_bytes() == b"previous"
    assert [p.name for p in tmp_path.iterdir()] == ["x.dzi"]


def test_tile_formats(recording, session):
    rgba = io.info_for_array("x.dzi", 4)
    rgb = io.info_for_array("x.dzi", 3)
    said = []
    rep = Reporter(verbose=True, err=said.append)
    assert tile_format("dz", TileOptions(), rgb, rep, "in").suffix == "jpeg"
    assert tile_format("iiif3", TileOptions(), rgba, rep, "in").suffix == "png" and "alpha" in said[-1]
    assert tile_format("dz", TileOptions(suffix="jpg"), rgb, rep, "in").suffix == "jpeg"
    assert tile_format("dz", TileOptions(suffix="webp"), rgba, rep, "in").suffix == "webp"
    assert tile_format("ome-zarr", TileOptions(), rgba, rep, "in").suffix is None
    with pytest.raises(UsageError, match="alpha"):
        tile_format("dz", TileOptions(suffix="jpeg"), rgba, rep, "in")
    with pytest.raises(UsageError, match="tiff layout"):
        tile_format("tiff", TileOptions(suffix="png"), rgb, rep, "in")


def test_refusals_before_any_work(recording, session, tmp_path):
    with pytest.raises(UsageError, match="cannot tell the layout"):
        tiles(premultiplied(4, 4), str(tmp_path / "x.png"), session=session)
    with pytest.raises(InputError):
        tile_file(str(tmp_path / "missing.png"), str(tmp_path / "x.dzi"), TileSettings(), session)
    src = tmp_path / "in.tif"
    write(src, np.zeros((4, 4, 3), np.uint8), "uint8")
    with pytest.raises(OutputError, match="overwrite input"):
        tile_file(str(src), str(src), TileSettings(), session)
    assert recording == []


def test_batches_and_shards(recording, session, tmp_path):
    for k in range(4):
        write(tmp_path / f"in{k}.png", np.full((5, 6, 3), 40 * k, np.uint8), "uint8")
    settings = dataclasses.replace(TileSettings(), layout="dz")
    stale = tmp_path / "out" / ".in3.dzi.tmp-killed"  # a SIGKILLed run's staging folder
    (stale / "in3_files").mkdir(parents=True)
    report, described = tile_files([str(tmp_path / "in*.png")], str(tmp_path / "out" / "{stem}.dzi"), settings,
                                   session, shard="2/2", reporter=Reporter(quiet=True))
    assert [j.input.rsplit("/", 1)[1] for j in report.done] == ["in2.png", "in3.png"]
    assert [d["path"].rsplit("/", 1)[1] for d in described] == ["in2.dzi", "in3.dzi"]
    assert not stale.exists()
    (tmp_path / "in1.png").write_bytes(b"not a picture")
    report, described = tile_files([str(tmp_path / "in*.png")], str(tmp_path / "out" / "{stem}.dzi"), settings,
                                   session, keep_going=True, reporter=Reporter(quiet=True))
    assert len(report.done) == 3 and len(report.failed) == 1 and report.exit_code == 3


def test_writer_memory_is_a_tile_row_per_level_in_the_stored_type():
    sizes = [(1000, 2000), (500, 1000), (250, 500)]
    bands = run_tiles.WRITER_BANDS * 64 * 2000 * 4  # float32 bands of level 0 being encoded
    held = run_tiles.writer_memory(sizes, 3, TileOptions(tile_size=254, overlap=1), itemsize=1, band=64)
    assert held == (sum(min(h, 256) * w for h, w in sizes) + 2 * 256 * 2000 + bands) * 3
    assert run_tiles.writer_memory(sizes[2:], 1, TileOptions(), band=1000) == 3 * 250 * 500 * 4 * 2
    assert run_tiles.writer_memory(sizes, 3, TileOptions(), itemsize=2) < held * 2  # 16-bit: twice the rows


@pytest.mark.slow
def test_an_exr_input_s_codec_threads_fit_the_budget(tmp_path, monkeypatch):
    """With OpenImageIO told to use 16 threads (a 16-core machine), an EXR input's codec threads are limited to
    what the budget leaves them (run.codec_budget.Codecs.within, the input opened again), and the tiles are the same."""
    from helpers.cli import run_cli
    from helpers.images import noise

    src = write(tmp_path / "in.exr", noise(600, 700, seed=5), "half")
    monkeypatch.setenv("OPENIMAGEIO_THREADS", "16")
    r = run_cli("tiles", src, tmp_path / "a.dzi", "--memory", "20M", "-v")
    assert r.returncode == 0 and "OpenEXR codes with" in r.stderr and "of its 16 threads" in r.stderr, r.stderr
    monkeypatch.delenv("OPENIMAGEIO_THREADS")
    r = run_cli("tiles", src, tmp_path / "b.dzi")
    assert r.returncode == 0 and "OpenEXR codes with" not in r.stderr, r.stderr
    a = sorted(p.relative_to(tmp_path / "a_files") for p in (tmp_path / "a_files").rglob("*.*"))
    assert a and a == sorted(p.relative_to(tmp_path / "b_files") for p in (tmp_path / "b_files").rglob("*.*"))
    for rel in a:
        assert (tmp_path / "a_files" / rel).read_bytes() == (tmp_path / "b_files" / rel).read_bytes(), rel
