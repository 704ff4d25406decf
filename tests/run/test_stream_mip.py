"""``pyramid mipmap`` streamed (issue 18): the same file as the whole-picture run, in bounded memory, atomic."""

from __future__ import annotations

import os

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.budgets import codecs
from helpers.cli import CLI, peak_rss, run_cli
from helpers.images import noise, write
from helpers.mipfiles import assert_same_file, levels
from pyramid_cli import imageio as io
from pyramid_cli.core.errors import UsageError
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.run import batch
from pyramid_cli.run.pipeline import process
from pyramid_cli.run.report import Reporter
from pyramid_cli.workflows import mip


def mipmap(session, src, out, memory=None, said=None, **kw):
    """``pyramid mipmap`` of ``src`` within ``memory`` bytes beside what OpenEXR's codecs hold for its files (the
    branches a test's budget picks do not depend on the input's compression)."""
    work = TextureLevels(levels=None, **kw)
    rep = Reporter(verbose=True, out=said.append, err=said.append) if said is not None else Reporter(quiet=True)
    if memory is not None:
        memory += codecs(src, [out], tile=16)
    return process([str(src), str(out)], None, work, session, mip_tile=16, memory=memory,
                   reporter=rep)


def coarser(said: str) -> str:
    """What a streamed mipmap's -v line says of its coarser levels ('' when it says nothing of them)."""
    return said.split("the coarser levels", 1)[1].split(";")[0] if "the coarser levels" in said else ""


def level0(said: str) -> str:
    """What it says of level 0 kept in memory until its header is known ('' when it reads the input twice)."""
    return said.split("; level 0 (", 1)[1].split(";")[0] if "; level 0 (" in said else ""


# ------------------------------------------------------------------ the file is the whole run's
@pytest.mark.parametrize("ext, pixel_type, size, rounding, budget, once, where", [
    # read once: level 0 kept in memory until its header is known; the coarser levels in memory or spilled
    ("exr", "half", (128, 128), "down", 520 << 10, True, "in memory"),
    ("tx", "half", (128, 128), "down", 450 << 10, True, "temporary file"),
    ("exr", "float", (128, 128), "down", 660 << 10, True, "temporary file"),
    ("tx", "uint8", (128, 128), "down", 660 << 10, True, "temporary file"),
    ("exr", "half", (160, 123), "up", 600 << 10, True, "in memory"),
    # read twice (level 0 does not fit): written as it is read the second time
    ("exr", "half", (160, 123), "up", 400 << 10, False, "in memory"),
    ("tx", "float", (150, 97), "up", 330 << 10, False, "temporary file"),
    ("tx", "uint8", (128, 128), "down", 420 << 10, False, "temporary file"),
])
def test_streamed_mipmap_is_the_whole_runs_file(tmp_path, session, ext, pixel_type, size, rounding, budget, once,
                                                 where):
    src = tmp_path / ("in.tif" if pixel_type == "uint8" else "in.exr")
    write(src, noise(*size, seed=3), pixel_type)
    said = []
    mipmap(session, src, tmp_path / f"s.{ext}", budget, said, rounding=rounding)
    chose = [m for m in said if "streams in bands" in m]
    assert len(chose) == 1 and any(m.endswith("the input read once)") == once for m in said if "wrote" in m), said
    assert bool(level0(chose[0])) == once and where in coarser(chose[0]), said
    mipmap(session, src, tmp_path / f"w.{ext}", rounding=rounding)
    assert_same_file(tmp_path / f"s.{ext}", tmp_path / f"w.{ext}")
    assert sorted(os.listdir(tmp_path)) == sorted([src.name, f"s.{ext}", f"w.{ext}"])  # no temporary left


@pytest.mark.parametrize("ext, size, border, budget", [
    ("exr", (100, 75), "clamp", 230), ("tx", (97, 131), "mirror", 420), ("exr", (128, 64), "zero", 165),
    ("tx", (161, 90), "clamp", 300)])
def test_streamed_mipmap_of_odd_sizes_resampled(tmp_path, session, ext, size, border, budget):
    """maketx's sizes ⌊n/2⌋: levels that do not halve exactly are resampled (ResamplePass), tiled too."""
    src = tmp_path / "in.exr"
    write(src, noise(*size, seed=6), "half")
    said = []
    mipmap(session, src, tmp_path / f"s.{ext}", budget << 10, said, border=border)  # the levels spill
    assert any("streamed in bands" in m for m in said) and any("temporary file" in coarser(m) for m in said), said
    mipmap(session, src, tmp_path / f"w.{ext}", border=border)
    assert_same_file(tmp_path / f"s.{ext}", tmp_path / f"w.{ext}")
    assert sorted(os.listdir(tmp_path)) == sorted([src.name, f"s.{ext}", f"w.{ext}"])


def test_streamed_mipmap_with_a_mirror_border_and_a_dithered_8_bit_texture(tmp_path, session):
    src = tmp_path / "in.png"
    write(src, noise(128, 128, 3, seed=5), "uint8")
    said = []
    for name, budget in (("s.tx", 310 << 10), ("w.tx", None)):
        process([str(src), str(tmp_path / name)], None, TextureLevels(levels=None, border="mirror"), session,
                mip_tile=16, memory=budget, reporter=Reporter(verbose=True, out=said.append, err=said.append),
                write=_dither())
    assert any("streamed in bands" in m for m in said), said
    assert_same_file(tmp_path / "s.tx", tmp_path / "w.tx")


def _dither():
    from pyramid_cli.run.settings import WriteOptions

    return WriteOptions(dither=True)


@pytest.mark.parametrize("budget, once", [(330 << 10, False), (520 << 10, True)])
def test_a_constant_picture_streamed_shrinks_as_whole(tmp_path, session, budget, once):
    """Found constant after the first of two reads, or after the one read (level 0 kept in memory)."""
    src = tmp_path / "in.exr"
    write(src, np.broadcast_to(np.float32([0.25, 0.5, 0.75, 1]), (128, 128, 4)).copy(), "half")
    said = []
    mipmap(session, src, tmp_path / "s.exr", budget, said, constant_detect=True)
    assert any("constant colour" in m for m in said), said
    assert [bool(level0(m)) for m in said if "streams in bands" in m] == [once], said
    mipmap(session, src, tmp_path / "w.exr", constant_detect=True)
    assert_same_file(tmp_path / "s.exr", tmp_path / "w.exr")
    spec = oiio.ImageInput.open(str(tmp_path / "s.exr")).spec()
    assert (spec.width, spec.height) == (16, 16) and spec.get_string_attribute("oiio:ConstantColor")
    # constant but not detected: streamed, with the constant colour in the header
    mipmap(session, src, tmp_path / "c.exr", budget)
    mipmap(session, src, tmp_path / "d.exr")
    assert_same_file(tmp_path / "c.exr", tmp_path / "d.exr")
    assert oiio.ImageInput.open(str(tmp_path / "c.exr")).spec().get_string_attribute("oiio:ConstantColor")
    assert sorted(os.listdir(tmp_path)) == ["c.exr", "d.exr", "in.exr", "s.exr", "w.exr"]


def test_what_cannot_stream_is_refused_with_memory_and_runs_whole_without(tmp_path, session):
    src = tmp_path / "in.exr"
    write(src, noise(64, 64, seed=1), "half")
    with pytest.raises(UsageError, match="--resize.*whole picture"):
        mipmap(session, src, tmp_path / "r.exr", 10 << 10, resize=True)
    with pytest.raises(Exception, match="needs at least"):
        mipmap(session, src, tmp_path / "x.exr", 4 << 10)
    assert sorted(os.listdir(tmp_path)) == ["in.exr"]
    report = mipmap(session, src, tmp_path / "w.exr", None, resize=True)  # default budget: runs whole
    assert isinstance(report, batch.Report) and (tmp_path / "w.exr").exists()
    # a batch takes --memory too (run.local.run_in_budget: each picture within it), and writes what it writes without
    (tmp_path / "in2.exr").write_bytes(src.read_bytes())
    for memory, suffix in ((1 << 20, "t"), (None, "free")):
        report = process([str(src), str(tmp_path / "in2.exr")], str(tmp_path / ("{stem}_" + suffix + ".exr")),
                         TextureLevels(levels=None), session, mip_tile=16, memory=memory, reporter=Reporter(quiet=True))
        assert len(report.done) == 2 and not report.failed
    for stem in ("in", "in2"):
        assert (tmp_path / f"{stem}_t.exr").read_bytes() == (tmp_path / f"{stem}_free.exr").read_bytes()


def test_pixel_stats_equal_the_whole_picture_functions():
    rng = np.random.default_rng(0)
    for dtype in (np.float32, np.float16, np.uint8, np.uint16):
        for h in (5, 256, 300):
            scale = np.iinfo(dtype).max if np.issubdtype(dtype, np.integer) else 1
            x = (rng.random((h, 37, 3)) * scale).astype(dtype)
            stats = mip.PixelStats(h)
            for y in range(0, h, 7):
                stats.hash_rows(x[y:y + 7])
                stats.add_encoded(x[y:y + 7])
            assert stats.average() == mip.average_color(x)  # bit for bit
            assert mip.finish_sha1(stats.sha1(), "e") == mip.pixel_sha1(x, "e")
            assert stats.constant() is None and mip.constant_color(x) is None
    c = np.full((9, 4, 2), 7, dtype=np.uint8)
    stats = mip.PixelStats(9)
    stats.add_encoded(c[:4])
    stats.add_encoded(c[4:])
    assert stats.constant() == mip.constant_color(c) and stats.average() == mip.average_color(c)


# ------------------------------------------------------------------ the command line
@pytest.mark.slow
def test_cli_mipmap_streams_when_told(tmp_path):
    pytest.importorskip("numba")
    src = tmp_path / "in.exr"
    write(src, noise(128, 128, seed=2), "half")
    memory = (330 << 10) + codecs(src, [tmp_path / "s.tx"], tile=64)  # 330K beside what the EXR codec holds
    r = run_cli("mipmap", "--backend", "cpu", "--memory", memory, "-v", src, tmp_path / "s.tx")
    assert r.returncode == 0 and "streamed in bands" in r.stdout and "streams in bands" in r.stderr, r.stderr
    r = run_cli("mipmap", "--backend", "cpu", "--memory", "4K", src, tmp_path / "x.tx")
    assert r.returncode == 5 and "needs at least" in r.stderr and "Traceback" not in r.stderr
    r = run_cli("mipmap", "--backend", "cpu", "--memory", memory, "--fill", src, tmp_path / "x.tx")
    assert r.returncode == 2 and "--fill" in r.stderr and "Traceback" not in r.stderr
    assert sorted(os.listdir(tmp_path)) == ["in.exr", "s.tx"]


@pytest.mark.slow
@pytest.mark.parametrize("memory", ["420K", "660K"])
def test_plan_says_what_a_streamed_mipmap_chooses(tmp_path, memory):
    """``pyramid plan --mipmap --memory`` and ``pyramid mipmap -v --memory`` choose the same band, the same place
    for the coarser levels and the same number of reads (420K: twice, the levels spilled; 660K: once, level 0
    kept in memory), from one function."""
    pytest.importorskip("numba")
    src = tmp_path / "in.exr"
    # RGBA float, what plan --memory assumes; uncompressed, as plan knows no file whose codec would hold memory
    write(src, noise(128, 128, 4, seed=2), "float", compression="none")
    r = run_cli("mipmap", "--backend", "cpu", "--memory", memory, "-v", src, tmp_path / "s.tx")
    said = [line.split(f"{src}: ", 1)[1] for line in r.stderr.splitlines() if "streams in bands" in line]
    assert r.returncode == 0 and len(said) == 1, r.stderr
    p = run_cli("plan", "--mipmap", "down", "quadratic *v g", "--size", "128x128", "--memory", memory)
    assert p.returncode == 0 and p.stdout.splitlines()[-1] == f"memory: {said[0]}", (p.stdout, said)
    if memory == "420K":
        assert "temporary file" in coarser(said[0]) and not level0(said[0]), said
    else:
        assert level0(said[0]), said


@pytest.mark.slow
@pytest.mark.parametrize("memory", ["6M", "60M"])  # read twice, the levels spilled; read once, level 0 kept
def test_a_signal_during_a_streamed_mipmap(tmp_path, memory):
    """SIGTERM during a streamed (and spilled) mipmap: exit 143 with the previous output kept, or the complete
    new file; no temporary (output or spilled levels) is left."""
    from helpers.interrupt import interrupt_runs

    pytest.importorskip("numba")
    big = tmp_path / "big.exr"
    write(big, noise(1536, 1536, 3, seed=7), "float")  # about 2.5 s: pass 1, pass 2, then the levels
    out = tmp_path / "out.exr"
    stopped = interrupt_runs(CLI + ["mipmap", "--backend", "cpu", "--memory", memory, "--compression", "zip",
                                    big, out], out, (0.7, 1.2, 1.8), lambda f: len(levels(f)) == 11)  # 1536 … 3, 1
    assert stopped, "no run was interrupted: make the picture larger"


@pytest.mark.slow
def test_streamed_mipmap_stays_within_the_memory_given(tmp_path, monkeypatch):
    """A picture several times --memory makes its MIP file within it (peak RSS over a tiny image's, a bound
    with a generous margin, not a timing); the whole run takes many times more; the files are the same. With
    OpenImageIO told to use 16 threads, as on a 16-core machine, where OpenEXR's line buffers (one set per codec
    thread) took the streamed run 48 MiB over before they were limited (run.codec_budget.Codecs.limit)."""

    pytest.importorskip("numba")
    monkeypatch.setenv("OPENIMAGEIO_THREADS", "16")
    budget = 16 << 20
    big, tiny = tmp_path / "big.exr", tmp_path / "tiny.exr"
    write(big, noise(2048, 2048, seed=1), "half")       # 32 MiB half, 64 MiB as float32
    write(tiny, noise(16, 16, seed=2), "half")
    cmd = CLI + ["mipmap", "--backend", "cpu", "--memory", str(budget)]
    base = peak_rss(cmd + [tiny, tmp_path / "t.exr"])
    streamed = peak_rss(cmd + [big, tmp_path / "s.exr"])
    whole = peak_rss(CLI + ["mipmap", "--backend", "cpu", big, tmp_path / "w.exr"])
    assert streamed - base < 2 * budget, (base, streamed, whole)
    assert whole - base > 3 * budget, (base, streamed, whole)
    assert_same_file(tmp_path / "s.exr", tmp_path / "w.exr")


def test_mip_outputs_stream(tmp_path):
    assert io.streams_to("x.tx") and io.streams_to("x.exr")


@pytest.mark.gl
@pytest.mark.slow
def test_streamed_mipmap_on_gl_is_the_whole_runs_file(tmp_path, gl):
    """The GL executor streams too (its textures the windows' size, counted in the budget; 380K spills the coarser
    levels): the same file as its whole run."""
    src = tmp_path / "in.exr"
    write(src, noise(128, 128, seed=8), "half")
    memory = (380 << 10) + codecs(src, [tmp_path / "s.exr"], tile=64)  # 380K beside what the EXR codecs hold
    r = run_cli("mipmap", "--backend", "gl", "--memory", memory, src, tmp_path / "s.exr")
    assert r.returncode == 0 and "streamed in bands" in r.stdout, r.stderr
    r = run_cli("mipmap", "--backend", "gl", src, tmp_path / "w.exr")
    assert r.returncode == 0, r.stderr
    assert_same_file(tmp_path / "s.exr", tmp_path / "w.exr")
