"""Streaming from file to file in bounded memory (issue 18): same pixels, bounded RSS, atomic writes."""

from __future__ import annotations

import os
import re
import resource

import numpy as np
import pytest

from helpers.budgets import codecs
from helpers.cli import CLI, peak_rss, run_cli
from helpers.images import noise, write
from pyramid_cli import imageio as io
from pyramid_cli.core.errors import DataError, UsageError
from pyramid_cli.core.parse import parse
from pyramid_cli.jobs.work import Blur, Filter
from pyramid_cli.run import stream


# ------------------------------------------------------------------ io: bands in, bands out
@pytest.mark.parametrize("fmt, pixel_type, tile, attrs", [
    ("exr", "half", None, {}), ("exr", "float", 16, {}), ("tif", "uint8", None, {}),
    ("png", "uint16", None, {}), ("tif", "uint8", None, {"oiio:UnassociatedAlpha": 1}),
    ("tif", "uint8", 16, {})])  # tiled and dithered (TIFF tiles are multiples of 16 rows, so of the dither's 8)
def test_bands_read_and_write_like_whole_pictures(tmp_path, fmt, pixel_type, tile, attrs):
    src = tmp_path / f"in.{fmt}"
    write(src, noise(45, 37), pixel_type, tile, **attrs)
    whole = io.read_image(src, keep_half=True)
    with io.open_stream(src, keep_half=True) as st:
        assert st.shape == whole.pixels.shape and st.dtype == whole.pixels.dtype
        bands = [st.read(y, min(45, y + 8)) for y in range(0, 45, 8)]
    pixels = np.concatenate(bands)
    assert np.array_equal(pixels, whole.pixels)
    dither = pixel_type == "uint8"
    io.write_image(tmp_path / f"whole.{fmt}", whole, dither=dither)
    with io.stream_writer(tmp_path / f"bands.{fmt}", whole.spec, pixels.shape, dither=dither) as w:
        for y in range(0, 45, 8):
            w.write(y, pixels[y:y + 8])
    a, b = (io.read_image(tmp_path / f"{n}.{fmt}", keep_half=True) for n in ("whole", "bands"))
    assert np.array_equal(a.pixels, b.pixels)
    assert a.spec.tile == b.spec.tile and a.spec.pixel_type == b.spec.pixel_type


def test_an_interrupted_stream_leaves_the_previous_output(tmp_path):
    out = tmp_path / "out.exr"
    out.write_bytes(b"previous")
    info = io.info_for_array(out, 4)
    with pytest.raises(KeyboardInterrupt), io.stream_writer(out, info, (32, 16, 4)) as w:
        w.write(0, noise(8, 16))
        raise KeyboardInterrupt
    assert out.read_bytes() == b"previous"
    assert sorted(os.listdir(tmp_path)) == ["out.exr"]  # no temporary left behind


def test_a_short_stream_is_not_committed(tmp_path):
    out = tmp_path / "out.exr"
    info = io.info_for_array(out, 4)
    with pytest.raises(ValueError, match="8 of 32 rows"), io.stream_writer(out, info, (32, 16, 4)) as w:
        w.write(0, noise(8, 16))
    assert not os.listdir(tmp_path)


def test_non_finite_values_follow_the_policy_per_band(tmp_path):
    px = noise(20, 6)
    px[13, 2, 1] = np.nan
    write(tmp_path / "nan.exr", px, "float")
    with pytest.raises(DataError, match="x=2, y=13, channel 1"), io.open_stream(tmp_path / "nan.exr",
                                                                                 nan="fail") as st:
        for y in range(0, 20, 8):
            st.read(y, min(20, y + 8))
    with io.open_stream(tmp_path / "nan.exr", nan="zero") as st:
        assert st.read(8, 16)[5, 2, 1] == 0


# ------------------------------------------------------------------ the driver
@pytest.mark.parametrize("work", [Blur(levels=3), Blur(levels=2, border="mirror"), Filter(expr=parse("gauss5")),
                                  Filter(expr=parse("box4 *v g"), border="wrap"), Filter(expr=parse("doosabin"))],
                         ids=lambda w: w.label + "-" + w.border)
@pytest.mark.parametrize("pixel_type", ["half", "float"])
def test_streamed_equals_whole(tmp_path, session, work, pixel_type):
    src, out = tmp_path / "in.exr", tmp_path / "out.exr"
    write(src, noise(67, 45, seed=3), pixel_type)
    whole = io.read_image(src, keep_half=True)
    half = whole.pixels.dtype == np.float16
    want = session.run(work, [whole.pixels], np.float16 if half else np.float32)[-1]
    plan = session.plan(work, [whole.pixels.shape])
    choice = stream.Choice(1 << 20, 1 << 30, 8, 1 << 20)
    stream.stream_file(str(src), str(out), work, session, choice, budget=1 << 20)
    got = io.read_image(out, keep_half=True).pixels
    assert got.shape == want.shape == plan.output.size + (4,)
    assert np.array_equal(got, want)


def test_choose_bands_from_the_budget():
    plan = Blur(levels=5).plan(((8192, 8192),))
    whole = stream.estimate(plan, 4, None)
    assert stream.choose(plan, 4, whole + 1).band is None  # fits: runs whole, as before
    small = stream.choose(plan, 4, 256 << 20)
    assert small.band % stream.MIN_BAND == 0 and small.working_set <= 256 << 20
    larger = stream.choose(plan, 4, 512 << 20)
    assert larger.band > small.band
    with pytest.raises(DataError, match="needs at least .* over the budget of 1.0 MiB"):
        stream.choose(plan, 4, 1 << 20, force=True)


def test_parse_size():
    assert stream.parse_size("512M") == 512 << 20
    assert stream.parse_size("1.5G") == 3 << 29
    assert stream.parse_size("2GiB") == 2 << 30
    assert stream.parse_size("1000") == 1000
    for bad in ("lots", "-1G", "0"):
        with pytest.raises(UsageError, match="--memory"):
            stream.parse_size(bad)


def test_a_job_that_writes_its_input_counts_that_writer():
    """``levels`` writes the input as level 0 beside the plan's outputs: its writer's band counts (it did not,
    and a 4K ``levels --memory 64M`` peaked about 20 MB over the budget above the interpreter's own)."""
    from pyramid_cli.jobs.work import Levels

    p = Levels(levels=3).plan([(300, 200)])
    anchor = max(p.images[k].size[0] for k in p.outputs)
    for band in (8, 64):
        extra = stream.estimate(p, 4, band, keeps_input=True) - stream.estimate(p, 4, band)
        assert extra == (2 + stream.DEPTH) * -(-band * 300 // anchor) * 200 * 4 * 4  # + its queue (run.overlap)
    assert stream.estimate(p, 4, None, keeps_input=True) - stream.estimate(p, 4, None) == 300 * 200 * 4 * 4
    budget = stream.estimate(p, 4, 64) + 1
    assert stream.choose(p, 4, budget, keeps_input=True, force=True).band < stream.choose(p, 4, budget, force=True).band


def test_gl_textures_count_in_the_budget():
    """The GL executor holds each image in a power-of-two RGBA32F texture (host memory on llvmpipe): they count
    in the estimate, and a picture they pad runs in bands (520×520 pads to 1024×1024), one they do not pad
    (a 512×512 blur: no guard at any level) runs whole when it fits."""
    from pyramid_cli.exec.emulate import Emulator
    from pyramid_cli.exec.gl import GLExecutor

    p = Blur(levels=3).plan([(520, 520)])
    cpu = stream.choose(p, 4, 24 << 20)
    gl = stream.choose(p, 4, 24 << 20, texture=GLExecutor.texture_bytes)
    assert not cpu.streams and gl.streams and gl.padded > 3, (cpu, gl)
    assert gl.whole - cpu.whole >= 1024 * 1024 * 16  # the input's texture at least
    assert "the bands are padded, not the picture" in gl.describe() and gl.to_json()["padded"] == round(gl.padded, 3)
    p = Blur(levels=3).plan([(512, 512)])
    assert stream.padding(p, GLExecutor.texture_bytes) <= stream.PADDED
    assert not stream.choose(p, 4, 64 << 20, texture=GLExecutor.texture_bytes).streams
    tiny = Blur(levels=3).plan([(20, 20)])  # too small for bands of a quarter of its run: whole
    assert not stream.choose(tiny, 4, 64 << 20, texture=GLExecutor.texture_bytes).streams
    assert stream.costs(Emulator()) == {"work_bytes": 8, "texture": None}


def test_only_host_memory_textures_count(gl):
    """llvmpipe's textures are host memory and count; a GPU's (any other renderer) are not the budget's. The
    machine's own GL is one or the other (llvmpipe on CI; an H100 counted none)."""
    from pyramid_cli.exec.gl import GLExecutor, is_software_renderer

    assert gl.host_textures == is_software_renderer(gl.renderer)
    assert stream.costs(gl)["texture"] == (GLExecutor.texture_bytes if gl.host_textures else None)
    gpu = GLExecutor()
    gpu._info = {"renderer": "NVIDIA H100 80GB HBM3/PCIe/SSE2"}  # what a GPU's GL_RENDERER reads like
    assert not gpu.host_textures and stream.costs(gpu) == {"work_bytes": 4, "texture": None}


# ------------------------------------------------------------------ the command line
@pytest.mark.slow
def test_cli_streams_when_told_and_says_so(tmp_path):
    pytest.importorskip("numba")
    src = tmp_path / "in.exr"
    write(src, noise(300, 200, seed=5), "half")
    r = run_cli("blur", "--backend", "cpu", "--levels", "3", "--memory", "1M", "-v", src, tmp_path / "s.exr")
    assert r.returncode == 0, r.stderr
    assert "streams in bands of" in r.stderr and "streamed in bands" in r.stdout
    r = run_cli("blur", "--backend", "cpu", "--levels", "3", "-v", src, tmp_path / "w.exr")
    assert r.returncode == 0 and "runs whole" in r.stderr, r.stderr
    a, b = (io.read_image(tmp_path / n, keep_half=True).pixels for n in ("s.exr", "w.exr"))
    assert np.array_equal(a, b)
    r = run_cli("blur", "--backend", "cpu", "--memory", "10K", src, tmp_path / "x.exr")
    assert r.returncode == 5 and "needs at least" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "x.exr").exists()


@pytest.mark.slow
def test_cli_gl_pads_the_bands_not_the_picture(tmp_path, gl):
    """On GL in host memory (llvmpipe) a picture that its power-of-two textures would pad (520×520: 1024×1024)
    runs in bands even within the budget, and says why; on a GPU it runs whole. The pixels are those of GL's whole
    run of the picture (the Python API's)."""
    from pyramid_cli import api

    src = tmp_path / "in.exr"
    write(src, noise(520, 520, seed=6), "half")
    r = run_cli("blur", "--backend", "gl", "--levels", "3", "-v", src, tmp_path / "s.exr")
    said = "the bands are padded, not the picture" if gl.host_textures else "runs whole"
    assert r.returncode == 0 and said in r.stderr, r.stderr
    whole = api.blur(io.read_image(src).pixels, levels=3, backend="gl")
    assert np.array_equal(io.read_image(tmp_path / "s.exr", keep_half=True).pixels, whole.astype(np.float16))


@pytest.mark.slow
def test_streaming_stays_within_the_memory_given(tmp_path):
    """A file whose decoded pixels are several times --memory streams within it (a bound, not a timing):
    peak RSS over the same command's on a tiny image (interpreter, libraries, kernels) stays under 2× the
    budget, where the whole-picture run takes many times more."""
    pytest.importorskip("numba")
    budget = 16 << 20
    big, tiny = tmp_path / "big.exr", tmp_path / "tiny.exr"
    write(big, noise(1536, 1536, seed=1), "half")       # 18 MiB half, 36 MiB as float32, 6 levels of it
    write(tiny, noise(16, 16, seed=2), "half")
    assert 1536 * 1536 * 4 * 4 > 2 * budget
    cmd = CLI + ["blur", "--backend", "cpu", "--levels", "5", "--memory", str(budget)]
    base = peak_rss(cmd + [tiny, tmp_path / "t.exr"])
    streamed = peak_rss(cmd + [big, tmp_path / "s.exr"])
    # the whole run's memory: a wrap border keeps the images whole (a default run of this size streams, in
    # bands of its own choosing: run.stream.speed_band), whose pixels the --memory run must equal
    whole = peak_rss(CLI + ["blur", "--backend", "cpu", "--levels", "5", "--border", "wrap", big, tmp_path / "w.exr"])
    peak_rss(CLI + ["blur", "--backend", "cpu", "--levels", "5", big, tmp_path / "d.exr"])
    assert streamed - base < 2 * budget, (base, streamed, whole)
    assert whole - base > 3 * budget, (base, streamed, whole)  # the bound could fail
    a, b = (io.read_image(tmp_path / n, keep_half=True).pixels for n in ("s.exr", "d.exr"))
    assert np.array_equal(a, b)


@pytest.mark.slow
def test_many_codec_threads_are_limited_to_what_the_budget_leaves(tmp_path, monkeypatch):
    """On a machine with many cores OpenEXR gives every codec thread line buffers of each open file: 16 threads
    (OpenImageIO told so, as a 16-core machine has) took the streamed run 42 MiB over its tiny run's peak with a
    16 MiB budget. They are limited to what the working set leaves, and the pixels are the same."""
    pytest.importorskip("numba")
    monkeypatch.setenv("OPENIMAGEIO_THREADS", "16")
    budget = 16 << 20
    big, tiny = tmp_path / "big.exr", tmp_path / "tiny.exr"
    write(big, noise(1536, 1536, seed=1), "half")
    write(tiny, noise(16, 16, seed=2), "half")
    cmd = CLI + ["blur", "--backend", "cpu", "--levels", "5", "--memory", str(budget)]
    base = peak_rss(cmd + [tiny, tmp_path / "t.exr"])
    streamed = peak_rss(cmd + [big, tmp_path / "s.exr"])
    assert streamed - base < 2 * budget, (base, streamed)
    r = run_cli("blur", "--backend", "cpu", "--levels", "5", "--memory", str(budget), "-v", "--force", big,
                tmp_path / "s.exr")
    assert r.returncode == 0 and "OpenEXR codes with 1 of its 16 threads" in r.stderr, r.stderr
    monkeypatch.delenv("OPENIMAGEIO_THREADS")
    r = run_cli("blur", "--backend", "cpu", "--levels", "5", "--memory", "1G", "-v", big, tmp_path / "w.exr")
    assert r.returncode == 0 and "OpenEXR codes with" not in r.stderr, r.stderr  # room for every thread
    a, b = (io.read_image(tmp_path / n, keep_half=True).pixels for n in ("s.exr", "w.exr"))
    assert np.array_equal(a, b)


@pytest.mark.slow
@pytest.mark.parametrize("compression", ["dwab", "dwaa"])
def test_a_dwa_file_s_codec_is_counted_in_the_budget(tmp_path, monkeypatch, compression):
    """OpenEXR's DWA codecs hold far more than their line buffers: a 3840-wide DWAB file 56 MiB on one thread (7.5
    chunks of 256 rows), DWAA about 13 MiB for every thread at any width (docs/performance.md). A budget that cannot
    hold them on one thread is refused before any work (exit 5, one line, nothing written); one that can keeps the
    run within it on a 16-core machine (OpenImageIO told so), with the pixels of a run with room."""
    pytest.importorskip("numba")
    monkeypatch.setenv("OPENIMAGEIO_THREADS", "16")
    big, tiny = tmp_path / "big.exr", tmp_path / "tiny.exr"
    write(big, noise(600, 1024, seed=1), "half", compression=compression)
    write(tiny, noise(16, 16, seed=2), "half", compression=compression)
    r = run_cli("blur", "--backend", "cpu", "--levels", "5", "--memory", "12M", big, tmp_path / "s.exr")
    assert r.returncode == 5 and "OpenEXR's codecs hold on one thread" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and str(big) in r.stderr and "Traceback" not in r.stderr
    assert sorted(os.listdir(tmp_path)) == ["big.exr", "tiny.exr"]
    budget = 64 << 20
    cmd = CLI + ["blur", "--backend", "cpu", "--levels", "5", "--memory", str(budget)]
    base = peak_rss(cmd + [tiny, tmp_path / "t.exr"])
    streamed = peak_rss(cmd + [big, tmp_path / "s.exr"])
    assert streamed - base < 2 * budget, (base, streamed)
    monkeypatch.delenv("OPENIMAGEIO_THREADS")
    r = run_cli("blur", "--backend", "cpu", "--levels", "5", "--memory", "1G", big, tmp_path / "w.exr")
    assert r.returncode == 0, r.stderr
    a, b = (io.read_image(tmp_path / n, keep_half=True).pixels for n in ("s.exr", "w.exr"))
    assert np.array_equal(a, b)


@pytest.mark.slow
@pytest.mark.parametrize("command, budget", [(["blur", "--levels", "3"], "64M"), (["levels", "--levels", "3"], "192M"),
                                             (["mipmap"], "64M"), (["fill", "--holes", "nan", "--levels", "3"], "96M"),
                                             (["blend", "--levels", "3"], "128M")])
def test_a_whole_run_s_codec_threads_fit_the_budget(tmp_path, monkeypatch, command, budget):
    """A picture that fits the budget whole still has its codec threads limited to what the whole run leaves of
    it (:meth:`pyramid_cli.run.codec_budget.Codecs.hold`), and the files are those of a run with room for every thread.
    (``levels`` writes four DWAA files at once, ``blend`` reads three: each one's codec holds 13 MiB.)"""
    pytest.importorskip("numba")
    px = noise(200, 1024, seed=1)
    px[3:9, 5:40] = np.nan  # holes for the fill
    srcs = [write(tmp_path / "in.exr", px, "half", compression="dwaa")]
    if command[0] == "blend":
        srcs += [write(tmp_path / "b.exr", noise(200, 1024, seed=2), "half", compression="dwaa"),
                 write(tmp_path / "m.exr", noise(200, 1024, 1, seed=3), "half", compression="dwaa")]
    out = "{level}.exr" if command[0] == "levels" else "o.exr"
    monkeypatch.setenv("OPENIMAGEIO_THREADS", "16")
    r = run_cli(*command, "--backend", "cpu", "--memory", budget, "-v", *srcs, tmp_path / "a" / out)
    assert r.returncode == 0 and "runs whole" in r.stderr, r.stderr
    limited = re.search(r"OpenEXR codes with (\d+) of its 16 threads", r.stderr)
    assert limited and int(limited.group(1)) < 16, r.stderr
    r = run_cli(*command, "--backend", "cpu", "--memory", "64G", "-v", *srcs, tmp_path / "b" / out)
    assert r.returncode == 0 and "OpenEXR codes with" not in r.stderr, r.stderr  # room for all 16
    names = sorted(os.listdir(tmp_path / "a"))
    assert names == sorted(os.listdir(tmp_path / "b")) and len(names) == (4 if command[0] == "levels" else 1)
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name


def test_resource_module_measures_children():
    assert resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss >= 0


@pytest.mark.parametrize("laplacian, budget", [(False, 280 << 10), (True, 300 << 10)])
def test_levels_stream_every_level(tmp_path, session, laplacian, budget):
    """Every level (the input itself as level 0, or the Laplacian bands) streamed equals the whole run's files."""
    from pyramid_cli.core.geometry import level_sizes
    from pyramid_cli.jobs.work import Laplacian, Levels
    from pyramid_cli.run.pipeline import write_levels_files
    from pyramid_cli.run.report import Reporter

    src = tmp_path / "in.exr"
    write(src, noise(150, 97, seed=4), "half")
    work = Laplacian(levels=3) if laplacian else Levels(levels=3)
    said = []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    outputs = [(tmp_path / f"s_{k}.exr", size) for k, size in enumerate(level_sizes((150, 97), 3))]
    budget += codecs(src, outputs, pixel_type="float" if laplacian else None)  # beside what the EXR codecs hold
    streamed = write_levels_files(str(src), str(tmp_path / "s_{level}.exr"), work, session, memory=budget,
                                  reporter=rep)
    assert any("streams in bands" in m for m in said), said
    whole = write_levels_files(str(src), str(tmp_path / "w_{level}.exr"), work, session)
    assert len(streamed) == len(whole) == 4
    for a, b in zip(streamed, whole, strict=True):
        x, y = io.read_image(a, keep_half=True), io.read_image(b, keep_half=True)
        assert np.array_equal(x.pixels, y.pixels) and x.spec.pixel_type == y.spec.pixel_type
        assert x.spec.attributes.get("pyramid:synthesis") == y.spec.attributes.get("pyramid:synthesis")
    with pytest.raises(UsageError, match="--multipart"):
        write_levels_files(str(src), str(tmp_path / "m.exr"), work, session, multipart=True, memory=1 << 20)


def test_plan_says_how_a_size_runs_in_a_budget():
    from click.testing import CliRunner

    from pyramid_cli.cli import main

    r = CliRunner().invoke(main, ["plan", "gauss5", "--size", "32768x32768", "--memory", "1G"])
    assert r.exit_code == 0 and "memory: streams in bands of" in r.output, r.output
    r = CliRunner().invoke(main, ["plan", "gauss5", "--size", "64x64", "--memory", "1G", "--json"])
    assert r.exit_code == 0 and '"band": null' in r.output
    r = CliRunner().invoke(main, ["plan", "gauss5", "--size", "32768x32768", "--memory", "1M"])
    assert r.exit_code == 5 and "needs at least" in r.output


def test_plan_says_how_gl_runs_a_size():
    """``plan --memory --backend gl`` counts GL's textures: a 5000×3000 picture they pad goes in bands."""
    from click.testing import CliRunner

    from pyramid_cli.cli import main

    args = ["plan", "gauss5", "--size", "5000x3000", "--memory", "4G"]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0 and "runs whole" in r.output, r.output
    r = CliRunner().invoke(main, args + ["--backend", "gl"])
    assert r.exit_code == 0 and "the bands are padded, not the picture" in r.output, r.output
    r = CliRunner().invoke(main, ["plan", "gauss5", "--size", "64x64", "--backend", "gl"])
    assert r.exit_code == 2 and "give --memory too" in r.output, r.output


@pytest.mark.slow
def test_a_signal_during_a_streamed_write(tmp_path):
    """SIGTERM while bands are being written: exit 143 with the previous output kept, or the complete new file."""
    from helpers.interrupt import interrupt_runs

    pytest.importorskip("numba")
    big = tmp_path / "big.exr"
    write(big, noise(1024, 1024, 3, seed=7), "float")
    out = tmp_path / "out.exr"
    interrupt_runs(CLI + ["blur", "--backend", "cpu", "--levels", "3", "--memory", "4M", "--compression", "zip",
                          big, out], out, (0.6, 1.0, 1.4),
                   lambda f: io.read_image(f).pixels.shape == (1024, 1024, 3))


def test_a_cpu_executor_encodes_8bit_srgb_on_its_compiled_loop(monkeypatch):
    """executor_of gives srgb8 the compiled CPU executor's loop (asked for at the loop's first call), the same
    codes; the emulator, which stands in for it without numba, and GL leave numpy's lookups."""
    from pyramid_cli.exec.emulate import Emulator
    from pyramid_cli.imageio import colour

    monkeypatch.setattr(colour, "_LOOP", [])
    x = np.linspace(-0.5, 1.5, 10001, dtype=np.float32)
    want = colour.srgb8(x)
    stream.encode_on(Emulator())
    assert colour._LOOP == []

    class Compiled:
        asked = 0

        def encode8(self):
            Compiled.asked += 1
            return lambda out, x, bits, codes, thresholds, i0, i1: out.__setitem__(slice(i0, i1), 9)

    stream.encode_on(Compiled())
    assert Compiled.asked == 0  # not waited for while the executor may still be loading
    np.testing.assert_array_equal(colour.srgb8(x[:5]), want[:5])  # a few values: numpy, the loop not asked for
    assert Compiled.asked == 0
    big = np.resize(x, colour.LOOP_MIN)
    assert (colour.srgb8(big) == 9).all() and (colour.srgb8(big) == 9).all() and Compiled.asked == 1
    pytest.importorskip("numba")
    from pyramid_cli.exec.session import Session

    with Session("cpu") as session:
        stream.executor_of(session)
        np.testing.assert_array_equal(colour.srgb8(np.resize(x, colour.LOOP_MIN)), np.resize(want, colour.LOOP_MIN))
        assert len(colour._LOOP) == 1  # registered: the codes above came through it
