"""The wheel carries everything the package reads at run time, and the demo runs from it alone."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile

import pytest

from helpers.paths import ROOT


@pytest.mark.slow
def test_the_demo_runs_from_the_built_wheel(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", str(ROOT),
                    "-w", str(tmp_path)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("bilinear_pyramid-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for needed in ("pyramid_cli/exec/gl/pass.frag.glsl", "pyramid_cli/exec/gl/pointwise.frag.glsl",
                   "pyramid_cli/exec/gl/shaders.py",
                   "pyramid_cli/plan/cost_model.json", "pyramid_cli/plan/lower.py", "pyramid_cli/samples/zoneplate.png",
                   "pyramid_cli/samples/highlights.exr"):
        assert needed in names
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    env = {**os.environ, "PYTHONPATH": str(site)}
    out = subprocess.run([sys.executable, "-m", "pyramid_cli.demo", str(tmp_path / "out")], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True).stdout
    assert str(site) in out and len(list((tmp_path / "out").glob("*.png"))) == 9  # 7 + blend_apple_orange, fill_holes
