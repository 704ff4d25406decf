"""Batch jobs: many inputs in one call, as Makefiles and CI use the tool."""

import os
import time

import numpy as np
import OpenImageIO as oiio
import pytest
from click.testing import CliRunner

from pyramid_cli.batch import output_for, plan_jobs
from pyramid_cli.cli import main
from pyramid_cli.errors import UsageError

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


def invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


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
