"""Jobs of several inputs streamed (:mod:`pyramid_cli.run.stream_many`): ``pyramid blend`` band by band writes
the whole run's file, within ``--memory``, atomically."""

from __future__ import annotations

import filecmp
import subprocess
import time

import numpy as np
import pytest

from helpers.budgets import codecs
from helpers.cli import CLI, peak_rss
from helpers.images import noise, write
from pyramid_cli.core.errors import UsageError
from pyramid_cli.exec.session import Session
from pyramid_cli.run import stream
from pyramid_cli.run.methods_files import blend_files
from pyramid_cli.run.report import Reporter

WHOLE = 1 << 62  # STREAM_PIXELS that no picture reaches: the whole run


def blend(session, paths, out, **kw):
    said, warned = [], []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    rep.warn = warned.append
    info = blend_files(*map(str, paths), str(out), session, reporter=rep, **kw)
    return " | ".join(said), sorted(warned), info


def inputs(folder, ext, pixel_type, size=(97, 131), tile=0):
    """A and B (RGB) and a mask with NaN and values outside [0, 1] (a 2-channel luminance-alpha PNG beside
    8-bit pictures: its alpha is the mask; one float channel beside float ones)."""
    a, b = folder / f"a.{ext}", folder / f"b.{ext}"
    write(a, noise(*size, 3, seed=1), pixel_type, tile)
    write(b, noise(*size, 3, seed=2), pixel_type, tile)
    m = noise(*size, 1, seed=3) * 1.4 - 0.2
    if ext == "png":
        mask = write(folder / "m.png", np.concatenate([noise(*size, 1, seed=4), m], axis=2), "uint8",
                     names=["Y", "A"], alpha=1)
    else:
        m[5, 7] = np.nan
        mask = write(folder / "m.exr", m, "float")
    return a, b, mask


@pytest.mark.parametrize("ext, pixel_type, tile, memory", [
    ("png", "uint8", 0, None),       # streams by default (faster), its mask an alpha channel
    ("exr", "float", 0, 1 << 20),    # streams because the whole run (about 2 MiB) does not fit --memory
    ("exr", "half", 16, None),       # rows of tiles read in bands of 8 rows, half written
])
def test_a_streamed_blend_writes_the_whole_runs_file(tmp_path, session, small_pictures_stream, ext, pixel_type, tile,
                                                     memory):
    paths = inputs(tmp_path, ext, pixel_type, tile=tile)
    if memory is not None:
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
        memory += codecs(paths[0], [tmp_path / f"s.{ext}"], inputs=paths[1:])  # beside what the EXR codecs hold
    said, warned, info = blend(session, paths, tmp_path / f"s.{ext}", levels=3, memory=memory)
    assert "streams in bands of" in said and "streamed in bands of" in said, said
    assert ("faster than whole" in said) == (memory is None), said
    small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
    said_whole, warned_whole, info_whole = blend(session, paths, tmp_path / f"w.{ext}", levels=3)
    assert "runs whole" in said_whole and "streamed in bands" not in said_whole, said_whole
    assert filecmp.cmp(tmp_path / f"s.{ext}", tmp_path / f"w.{ext}", shallow=False)
    assert warned == warned_whole and len(warned) == (1 if ext == "png" else 2), warned  # alpha; NaN, clipped
    assert info == {**info_whole, "output": info["output"]}


def test_blend_refusals(tmp_path, session,
                        small_pictures_stream):
    """--memory without a plan executor, or too small for the smallest band, is refused before any work; inputs that
    do not match are refused by the whole run's checks, with its one line."""
    from pyramid_cli.core.errors import DataError, InputError

    paths = inputs(tmp_path, "exr", "float")
    with Session("reference") as ref, pytest.raises(UsageError, match="--memory needs a plan executor"):
        blend(ref, paths, tmp_path / "o.exr", memory=1 << 20)
    with pytest.raises(DataError, match=r"a.exr: this job needs at least .* over the budget of 300.0 KiB"):
        blend(session, paths, tmp_path / "o.exr", levels=3, memory=300 << 10)
    write(tmp_path / "small.exr", noise(96, 131, 3), "float")
    with pytest.raises(InputError, match="small.exr: 131×96"):  # the whole run's one line
        blend(session, (paths[0], tmp_path / "small.exr", paths[2]), tmp_path / "o.exr")


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    """640×512 float RGB pictures (3.75 MiB each; the whole blend of 3 levels holds about 53 MiB) and a tiny set."""
    folder = tmp_path_factory.mktemp("blend")
    mask = np.zeros((512, 640, 1), np.float32)
    mask[:, :300] = 1
    paths = [write(folder / "a.exr", noise(512, 640, 3, seed=1), "float"),
             write(folder / "b.exr", noise(512, 640, 3, seed=2), "float"), write(folder / "m.exr", mask, "float")]
    tiny = [write(folder / "t.exr", noise(16, 16, 3, seed=1), "float")] * 2 + [write(folder / "tm.exr", mask[:16, :16])]
    return folder, paths, tiny


@pytest.mark.slow
@pytest.mark.parametrize("codec_threads", [None, "16"])
def test_a_streamed_blend_stays_within_the_memory_given(big, monkeypatch, codec_threads):
    """Three inputs of 3.75 MiB each (as float32), about twice --memory together, are blended within it (peak RSS
    over a tiny blend's, a bound with a generous margin, not a timing). The whole run's file is the same
    (test_a_streamed_blend_writes_the_whole_runs_file); at 1024×768 its peak was 72 MiB over the tiny blend's
    when measured, against 13 MiB streamed in 16M (a third process is left out here: it took 3 s). Also with
    OpenImageIO told to use 16 threads, as on a 16-core machine: OpenEXR's threads are limited to what the budget
    leaves them (run.codec_budget.Codecs.within)."""
    pytest.importorskip("numba")
    if codec_threads:
        monkeypatch.setenv("OPENIMAGEIO_THREADS", codec_threads)
    folder, paths, tiny = big
    budget = 6 << 20
    cmd = CLI + ["blend", "--backend", "cpu", "--levels", "3"]
    base = peak_rss(cmd + ["--memory", str(budget)] + tiny + [folder / "t_out.exr"])
    streamed = peak_rss(cmd + ["--memory", str(budget)] + paths + [folder / "s.exr"])
    assert streamed - base < 2 * budget, (base, streamed)


@pytest.mark.slow
def test_a_signal_during_a_streamed_blend(big):
    """SIGTERM during a streamed blend: exit 143 with the previous output kept, or the complete new file; no
    temporary is left (helpers.interrupt)."""
    from helpers.interrupt import interrupt_runs

    pytest.importorskip("numba")
    folder, paths, _ = big
    out = folder / "out.exr"

    def complete(f):
        from pyramid_cli import imageio as io

        return io.read_image(str(f)).pixels.shape == (512, 640, 3)

    cmd = CLI + ["blend", "--backend", "cpu", "--levels", "3", "--memory", "6M"] + paths + [out]
    # the signal lands part-way through the run on any machine: at fractions of its own time here, timed warm (a
    # first run that compiled the kernels took so long in CI that both signals came after the runs had ended)
    took = []
    for _ in range(2):
        t0 = time.monotonic()
        subprocess.run([str(c) for c in cmd], check=True, capture_output=True, timeout=300)
        took.append(time.monotonic() - t0)
        out.unlink()
    stopped = interrupt_runs(cmd, out, [f * min(took) for f in (0.3, 0.5, 0.75)], complete)
    assert stopped, "no run was interrupted: make the pictures larger"


def collapse(session, pattern, out, **kw):
    from pyramid_cli.run.pipeline import collapse_files

    said = []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    collapse_files([str(pattern)], str(out), session, reporter=rep, **kw)
    return " | ".join(said)


@pytest.mark.parametrize("ext, memory", [
    ("png", None),        # streams by default (faster): 8-bit, rounded
    ("exr", 400 << 10),   # streams because the whole run does not fit --memory
])
def test_a_streamed_collapse_of_band_files_writes_the_whole_runs_file(tmp_path, session, small_pictures_stream, ext,
                                                                      memory):
    """Laplacian band files of several sizes (97×131 down to 13×17: each read at its own pace), mirror border."""
    from pyramid_cli.jobs.work import Laplacian
    from pyramid_cli.run.pipeline import write_levels_files

    src = write(tmp_path / "in.exr", noise(97, 131, 3, seed=5), "float")
    small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
    write_levels_files(str(src), str(tmp_path / "band_{level}.exr"), Laplacian(levels=3, border="mirror"), session,
                       reporter=Reporter(quiet=True))
    said_whole = collapse(session, tmp_path / "band_*.exr", tmp_path / f"w.{ext}")
    assert "runs whole" in said_whole and "streamed in bands" not in said_whole, said_whole
    if memory is None:
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", 1)
    else:  # beside what the EXR codecs hold
        memory += codecs(tmp_path / "band_0.exr", [tmp_path / f"s.{ext}"],
                         inputs=[tmp_path / f"band_{k}.exr" for k in (1, 2, 3)])
    said = collapse(session, tmp_path / "band_*.exr", tmp_path / f"s.{ext}", memory=memory)
    assert "streamed in bands of" in said and ("faster than whole" in said) == (memory is None), said
    assert filecmp.cmp(tmp_path / f"s.{ext}", tmp_path / f"w.{ext}", shallow=False)
    with pytest.raises(UsageError, match="--border clamp would not give the image back"):
        collapse(session, tmp_path / "band_*.exr", tmp_path / f"x.{ext}", border="clamp", memory=memory)
    with pytest.raises(UsageError, match="not a multipart EXR"):
        collapse(session, tmp_path / "band_0.exr", tmp_path / f"x.{ext}", memory=memory or 1 << 30)


def fill(session, src, out, **kw):
    from pyramid_cli.run.methods_files import fill_file

    said, warned = [], []
    rep = Reporter(verbose=True, out=said.append, err=said.append)
    rep.warn = warned.append
    info = fill_file(str(src), str(out), session, reporter=rep, **kw)
    return " | ".join(said), sorted(warned), info


def holes_of(folder, holes):
    """A picture with holes as ``holes`` finds them (97×131: 2 pull levels keep 25 rows) and the options."""
    px = noise(97, 131, 4, seed=6)
    px[20:60, 30:90] = 0      # a hole larger than a band
    px[::7, ::5, 3] = 0.5     # partial pixels
    if holes == "alpha":      # 8-bit RGBA, straight alpha kept beside the colours
        px[:, :, :3] *= px[:, :, 3:]
        return write(folder / "in.png", px, "uint8", alpha=3), "png", {"keep_alpha": True}
    if holes == "nan":
        px[px[:, :, 3] < 0.5] = np.nan
        return write(folder / "in.exr", px[:, :, :3], "float"), "exr", {"holes": "nan"}
    mask = px[:, :, 3:] * 1.2 - 0.1  # NaN/Inf-free, some values outside [0, 1]
    write(folder / "m.exr", mask, "float")
    return write(folder / "in.exr", px[:, :, :3], "float"), "exr", {"mask": str(folder / "m.exr")}


@pytest.mark.parametrize("holes, memory", [("alpha", None), ("nan", None), ("mask", 600 << 10)])
def test_a_streamed_fill_writes_the_whole_runs_file(tmp_path, session, small_pictures_stream, holes, memory):
    src, ext, kw = holes_of(tmp_path, holes)
    if memory is not None:
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
        memory += codecs(src, [tmp_path / f"s.{ext}"], inputs=[kw["mask"]] if "mask" in kw else [])
    said, warned, info = fill(session, src, tmp_path / f"s.{ext}", levels=2, memory=memory, **kw)
    assert "streamed in bands of" in said and ("faster than whole" in said) == (memory is None), said
    small_pictures_stream.setattr(stream, "STREAM_PIXELS", WHOLE)
    said_whole, warned_whole, info_whole = fill(session, src, tmp_path / f"w.{ext}", levels=2, **kw)
    assert "streamed in bands" not in said_whole, said_whole
    assert filecmp.cmp(tmp_path / f"s.{ext}", tmp_path / f"w.{ext}", shallow=False)
    assert info == {**info_whole, "output": info["output"]} and info["empty"], info
    assert info["partial"] or holes == "nan", info
    assert warned == warned_whole


def test_fill_refusals_streamed_are_the_whole_runs(tmp_path, session, small_pictures_stream):
    """No known pixel: refused once the last band is read, in the whole run's words, the previous output kept and
    no temporary left. --memory with a pull down to 1×1 (which reads every row before the first) is refused."""
    import os

    from pyramid_cli.core.errors import DataError

    src = write(tmp_path / "in.exr", np.full((40, 24, 3), np.nan, np.float32), "float")
    out = tmp_path / "out.exr"
    out.write_bytes(b"previous")
    said = []
    for threshold in (1, WHOLE):  # streamed, then whole
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", threshold)
        with pytest.raises(DataError, match="no known pixel") as caught:
            fill(session, src, out, holes="nan", levels=1)
        said.append(str(caught.value))
        assert out.read_bytes() == b"previous" and sorted(os.listdir(tmp_path)) == ["in.exr", "out.exr"]
    assert said[0] == said[1]
    with pytest.raises(UsageError, match="--memory: a fill pulled down to 1 row"):
        fill(session, src, out, holes="nan", memory=1 << 30)


@pytest.mark.parametrize("job, budget", [("fill", 4 << 20), ("collapse", 2 << 20)])  # whole: 6.5 and 5.3 MB
def test_streamed_fill_and_collapse_allocate_within_the_memory_given(tmp_path, session, job, budget):
    """In process, the arrays a run allocates (tracemalloc: numpy's buffers, OpenImageIO's reads): streamed within
    --memory, half the whole run's or less (the same files). The RSS of a streamed blend: below."""
    import tracemalloc

    from pyramid_cli.jobs.work import Laplacian
    from pyramid_cli.run.methods_files import fill_file
    from pyramid_cli.run.pipeline import collapse_files, write_levels_files

    px = noise(256, 320, 4, seed=9)
    px[50:150, 50:200, 3] = 0
    src = write(tmp_path / "in.exr", px, "float", alpha=3)
    if job == "collapse":
        write_levels_files(str(src), str(tmp_path / "band_{level}.exr"), Laplacian(levels=3), session,
                           reporter=Reporter(quiet=True))

    def run(memory, out):
        if job == "fill":
            fill_file(str(src), str(out), session, levels=2, memory=memory, reporter=Reporter(quiet=True))
        else:
            collapse_files([str(tmp_path / "band_*.exr")], str(out), session, memory=memory,
                           reporter=Reporter(quiet=True))
        return tracemalloc.get_traced_memory()[1]

    run(None, tmp_path / "w.exr")  # plans, kernels and caches made before anything is measured
    peaks = []
    for memory, out in ((None, tmp_path / "w.exr"), (budget, tmp_path / "s.exr")):
        tracemalloc.start()
        try:
            peaks.append(run(memory, out))
        finally:
            tracemalloc.stop()
    whole, streamed = peaks
    assert streamed < budget < whole and 2 * streamed < whole, peaks
    assert filecmp.cmp(tmp_path / "s.exr", tmp_path / "w.exr", shallow=False)


def test_streamed_blend_and_collapse_across_colour_spaces(tmp_path, session, small_pictures_stream):
    """An ACEScct plate blended with an sRGB PNG (B brought into A's linear space band by band), and Laplacian bands
    (in ACEScg) collapsed back to ACEScct with --tocolorspace: the whole runs' files."""
    from pyramid_cli.jobs.work import Laplacian
    from pyramid_cli.run.pipeline import collapse_files, write_levels_files
    from pyramid_cli.run.settings import WriteOptions

    a = write(tmp_path / "a.exr", noise(77, 37, 3, seed=1), "float", oiio__ColorSpace="ACEScct")
    b = write(tmp_path / "b.png", noise(77, 37, 3, seed=2), "uint8")
    m = write(tmp_path / "m.exr", noise(77, 37, 1, seed=3), "float")
    back = WriteOptions(tocolorspace="ACEScct")
    for threshold, name in ((1, "s"), (WHOLE, "w")):
        small_pictures_stream.setattr(stream, "STREAM_PIXELS", threshold)
        said = blend(session, (a, b, m), tmp_path / f"{name}.exr", levels=1)[0]
        assert ("streamed in bands" in said) == (name == "s"), said
        write_levels_files(str(a), str(tmp_path / f"{name}_band_{{level}}.exr"), Laplacian(levels=2), session,
                           reporter=Reporter(quiet=True))
        said = []
        collapse_files([str(tmp_path / f"{name}_band_*.exr")], str(tmp_path / f"{name}_back.exr"), session,
                       write=back, reporter=Reporter(verbose=True, out=said.append, err=said.append))
        assert ("streamed in bands" in " ".join(said)) == (name == "s"), said
    for out in ("s.exr", "s_band_0.exr", "s_back.exr"):
        assert filecmp.cmp(tmp_path / out, tmp_path / out.replace("s", "w", 1), shallow=False), out
