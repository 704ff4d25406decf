"""``pyramid farm-template`` (pyramid_cli.cli.farm): its options to the template. The template itself and
``openjd check``/``run`` on it: tests/system/test_openjd.py."""

import json

import pytest

from helpers.cli import invoke

pytestmark = pytest.mark.cli

BLUR = ["blur", "--levels", "2", "/sh/a.####.exr", "-o", "/sh/b.####.exr"]


def test_template_goes_to_stdout_by_default_with_the_options_in_it():
    r = invoke("farm-template", "--frames", "1010-1001", "--chunk", "4", "--name", "soft", "--executable",
               "/opt/bin/pyramid", "--target-seconds", "300", "--", *BLUR)
    assert r.exit_code == 0, r.output
    t = json.loads(r.stdout)
    assert t["name"] == "soft"
    frames, chunk = t["parameterDefinitions"]
    assert frames["default"] == "1001-1010" and chunk["default"] == 4
    (step,) = t["steps"]
    assert step["name"] == "blur"
    run = step["script"]["actions"]["onRun"]
    assert run["command"] == "/opt/bin/pyramid" and run["args"] == [*BLUR, "--frames", "{{Task.Param.Frame}}"]
    assert step["parameterSpace"]["taskParameterDefinitions"][0]["chunks"]["targetRuntimeSeconds"] == 300


def test_output_option_writes_the_file_and_says_so(tmp_path):
    out = tmp_path / "job.json"
    r = invoke("farm-template", "--frames", "1-9", "-o", out, "--", *BLUR)
    assert r.exit_code == 0, r.output
    assert r.stdout == "" and r.stderr == f"wrote {out}\n"
    assert json.loads(out.read_text()) == json.loads(invoke("farm-template", "--frames", "1-9", "--", *BLUR).stdout)


@pytest.mark.parametrize("options, message", [
    (["--frames", "1-9"], "Missing argument"),
    (["--", *BLUR], "Missing option '--frames'"),
    (["--frames", "1-9", "--chunk", "0", "--", *BLUR], "--chunk"),
])
def test_a_bad_command_line_exits_2(options, message):
    r = invoke("farm-template", *options)
    assert r.exit_code == 2 and message in r.output, r.output
