"""``pyramid mipmap`` held whole with level 0 written as read (:mod:`pyramid_cli.run.mip_whole`): the file the
whole-picture run (:func:`pyramid_cli.run.local.run_jobs`) writes, checked level by level and header by header."""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.images import noise, write
from helpers.mipfiles import assert_same_file, levels
from pyramid_cli.exec.cpu import CPUExecutor
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.run import batch, local, mip_whole
from pyramid_cli.run.local import run_jobs
from pyramid_cli.run.pipeline import process
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.settings import ReadOptions, WriteOptions

AS_READ = "level 0 written as read"


def new(session, src, out, read=None, write=None, **kw) -> list[str]:
    """``pyramid mipmap`` through the pipeline; what it said with -v."""
    said: list[str] = []
    process([str(src), str(out)], None, TextureLevels(levels=None, **kw), session, mip_tile=16,
            read=read, write=write, reporter=Reporter(verbose=True, out=said.append, err=said.append))
    return said


def old(session, src, out, read=None, write=None, **kw) -> None:
    """The whole-picture run as it was before level 0 was written as read."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(local, "_level0_as_read", lambda *args: None)
        report = run_jobs([batch.Job(str(src), str(out))], TextureLevels(levels=None, **kw), session,
                          read=read or ReadOptions(), write=write or WriteOptions(), reporter=Reporter(quiet=True),
                          mip_tile=16, many=False)
    assert not report.failed, report.failed


def rgb8(h: int, w: int, c: int = 3, seed: int = 0) -> np.ndarray:
    return (noise(h, w, c, seed=seed) * 255).astype(np.uint8)


@pytest.mark.parametrize("name, out, pixels, pixel_type, kw, as_read", [
    ("in.png", "t.tx", rgb8(300, 37), "uint8", {}, True),                  # two hash blocks, an odd width
    ("in.png", "t.tx", rgb8(45, 300, 1), "uint8", {"border": "mirror"}, True),  # one channel, one block
    ("in.tif", "t.tx", (noise(70, 130, 3, seed=2) * 65535).astype(np.uint16), "uint16", {}, True),
    ("in.exr", "t.exr", noise(161, 90, seed=3), "half", {"rounding": "up"}, False),  # half: runs as before
    ("in.png", "t.exr", rgb8(64, 80), "uint8", {}, False),         # stored as half: runs as before
    ("in.png", "t.tx", rgb8(64, 80, 4), "uint8", {}, False),       # straight alpha: premultiplied when decoded
    ("in.exr", "t.exr", noise(64, 80, seed=5), "float", {}, False),  # float: every value cannot be checked
])
def test_the_file_is_the_whole_runs(tmp_path, session, name, out, pixels, pixel_type, kw, as_read):
    src = tmp_path / name
    write(src, pixels, pixel_type)
    said = new(session, src, tmp_path / out, **kw)
    old(session, src, tmp_path / f"old_{out}", **kw)
    assert_same_file(tmp_path / out, tmp_path / f"old_{out}")
    assert any(AS_READ in m for m in said) == as_read, said
    assert sorted(os.listdir(tmp_path)) == sorted([name, out, f"old_{out}"])  # no temporary left


@pytest.mark.parametrize("pixels, kw", [
    (rgb8(300, 37), {}), (rgb8(97, 131), {"border": "mirror", "rounding": "up"}),
    (rgb8(64, 200, 1), {"border": "zero"}),
    ((noise(70, 130, 3, seed=2) * 65535).astype(np.uint16), {}),
])
def test_the_levels_made_from_codes_in_bands_are_the_whole_runs(tmp_path, session, small_pictures_stream, pixels, kw):
    """8/16-bit codes read by the executor through their table, band by band on the scheduler (here in bands of a
    few rows), each band of every level encoded as it is made: the same file."""
    src = tmp_path / ("in.png" if pixels.dtype == np.uint8 else "in.tif")
    write(src, pixels, pixels.dtype.name)
    said = new(session, src, tmp_path / "t.tx", **kw)
    old(session, src, tmp_path / "o.tx", **kw)
    assert_same_file(tmp_path / "t.tx", tmp_path / "o.tx")
    assert any(AS_READ in m for m in said), said


def test_a_batch_writes_each_level_0_as_read_where_it_can(tmp_path, session):
    """Several inputs (``run_jobs``, decoding and encoding beside the work): 8/16-bit inputs the output keeps are
    read as stored and written from their codes; the others as before; every file the whole run's."""
    ins = tmp_path / "in"
    pictures = {"a.png": rgb8(300, 37), "b.png": rgb8(45, 61, 1), "c.tif": (noise(70, 130, 3, seed=2) * 65535)
                .astype(np.uint16), "d.png": rgb8(64, 80, 4)}
    for name, px in pictures.items():
        write(ins / name, px, px.dtype.name)
    said: list[str] = []
    report = process([str(ins / "*.*")], str(tmp_path / "out" / "{stem}.tx"), TextureLevels(levels=None), session,
                     mip_tile=16, reporter=Reporter(verbose=True, out=said.append, err=said.append))
    assert len(report.done) == 4 and not report.failed, report
    for name in pictures:
        stem = name.split(".")[0]
        old(session, ins / name, tmp_path / f"{stem}_old.tx")
        assert_same_file(tmp_path / "out" / f"{stem}.tx", tmp_path / f"{stem}_old.tx")
    assert sum(AS_READ in m for m in said) == 3, said  # not the RGBA one: straight alpha
    assert sorted(os.listdir(tmp_path / "out")) == ["a.tx", "b.tx", "c.tx", "d.tx"]


@pytest.mark.parametrize("many", [False, True])
def test_the_reference_backend_writes_level_0_as_read_too(tmp_path, many):
    """The reference runs no plans: the levels are made from the decoded codes by the float64 oracle, level 0
    written as read, one input or a batch (this was exit 6, "the reference backend runs jobs, not plans")."""
    src = tmp_path / "in.png"
    write(src, rgb8(40, 29), "uint8")
    with Session("reference") as session:
        paths, template = ([str(src)], str(tmp_path / "{stem}_t.tx")) if many else ([str(src), str(tmp_path /
                                                                                       "in_t.tx")], None)
        said: list[str] = []
        report = process(paths, template, TextureLevels(levels=None), session, mip_tile=16,
                         reporter=Reporter(verbose=True, out=said.append, err=said.append))
        assert report.done and not report.failed, report
        old(session, src, tmp_path / "o.tx")
    assert_same_file(tmp_path / "in_t.tx", tmp_path / "o.tx")
    assert any(AS_READ in m for m in said), said


@pytest.mark.parametrize("options, as_read", [
    (WriteOptions(dither=True), False),         # the dither pattern depends on the place
    (WriteOptions(pixel_type="uint16"), False),  # stored otherwise
    (WriteOptions(compression="none"), True),
])
def test_write_options_decide_whether_level_0_is_written_as_read(tmp_path, session, options, as_read):
    src = tmp_path / "in.png"
    write(src, rgb8(90, 70), "uint8")
    said = new(session, src, tmp_path / "t.tx", write=options)
    old(session, src, tmp_path / "o.tx", write=options)
    assert_same_file(tmp_path / "t.tx", tmp_path / "o.tx")
    assert any(AS_READ in m for m in said) == as_read, said


def test_a_constant_picture_detected_shrinks_as_before(tmp_path, session):
    src = tmp_path / "in.png"
    write(src, np.full((64, 64, 3), 77, np.uint8), "uint8")
    new(session, src, tmp_path / "t.tx", constant_detect=True)
    old(session, src, tmp_path / "o.tx", constant_detect=True)
    assert_same_file(tmp_path / "t.tx", tmp_path / "o.tx")
    spec = oiio.ImageInput.open(str(tmp_path / "t.tx")).spec()
    assert (spec.width, spec.height) == (16, 16) and spec.get_string_attribute("oiio:ConstantColor")


def test_a_failure_of_the_work_stops_level_0_and_leaves_nothing(tmp_path, monkeypatch):
    """The plan fails while level 0 is being written: the write stops at its next band, the error is raised,
    and neither the output nor a temporary is left."""
    pytest.importorskip("numba")
    src = tmp_path / "in.png"
    write(src, rgb8(2000, 300), "uint8")
    monkeypatch.setattr(mip_whole, "WRITE_ROWS", 8)
    bands = []
    real = mip_whole.write_levels

    def level0(writer, level, levels, stop):
        real(writer, level, levels, stop)
        bands.append(writer.written)

    def fail(*args, **kwargs):
        raise RuntimeError("the plan failed")

    monkeypatch.setattr(mip_whole, "write_levels", level0)
    monkeypatch.setattr(CPUExecutor, "run_outputs", fail)
    with Session("cpu") as session, pytest.raises(RuntimeError, match="the plan failed"):
        new(session, src, tmp_path / "t.tx")
    assert bands and bands[0] < 2000  # stopped before the last row
    assert sorted(os.listdir(tmp_path)) == ["in.png"]


@pytest.mark.slow
def test_a_signal_while_level_0_is_written(tmp_path):
    """SIGTERM while the input is read, level 0 written or the coarser levels computed: exit 143 with the previous
    output kept, or the complete file; no temporary left, never a traceback."""
    from helpers.cli import CLI
    from helpers.interrupt import interrupt_runs

    pytest.importorskip("numba")
    import subprocess
    import time

    big = tmp_path / "big.png"
    write(big, rgb8(3000, 3000), "uint8")
    out = tmp_path / "out.tx"
    cmd = CLI + ["mipmap", "-v", "--backend", "cpu", big, out]
    took = []
    for _ in range(2):  # the first run may compile the kernels: the second is what the signals are timed by
        start = time.perf_counter()
        subprocess.run([str(c) for c in cmd], check=True, capture_output=True)
        took.append(time.perf_counter() - start)
    stopped = interrupt_runs(cmd, out, [f * min(took) for f in (0.35, 0.55, 0.75)],
                             lambda f: len(levels(f)) == 12)
    assert stopped, "no run was interrupted: make the picture larger"
