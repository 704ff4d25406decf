"""Open Job Description templates: generated, validated by `openjd check`, run by `openjd run`."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest
from click.testing import CliRunner
from test_sequence import write_sequence

from pyramid_cli import farm
from pyramid_cli.cli import main
from pyramid_cli.errors import UsageError

BIN = os.path.dirname(sys.executable)


def openjd() -> str:
    path = shutil.which("openjd", path=BIN) or shutil.which("openjd")
    if path is None:
        pytest.skip("openjd-cli is not installed (pip install openjd-cli)")
    return path


@pytest.mark.parametrize("frames, expected", [("1001-1240", "1001-1240"), ("1001-1240x2", "1001-1240:2"),
                                              ("1,5-9", "1,5-9"), ("-5--1", "-5--1"), ("1-10x2,20", "1-10:2,20")])
def test_frame_ranges_in_openjd_syntax(frames, expected):
    assert farm.openjd_range(frames) == expected


def test_template_shape_and_errors():
    t = farm.job_template(["blur", "plate.####.exr", "-o", "soft.####.exr"], "1001-1240", chunk=20)
    assert t["specificationVersion"] == "jobtemplate-2023-09" and t["extensions"] == ["TASK_CHUNKING"]
    (param,) = t["steps"][0]["parameterSpace"]["taskParameterDefinitions"]
    assert param["type"] == "CHUNK[INT]" and param["chunks"]["rangeConstraint"] == "CONTIGUOUS"
    assert t["steps"][0]["script"]["actions"]["onRun"]["args"][-2:] == ["--frames", "{{Task.Param.Frame}}"]
    with pytest.raises(UsageError, match="one of apply, blur, mipmap"):
        farm.job_template(["levels", "a.exr", "b_{level}.exr"], "1-2")
    with pytest.raises(UsageError, match="sets --frames itself"):
        farm.job_template(["blur", "p.####.exr", "-o", "o.####.exr", "--frames", "1-3"], "1-2")


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
