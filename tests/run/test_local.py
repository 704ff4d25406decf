"""The local runner (pyramid_cli.run.local): read → run → write a list of jobs on one session, and a texture's
channels as maketx's --nchannels and --monochrome-detect change them. Whole commands: tests/run/test_batch.py."""

from pathlib import Path

import numpy as np
import pytest

import pyramid_cli as pyr
from pyramid_cli import imageio as io
from pyramid_cli.exec.session import Session
from pyramid_cli.jobs.texture import TextureLevels
from pyramid_cli.run import batch
from pyramid_cli.run.local import held_at_once, run_in_budget, run_jobs, texture_channels
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.settings import ReadOptions, WriteOptions
from pyramid_cli.run.weight import weigh


@pytest.fixture(scope="module")
def session():
    with Session("cpu") as s:
        yield s


def exr_jobs(tmp_path, sizes, seed, channels=4, half=True) -> list[batch.Job]:
    """One job per size (rows, columns): a random EXR ``in{k}.exr`` (half unless told) to ``out{k}.exr``."""
    rng = np.random.default_rng(seed)
    jobs = []
    for k, (h, w) in enumerate(sizes):
        px = rng.random((h, w, channels), dtype=np.float32)
        pyr.write_image(tmp_path / f"in{k}.exr", px.astype(np.float16) if half else px)
        jobs.append(batch.Job(str(tmp_path / f"in{k}.exr"), str(tmp_path / f"out{k}.exr")))
    return jobs


@pytest.fixture
def small_is_large(monkeypatch):
    """The thresholds scaled down so that 300×420 pictures stream faster (run.stream.speed_band) and count as
    large (run.local.ALONE_PIXELS, to be set by the test)."""
    from pyramid_cli.run import local, stream

    monkeypatch.setattr(stream, "STREAM_PIXELS", 1 << 14)
    monkeypatch.setattr(stream, "BAND_PIXELS", 1 << 12)
    return local


def test_run_jobs_writes_each_output_and_says_so_in_job_order(tmp_path, session):
    jobs = []
    for k in range(3):
        pyr.write_image(tmp_path / f"in{k}.exr", np.full((6, 8, 3), k / 4, np.float32))
        jobs.append(batch.Job(str(tmp_path / f"in{k}.exr"), str(tmp_path / f"out{k}.exr")))
    (tmp_path / "in1.exr").write_text("not an exr")
    out = []
    report = run_jobs(jobs, pyr.Blur(levels=1), session, read=ReadOptions(), write=WriteOptions(),
                      reporter=Reporter(out=out.append, err=out.append), keep_going=True)
    assert [j.input for j in report.done] == [jobs[0].input, jobs[2].input] and len(report.failed) == 1
    assert out == [f"wrote {jobs[0].output} (8×6, {session.ran})", f"wrote {jobs[2].output} (8×6, {session.ran})"]
    np.testing.assert_allclose(pyr.read_image(jobs[2].output).pixels, 0.5, atol=1e-6)  # a constant stays constant


def test_texture_channels_makes_a_grey_texture_one_channel(tmp_path):
    grey = np.repeat(np.linspace(0, 1, 20, dtype=np.float32).reshape(4, 5, 1), 3, axis=2)
    pyr.write_image(tmp_path / "grey.exr", grey)
    image = io.read_image(str(tmp_path / "grey.exr"))
    said = []
    reporter = Reporter(verbose=True, err=said.append)
    assert texture_channels(image, TextureLevels(), "grey.exr", reporter) is image  # nothing asked: as it is
    mono = texture_channels(image, TextureLevels(monochrome_detect=True), "grey.exr", reporter)
    assert mono.pixels.shape == (4, 5, 1) and len(mono.spec.channel_names) == 1
    np.testing.assert_array_equal(mono.pixels[..., 0], grey[..., 0])
    assert said == ["pyramid: grey.exr: 3 channel(s) → 1 (Y): monochrome"]


@pytest.mark.parametrize("ext, levels_as", [("exr", np.float16), ("tx", np.float32)])
def test_a_half_texture_is_read_half_and_its_levels_made_half_where_the_file_keeps_half(tmp_path, session,
                                                                                        monkeypatch, ext,
                                                                                        levels_as):
    """A whole MIP map of a half EXR: no float32 copy of the input (kept as read, the kernels read half); OpenEXR
    levels come out half as the writer would round them, a TIFF texture's float as it stores them. The file is
    the same as the streamed run's (tests/run/test_stream_mip.py compares those for half inputs too)."""
    src = tmp_path / "in.exr"
    px = np.random.default_rng(4).random((40, 56, 4)).astype(np.float16)
    pyr.write_image(src, px, pixel_type="half")
    seen = []
    real = Session.run

    def spy(self, work, images, dtype=np.float32):
        outs = real(self, work, images, dtype)
        seen.append((np.asarray(images[0] if isinstance(images, list) else images).dtype, [o.dtype for o in outs]))
        return outs

    monkeypatch.setattr(Session, "run", spy)
    job = batch.Job(str(src), str(tmp_path / f"out.{ext}"))
    run_jobs([job], TextureLevels(), session, read=ReadOptions(), write=WriteOptions(), reporter=Reporter(),
             mip_tile=16)
    ((given, made),) = seen
    assert given == np.float16 and made[0] == np.float16  # level 0: the input as read
    assert set(made[1:]) == {np.dtype(levels_as)} and len(made) > 3
    got = io.read_image(job.output)
    np.testing.assert_array_equal(got.pixels, px.astype(np.float32))


def test_a_batch_holds_a_picture_its_budget_cannot_hold_beside_others_alone_and_streams_it(tmp_path, session):
    """run_in_budget: a picture whose whole run, held as many times as the batch holds pictures (held_at_once),
    would not fit the budget runs alone, streamed when it does not fit alone either; the small ones overlap as
    before. Job order is kept and the files are those of the plain batch (run_jobs), byte for byte."""
    jobs = exr_jobs(tmp_path, [(16, 20), (300, 420), (24, 16)], seed=7)
    work = pyr.Blur(levels=3)
    big = weigh(jobs[1].input, work, session).whole
    small = max(weigh(j.input, work, session).whole for j in (jobs[0], jobs[2]))
    memory = big // 2  # the big one streams even alone; the small ones fit the batch's share of it
    assert small * held_at_once(2) < memory < big
    out = []
    report = run_in_budget(jobs, work, session, memory=memory, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter(out=out.append, err=out.append, verbose=True))
    assert [j.input for j in report.done] == [j.input for j in jobs] and not report.failed
    wrote = [line for line in out if line.startswith("wrote ")]
    assert [line.split()[1] for line in wrote] == [j.output for j in jobs]
    assert "streamed in bands of" in wrote[1] and "streamed" not in wrote[0] + wrote[2], wrote
    plain = [batch.Job(j.input, j.output.replace("out", "plain")) for j in jobs]
    run_jobs(plain, work, session, read=ReadOptions(), write=WriteOptions(), reporter=Reporter(out=out.append))
    for a, b in zip(jobs, plain, strict=True):
        assert (tmp_path / a.output).read_bytes() == (tmp_path / b.output).read_bytes()


@pytest.mark.parametrize("keep_going", [False, True])
def test_a_picture_run_alone_that_fails_is_reported_and_the_batch_goes_on_only_when_asked(tmp_path, session,
                                                                                         keep_going):
    jobs = exr_jobs(tmp_path, [(200, 260)] * 3, seed=8, channels=3, half=False)
    (tmp_path / "blocker").write_text("a file, not a folder")
    jobs[0] = batch.Job(jobs[0].input, str(tmp_path / "blocker" / "out0.exr"))  # cannot be written
    work = pyr.Blur(levels=2)
    memory = weigh(jobs[1].input, work, session).whole // 2  # every picture runs alone, streamed
    out = []
    report = run_in_budget(jobs, work, session, memory=memory, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter(out=out.append, err=out.append), keep_going=keep_going)
    assert [j.output for j, _ in report.failed] == [jobs[0].output]
    assert "blocker" in str(report.failed[0][1])
    written = [j.output for j in jobs[1:]] if keep_going else []
    assert [j.output for j in report.done] == written
    assert sorted(p.name for p in tmp_path.glob("out*.exr")) == sorted(Path(p).name for p in written)


def test_held_at_once_counts_the_reads_ahead_the_work_and_the_writes_behind():
    """batch.run overlaps with two threads or more; with one it holds one picture at a time; never more pictures
    than the batch has."""
    assert held_at_once(2) == 6 and held_at_once(4) == 10 and held_at_once(1) == held_at_once(0) == 1
    assert held_at_once(2, 2) == 2 and held_at_once(2, 9) == 6 and held_at_once(4, 1) == held_at_once(2, 0) == 1


def test_two_pictures_overlap_where_the_budget_holds_both_whole_runs(tmp_path, session, monkeypatch):
    """A batch of two holds two pictures at most: where two whole runs fit the budget (six would not) they
    overlap as a batch does instead of running one after the other. Two 8K MIP maps lost their overlap to the
    six-picture bound (9.5 → 10.7 s)."""
    from pyramid_cli.run import local

    jobs = exr_jobs(tmp_path, [(120, 160)] * 2, seed=9)
    work = pyr.Blur(levels=3)
    memory = weigh(jobs[0].input, work, session).whole * 3  # two whole runs fit; six would not
    alone = []
    monkeypatch.setattr(local, "run_alone", lambda job, *a, **k: alone.append(job) or False)
    report = run_in_budget(jobs, work, session, memory=memory, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter())
    assert alone == [] and [j.input for j in report.done] == [j.input for j in jobs]
    report = run_in_budget(jobs * 4, work, session, memory=memory, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter())  # eight: six held at once would not fit
    assert len(alone) == 8 and len(report.done) == 8


@pytest.mark.parametrize("jobs, large, streamed",
                         [(2, 1 << 24, False), (2, 100_000, True), (1, 1 << 24, False), (1, 100_000, True)])
def test_a_large_picture_that_streams_faster_alone_leaves_the_overlap(tmp_path, session, monkeypatch, small_is_large,
                                                                       jobs, large, streamed):
    """Pictures that stream faster than they run whole (run.stream.speed_band) and have ALONE_PIXELS or more
    stream one by one, as one input would, with one thread as with two. Two 8K
    frames overlapped took 7.5 s and 1.8 GB, streamed one by one 5.1 s and 141 MiB. The thresholds are scaled
    down here so that 300×420 pictures count as large."""
    monkeypatch.setattr(small_is_large, "ALONE_PIXELS", large)
    jobs_list = exr_jobs(tmp_path, [(300, 420)] * 3, seed=10, channels=3)
    work = pyr.Blur(levels=2)
    assert weigh(jobs_list[0].input, work, session).streamed == 300 * 420
    assert weigh(jobs_list[0].input, pyr.TextureLevels(), session, tile=64).streamed == 0  # MIP files: by fit only
    out = []
    report = run_in_budget(jobs_list, work, session, memory=None, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter(out=out.append, err=out.append), jobs=jobs)
    assert [j.input for j in report.done] == [j.input for j in jobs_list]
    wrote = [line for line in out if line.startswith("wrote ")]
    assert [line.split()[1] for line in wrote] == [j.output for j in jobs_list]
    assert all(("streamed in bands of" in line) == streamed for line in wrote), wrote


def test_a_batch_with_pictures_run_alone_shows_one_progress_bar_over_all_of_them(tmp_path, session, monkeypatch,
                                                                                 small_is_large):
    """At a terminal a batch shows a bar, not a line per file, whether its pictures overlap or some run alone:
    one bar over the whole batch, moved once per picture; without a bar each picture's line is printed."""
    monkeypatch.setattr(small_is_large, "ALONE_PIXELS", 100_000)
    jobs = exr_jobs(tmp_path, [(16, 20), (300, 420), (24, 16), (20, 20)], seed=11, channels=3, half=False)  # 2nd alone
    bars = []

    class Bar:
        def __init__(self, total):
            self.total, self.moved = total, 0
            bars.append(self)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def update(self, n):
            self.moved += n

    out = []
    report = run_in_budget(jobs, pyr.Blur(levels=2), session, memory=None, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter(out=out.append, err=out.append, progress=Bar))
    assert len(report.done) == 4 and [(b.total, b.moved) for b in bars] == [(4, 4)] and out == []
    out.clear()
    report = run_in_budget(jobs, pyr.Blur(levels=2), session, memory=None, read=ReadOptions(), write=WriteOptions(),
                           reporter=Reporter(out=out.append, err=out.append))
    assert [line.split()[1] for line in out] == [j.output for j in jobs]
    assert "streamed in bands" in out[1] and len(bars) == 1
