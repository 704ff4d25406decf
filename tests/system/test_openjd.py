"""Open Job Description templates: generated, validated by `openjd check`, run by `openjd run`."""

from __future__ import annotations

import filecmp
import json
import os
import random
import re
import shutil
import subprocess
import sys

import pytest
from click.testing import CliRunner

from helpers.images import write_sequence
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run import farm, sequence

BIN = os.path.dirname(sys.executable)


def openjd() -> str:
    path = shutil.which("openjd", path=BIN) or shutil.which("openjd")
    if path is None:
        pytest.skip("openjd-cli is not installed (pip install openjd-cli)")
    return path


@pytest.mark.parametrize("frames, expected", [
    ("1001-1240", "1001-1240"),
    ("1001-1240x2", "1001-1239:2"),
    ("1001-1240:2", "1001-1239:2"),        # OpenJD's step, the same frames as x
    ("1010-1001", "1001-1010"),            # ascending, as openjd run requires
    ("19-1x2", "1-19:2"),
    ("1,5-9", "1,5-9"),
    ("-5--1", "-5--1"),
    ("1-10x2,20", "1-9:2,20"),
    ("1-5,3-7", "1-7"),                    # overlaps, which OpenJD refuses, merged
])
def test_frame_ranges_in_openjd_syntax(frames, expected):
    assert farm.openjd_range(frames) == expected


@pytest.mark.slow
def test_range_spellings_mean_the_same_to_openjd():
    """What farm-template writes, OpenJD reads as the same frames; what OpenJD hands a task, --frames reads so."""
    ranges = pytest.importorskip("openjd.model._range_expr")
    rng = random.Random(22)
    for _ in range(300):
        frames = sorted({rng.randint(-40, 40) for _ in range(rng.randint(1, 30))})
        text = sequence.range_text(frames)
        assert list(ranges.IntRangeExpr.from_str(text)) == frames, text
        handed = str(ranges.IntRangeExpr.from_list(frames))
        assert sequence.frame_set(handed) == frames, handed


def test_a_range_too_long_for_a_job_parameter_is_refused():
    frames = ",".join(str(f * f) for f in range(1, 300))   # 299 frames, no run: 1500 characters
    with pytest.raises(UsageError, match=r"take \d+ characters .* more than a job parameter holds \(1024\)"):
        farm.openjd_range(frames)


def test_template_shape_and_errors():
    t = farm.job_template(["blur", "plate.####.exr", "-o", "soft.####.exr"], "1001-1240", chunk=20)
    assert t["specificationVersion"] == "jobtemplate-2023-09" and t["extensions"] == ["TASK_CHUNKING"]
    (param,) = t["steps"][0]["parameterSpace"]["taskParameterDefinitions"]
    assert param["type"] == "CHUNK[INT]" and param["chunks"]["rangeConstraint"] == "NONCONTIGUOUS"
    assert t["steps"][0]["script"]["actions"]["onRun"]["args"][-2:] == ["--frames", "{{Task.Param.Frame}}"]
    with pytest.raises(UsageError, match="one of apply, blur, mipmap"):
        farm.job_template(["levels", "a.exr", "b_{level}.exr"], "1-2")
    base = ["blur", "p.####.exr", "-o", "o.####.exr"]
    for extra, message in [(["--frames", "1-3"], "farm-template sets --frames itself"),
                           (["--cluster", "local:2"], "--cluster cannot be in a farm template's command: the farm's "
                                                      "tasks are the split"),
                           (["--shard=1/2"], "--shard cannot be in a farm template's command"),
                           (["--chunk", "3"], "give farm-template's own --chunk N"),
                           (["--keep-going", "-o", "{{Param.X}}.####.exr"], "read by Open Job Description")]:
        with pytest.raises(UsageError) as e:
            farm.job_template(base + extra, "1-2")
        assert message in str(e.value) and "sets --cluster" not in str(e.value)


@pytest.mark.cli
@pytest.mark.parametrize("command, message", [
    (["blur", "/in/plate.####.exr", "-o", "/out/soft.exr"], "gives frame 1 and frame 2 the same output"),
    (["blur", "in/plate.####.exr", "-o", "/out/soft.####.exr"], "in/plate.####.exr: a farm task runs in a session"),
    (["blur", "/in/plate.1-5#.exr", "-o", "/out/s.####.exr"], "frames 6-10 are outside /in/plate.1-5#.exr's own"),
    (["blur", "/in/plate.####.exr", "-o", "/out/{nope}.####.exr"], "unknown field 'nope'"),
    (["blur", "/in/a.exr", "-o", "/out/{stem}.exr"], "/in/a.exr is not one"),
    (["blur", "--levels", "x", "/in/plate.####.exr", "-o", "/o.####.exr"], "the command after --: Invalid value"),
    (["apply", "bartlet *v g", "/in/plate.####.exr", "-o", "/o.####.exr"], "unknown filter 'bartlet'"),
])
def test_what_a_task_would_refuse_is_refused_when_written(tmp_path, command, message):
    r = CliRunner().invoke(main, ["farm-template", "--frames", "1-10", "-o", str(tmp_path / "t.json"), "--",
                                  *command])
    assert r.exit_code == 2 and message in r.output and r.output.count("\n") == 1, r.output
    assert not (tmp_path / "t.json").exists()


@pytest.mark.slow
@pytest.mark.cli
def test_openjd_check_and_run_on_a_small_sequence(tmp_path):
    tool = openjd()
    write_sequence(tmp_path / "in", 1, 5)
    template = tmp_path / "job" / "template.json"
    r = CliRunner().invoke(main, ["farm-template", "--frames", "1-5", "--chunk", "2", "-o", str(template),
                                  "--executable", os.path.join(BIN, "pyramid"), "--",
                                  "blur", "--backend", "cpu", "--levels", "2", str(tmp_path / "in" / "plate.####.exr"),
                                  "-o", str(tmp_path / "out" / "soft.####.exr")])
    assert r.exit_code == 0, r.output
    assert json.loads(template.read_text())["parameterDefinitions"][0]["default"] == "1-5"
    check = subprocess.run([tool, "check", str(template)], capture_output=True, text=True, timeout=60)
    assert check.returncode == 0, check.stdout + check.stderr
    run = subprocess.run([tool, "run", str(template)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "Chunks run: 3" in run.stdout
    assert sorted(os.listdir(tmp_path / "out")) == [f"soft.{f:04d}.exr" for f in range(1, 6)]


def _farm_and_local(tmp_path, frames: str, chunk: int, output: str) -> tuple[list[list[int]], str]:
    """Write a template, ``openjd run`` it into farm/, run the same command locally into local/.

    Returns each task's frames (as ``openjd run`` logged them) and the output folder's name pattern.
    """
    tool = openjd()
    command = ["blur", "--backend", "cpu", "--levels", "2", str(tmp_path / "in" / "plate.####.exr")]
    template = tmp_path / "job" / "template.json"
    r = CliRunner().invoke(main, ["farm-template", "--frames", frames, "--chunk", str(chunk), "-o", str(template),
                                  "--executable", os.path.join(BIN, "pyramid"), "--",
                                  *command, "-o", str(tmp_path / "farm" / output)])
    assert r.exit_code == 0, r.output
    check = subprocess.run([tool, "check", str(template)], capture_output=True, text=True, timeout=60)
    assert check.returncode == 0, check.stdout + check.stderr
    run = subprocess.run([tool, "run", str(template)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    tasks = [sequence.frame_set(m) for m in re.findall(r"Frame\(CHUNK\[INT\]\) = (\S+)", run.stdout)]
    local = CliRunner().invoke(main, [*command, "-o", str(tmp_path / "local" / output), "--frames", frames])
    assert local.exit_code == 0, local.output
    names = sorted(os.listdir(tmp_path / "local"))
    assert sorted(os.listdir(tmp_path / "farm")) == names
    match, mismatch, errors = filecmp.cmpfiles(tmp_path / "farm", tmp_path / "local", names, shallow=False)
    assert match == names and not mismatch and not errors
    return tasks, names


@pytest.mark.slow
@pytest.mark.cli
def test_openjd_runs_stepped_descending_chunked_frames_with_combined_fields(tmp_path):
    """1001-1020x2 at --chunk 4 was ten one-frame tasks; 1010-1001 was refused by openjd run (issue 22)."""
    write_sequence(tmp_path / "in", 1, 19, size=(16, 16))
    tasks, names = _farm_and_local(tmp_path, "19-1x2", 4, "{stem}_blur_{frame:05d}{ext}")
    assert tasks == [[1, 3, 5, 7], [9, 11, 13], [15, 17, 19]]
    assert names == [f"plate.{f:04d}_blur_{f:05d}.exr" for f in range(1, 20, 2)]


@pytest.mark.slow
@pytest.mark.cli
def test_openjd_runs_a_listed_range_with_a_token_and_fields(tmp_path):
    write_sequence(tmp_path / "in", 1, 10, size=(16, 16))
    tasks, names = _farm_and_local(tmp_path, "9-10,1-3,7", 2, "{stem}.soft.####{ext}")
    assert tasks == [[1, 2], [3, 7], [9, 10]]
    assert names == [f"plate.{f:04d}.soft.{f:04d}.exr" for f in (1, 2, 3, 7, 9, 10)]
