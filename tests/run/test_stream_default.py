"""Streaming by default: a picture from ``stream.STREAM_PIXELS`` streams on the CPU executor even when it fits
the memory budget (faster: decoding, computing and encoding overlap), and writes the whole run's bytes.

The fast tests lower the threshold so that small pictures stream; the slow one runs a megapixel picture as
shipped."""

from __future__ import annotations

import filecmp

import pytest

from helpers.images import noise, write
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.jobs.work import Levels, blur_work
from pyramid_cli.run import stream
from pyramid_cli.run.pipeline import process, write_levels_files
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.settings import WriteOptions

WHOLE = 1 << 62  # STREAM_PIXELS that no picture reaches: the whole run


def run(session, src, out, work, *, mip=False, write_options=None):
    said = []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    process([str(src), str(out)], None, work, session, mip_tile=16 if mip else None, reporter=rep,
            write=write_options)
    return " | ".join(said)


@pytest.mark.parametrize("name, pixel_type, work, options", [
    ("in.png", "uint8", blur_work(sigma=3.0), WriteOptions(dither=True)),   # dithering lines up across bands
    ("in.png", "uint8", blur_work(3), None),                                # rounding
    ("in.exr", "half", blur_work(4), None),                                 # half in, half out
    ("in.tif", "float", blur_work(sigma=2.5), WriteOptions(compression="zip")),
])
def test_a_default_run_streams_and_writes_the_whole_runs_file(tmp_path, session, small_pictures_stream, name,
                                                              pixel_type, work, options):
    src = tmp_path / name
    write(src, noise(150, 97, 3, seed=11), pixel_type)
    out = name.replace("in.", "{}.")
    said = run(session, src, tmp_path / out.format("s"), work, write_options=options)
    assert "faster than whole" in said and "streamed in bands of 8 rows" in said, said
    small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
    said = run(session, src, tmp_path / out.format("w"), work, write_options=options)
    assert "streamed" not in said, said
    assert filecmp.cmp(tmp_path / out.format("s"), tmp_path / out.format("w"), shallow=False)


def test_a_mipmap_runs_whole_by_default(tmp_path, session, small_pictures_stream):
    """A MIP map keeps level 0 and the coarser levels until level 0's header is known: in bands it took more time
    and memory than whole (measured), so it streams only when it must (run.stream_mip)."""
    src = tmp_path / "in.png"
    write(src, noise(150, 97, 3, seed=12), "uint8")
    said = run(session, src, tmp_path / "w.tx", TextureLevels(levels=None), mip=True)
    assert "runs whole" in said and "streamed" not in said, said


def test_default_levels_stream_every_level(tmp_path, session, small_pictures_stream):
    src = tmp_path / "in.exr"
    write(src, noise(150, 97, 4, seed=13), "half")
    said = []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    streamed = write_levels_files(str(src), str(tmp_path / "s_{level}.exr"), Levels(levels=3), session, reporter=rep)
    assert any("faster than whole" in m for m in said), said
    small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
    whole = write_levels_files(str(src), str(tmp_path / "w_{level}.exr"), Levels(levels=3), session,
                               reporter=Reporter(quiet=True))
    assert len(streamed) == len(whole) == 4
    for a, b in zip(streamed, whole, strict=True):
        assert filecmp.cmp(a, b, shallow=False)


def test_what_runs_whole_by_default(session):
    """Small pictures, a wrap border (the scheduler keeps its images whole) and executors other than the CPU's."""
    plan = session.plan(blur_work(3), [(2160, 3840)])
    assert stream.speed_band(plan, session.executor) == stream.BAND_PIXELS // 3840 // 8 * 8
    assert stream.speed_band(session.plan(blur_work(3), [(512, 512)]), session.executor) is None
    assert stream.speed_band(session.plan(blur_work(3, border="wrap"), [(2160, 3840)]), session.executor) is None

    class Other:
        backend = "gl"

    assert stream.speed_band(plan, Other()) is None
    choice = stream.choose(plan, 3, 1 << 40, prefer=64)
    assert choice.faster and choice.band == 64 and choice.working_set < choice.whole
    assert "faster than whole" in choice.describe() and choice.to_json()["faster"]
    assert not stream.choose(plan, 3, 1 << 40).streams
    # over the budget: the bands of the fastest size, not the largest the budget holds (memory stays flat)
    over = stream.choose(plan, 3, choice.whole // 2, prefer=64)
    assert over.band == 64 and not over.faster
    assert stream.choose(plan, 3, choice.whole // 2).band > 64


@pytest.mark.slow
def test_a_megapixel_png_streams_as_shipped(tmp_path, session):
    src = tmp_path / "in.png"
    write(src, noise(1024, 1024, 3, seed=14), "uint8")
    said = run(session, src, tmp_path / "s.png", blur_work(sigma=8.0), write_options=WriteOptions(dither=True))
    assert "faster than whole" in said, said
    mp = pytest.MonkeyPatch()
    try:
        mp.setattr(stream, "STREAM_PIXELS", WHOLE)
        run(session, src, tmp_path / "w.png", blur_work(sigma=8.0), write_options=WriteOptions(dither=True))
    finally:
        mp.undo()
    assert filecmp.cmp(tmp_path / "s.png", tmp_path / "w.png", shallow=False)


def test_a_read_error_mid_stream_is_the_whole_runs_error_and_leaves_nothing(tmp_path, session,
                                                                          small_pictures_stream):
    """--nan fail meets a NaN in the reader's thread, past the first bands: the main thread raises the whole run's
    one-line error, the previous output stays, no temporary and no thread is left."""
    import os
    import threading

    from pyramid_cli.core.errors import DataError
    from pyramid_cli.run.settings import ReadOptions

    px = noise(150, 97, 4, seed=15)
    px[120, 50, 1] = float("nan")
    src = tmp_path / "in.exr"
    write(src, px, "float")
    out = tmp_path / "out.exr"
    out.write_bytes(b"previous")
    said = []
    for threshold in (1, WHOLE):  # streamed, then whole
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", threshold)
        with pytest.raises(DataError, match="first at x=50, y=120") as caught:
            process([str(src), str(out)], None, blur_work(3), session, read=ReadOptions(nan="fail"),
                    reporter=Reporter(quiet=True))
        said.append(str(caught.value))
        assert out.read_bytes() == b"previous" and sorted(os.listdir(tmp_path)) == ["in.exr", "out.exr"]
        assert not [t for t in threading.enumerate() if t.name in ("pyramid-read", "pyramid-write")]
    assert said[0] == said[1] and "\n" not in said[0]
