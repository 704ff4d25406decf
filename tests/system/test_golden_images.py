"""Golden images, checked with `pyramid diff` itself. Goldens come from the numpy reference of
the paper's formulas, never from the GL path they check."""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.cases import NAMED
from helpers.images import write
from helpers.paths import ROOT
from pyramid_cli.cli import main
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference
from pyramid_cli.reference.pyramids import blur_reference

pytestmark = pytest.mark.cli


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    d = tmp_path_factory.mktemp("golden")
    px = np.random.default_rng(2007).random((37, 29, 3)).astype(np.float32)
    write(d / "input.exr", px)
    return d, px.astype(np.float64)


def diff(a, b):
    return CliRunner().invoke(main, ["diff", str(a), str(b)])


@pytest.mark.parametrize("text", NAMED)
def test_named_filter_matches_its_reference_golden(source, text):
    d, px = source
    golden = d / f"golden_{abs(hash(text))}.exr"
    write(golden, reference.run(parse(text), px))
    out = d / f"out_{abs(hash(text))}.exr"
    r = CliRunner().invoke(main, ["apply", "-q", text, str(d / "input.exr"), str(out)])
    assert r.exit_code == 0, r.output
    r = diff(out, golden)
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("analysis, synthesis", [("box", "doosabin"), ("box4", "doosabin"),
                                                 ("quadratic", "cubic"), ("cubic", "fourpoint")])
def test_blur_matches_its_reference_golden(source, analysis, synthesis):
    d, px = source
    golden = d / f"blur_{analysis}_{synthesis}.exr"
    write(golden, blur_reference(px, 3, analysis, synthesis))
    out = d / f"out_blur_{analysis}_{synthesis}.exr"
    r = CliRunner().invoke(main, ["blur", "-q", "--levels", "3", "--analysis", analysis, "--synthesis", synthesis,
                                  "--allow-mixed-lattice", str(d / "input.exr"), str(out)])
    assert r.exit_code == 0, r.output
    assert diff(out, golden).exit_code == 0


def test_levels_match_their_reference_goldens(source):
    d, px = source
    r = CliRunner().invoke(main, ["levels", "-q", "--levels", "3", "--analysis", "quadratic", str(d / "input.exr"),
                                  str(d / "lvl_{level}.exr")])
    assert r.exit_code == 0, r.output
    x = px
    for k in range(4):
        if k:
            x = reference.run(parse("quadratic *v g"), x)
        write(d / f"lvl_golden_{k}.exr", x)
        assert diff(d / f"lvl_{k}.exr", d / f"lvl_golden_{k}.exr").exit_code == 0


def test_a_wrong_result_fails_the_golden_check(source):
    """The check can fail: box↘ where box↖ was meant is caught."""
    d, px = source
    write(d / "wrong_golden.exr", reference.run(parse("box^nw * g"), px))
    r = CliRunner().invoke(main, ["apply", "-q", "box * g", str(d / "input.exr"), str(d / "wrong.exr")])
    assert r.exit_code == 0
    assert diff(d / "wrong.exr", d / "wrong_golden.exr").exit_code == 2


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_samples_makefile_batch_job_passes(tmp_path):
    pyramid = os.path.join(os.path.dirname(sys.executable), "pyramid")
    r = subprocess.run(["make", "-s", "-C", os.path.join(ROOT, "samples"), f"OUT={tmp_path}", f"PYRAMID={pyramid}"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    names = sorted(os.listdir(tmp_path))
    assert "highlights_blur.ok" in names and "zoneplate.tx.exr" in names
