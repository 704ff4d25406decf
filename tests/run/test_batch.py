"""Batch jobs: many inputs in one call, as Makefiles and CI use the tool."""

import os
import time

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import invoke
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run.batch import output_for, plan_jobs

pytestmark = pytest.mark.cli


def write_png(path, seed):
    px = (np.random.default_rng(seed).random((12, 10, 3)) * 255).astype(np.uint8)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(10, 12, 3, "uint8"))
    out.write_image(px)
    out.close()


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "in").mkdir()
    for i in range(5):
        write_png(tmp_path / "in" / f"img{i}.png", i)
    return tmp_path


def test_template_fields():
    assert output_for("out/{stem}_blur{ext}", "a/b/photo.png") == "out/photo_blur.png"
    assert output_for("{dir}/{name}.exr", "a/b/photo.png") == "a/b/photo.png.exr"
    with pytest.raises(UsageError, match="bad output template"):
        output_for("{nope}", "x.png")


def test_two_paths_without_template_is_one_job_and_globs_need_a_template():
    assert len(plan_jobs(["a.png", "b.png"], None)) == 1
    with pytest.raises(UsageError):
        plan_jobs(["a.png", "b.png", "c.png"], None)


def test_outputs_must_be_distinct(folder):
    with pytest.raises(UsageError, match="same output"):
        plan_jobs([str(folder / "in" / "*.png")], str(folder / "out.png"))


def test_blur_many_inputs_in_one_call(folder):
    r = invoke("blur", "--backend", "cpu", "--levels", "2", folder / "in" / "*.png", "-o",
               folder / "out" / "{stem}_blur.png")
    assert r.exit_code == 0, r.output
    outs = sorted(os.listdir(folder / "out"))
    assert outs == [f"img{i}_blur.png" for i in range(5)]
    assert "5 written, 0 up to date, 0 failed" in r.output
    assert "wrote" in r.output  # not a terminal: per-file lines, no progress bar


def test_keep_going_reports_failures_and_exits_non_zero(folder):
    (folder / "in" / "broken.png").write_text("not a png")
    r = invoke("apply", "--backend", "cpu", "box *v g", folder / "in" / "*.png", "-o", folder / "out" / "{name}",
               "--keep-going")
    assert r.exit_code == 3
    assert len(os.listdir(folder / "out")) == 5
    assert "broken.png" in r.output and "1 failed" in r.output


def test_without_keep_going_stops_at_the_first_failure(folder):
    (folder / "in" / "a_broken.png").write_text("not a png")
    r = invoke("apply", "--backend", "cpu", "--jobs", "1", "box *v g", folder / "in" / "*.png",
               "-o", folder / "out" / "{name}")
    assert r.exit_code == 3
    assert not (folder / "out").exists() or not os.listdir(folder / "out")


def test_skip_existing_skips_fresh_outputs_only(folder):
    args = ["apply", "--backend", "cpu", "box *v g", folder / "in" / "*.png", "-o", folder / "out" / "{name}"]
    assert invoke(*args).exit_code == 0
    later = time.time() + 5
    os.utime(folder / "in" / "img2.png", (later, later))  # one input changed after its output
    r = invoke(*args, "--skip-existing")
    assert r.exit_code == 0
    assert "1 written, 4 up to date" in r.output


def test_no_match_is_an_input_error(folder):
    r = invoke("blur", folder / "in" / "*.exr", "-o", folder / "{stem}.exr")
    assert r.exit_code == 3 and "no file matches" in r.output


def test_quiet_prints_nothing(folder):
    r = invoke("blur", "--backend", "cpu", "-q", folder / "in" / "*.png", "-o", folder / "out" / "{name}")
    assert r.exit_code == 0 and r.output == ""


def test_frame_numbered_plain_files_keep_their_names(tmp_path):
    """Digits in a name are no frame token: plain inputs and outputs keep their names (issue 22)."""
    (tmp_path / "in").mkdir()
    write_png(tmp_path / "in" / "plate.1001.png", 1)
    write_png(tmp_path / "in" / "v2.1001_1.png", 2)
    r = invoke("blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "*.png", "-o",
               tmp_path / "out" / "{stem}_blur{ext}")
    assert r.exit_code == 0, r.output
    assert sorted(os.listdir(tmp_path / "out")) == ["plate.1001_blur.png", "v2.1001_1_blur.png"]
    r = invoke("blur", "--backend", "cpu", "--levels", "2", tmp_path / "in" / "plate.1001.png",
               tmp_path / "soft.1001_2.png")
    assert r.exit_code == 0, r.output
    assert (tmp_path / "soft.1001_2.png").exists()


@pytest.mark.parametrize("args, message", [
    (["IN/img0.png", "OUT/soft.####.png"], "a frame token in the output, and"),
    (["IN/img0.png", "-o", "OUT/soft.####.png"], "has a frame token (####), and"),
    (["IN/*.png", "-o", "OUT/soft_{frame}.png"], "has {frame}, and"),
])
def test_a_frame_in_the_output_of_a_plain_input_is_refused(folder, args, message):
    args = [a.replace("IN", str(folder / "in")).replace("OUT", str(folder / "out")) for a in args]
    r = invoke("blur", "--backend", "cpu", *args)
    assert r.exit_code == 2 and message in r.output and r.output.count("\n") == 1
    assert not (folder / "out").exists()


def test_lines_are_said_in_job_order_whichever_write_ends_first():
    """Writes overlap in worker threads; what they return reaches ``written`` in job order, in the calling thread."""
    import threading

    from pyramid_cli.run import batch

    jobs = [batch.Job(f"in{k}", f"out{k}") for k in range(6)]

    def write(job, value):
        time.sleep(0.05 if job.input == "in0" else 0.0)  # the first write ends last
        return value

    said, threads = [], set()

    def written(job, value):
        said.append(value)
        threads.add(threading.get_ident())

    report = batch.run(jobs, lambda j: j.input, lambda v: v.upper(), write, workers=3, written=written)
    assert said == ["IN0", "IN1", "IN2", "IN3", "IN4", "IN5"] and len(report.done) == 6
    assert threads == {threading.get_ident()}


def test_a_batch_s_progress_counts_the_outputs_it_skips(tmp_path):
    """A progress bar over a batch reaches its end with --skip-existing: skipped jobs move it too."""
    from pyramid_cli.run import batch

    jobs = []
    for k in range(3):
        (tmp_path / f"in{k}").write_text("x")
        jobs.append(batch.Job(str(tmp_path / f"in{k}"), str(tmp_path / f"out{k}")))
    time.sleep(0.01)
    (tmp_path / "out1").write_text("newer than its input")
    moved = []
    report = batch.run(jobs, lambda j: j, lambda x: x, lambda j, x: None, skip_existing=True, workers=2,
                       progress=moved.append)
    assert [j.input for j in report.skipped] == [jobs[1].input] and len(report.done) == 2
    assert sorted(j.input for j in moved) == sorted(j.input for j in jobs)
