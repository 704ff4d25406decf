"""matplotlib is the ``plot`` extra: without it, what draws a picture says how to install it in one line."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from click.testing import CliRunner

import pyramid_cli as pyr
from pyramid_cli.cli import main
from pyramid_cli.core.errors import UsageError

pytestmark = pytest.mark.cli

INSTALL = "pip install 'bilinear-pyramid[plot]'"


@pytest.fixture
def no_matplotlib(monkeypatch):
    """``import matplotlib`` fails as it does where the extra is not installed."""
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)


def _one_error_line(output: str) -> str:
    lines = [line for line in output.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in output, output
    return lines[0]


def test_explain_plot_without_matplotlib(no_matplotlib, tmp_path):
    r = CliRunner().invoke(main, ["explain", "--plot", str(tmp_path / "box4.png"), "box4 *v g"])
    assert r.exit_code == 2, r.output
    line = _one_error_line(r.stderr)
    assert "--plot needs matplotlib" in line and INSTALL in line
    assert not (tmp_path / "box4.png").exists()


def test_diff_heatmap_without_matplotlib(no_matplotlib, tmp_path):
    a, b = str(tmp_path / "a.exr"), str(tmp_path / "b.exr")
    pyr.write_image(a, np.zeros((8, 8, 3), np.float32))
    pyr.write_image(b, np.full((8, 8, 3), 0.5, np.float32))
    r = CliRunner().invoke(main, ["diff", "--out", str(tmp_path / "h.png"), "--heatmap", a, b])
    assert r.exit_code == 2, r.output
    line = _one_error_line(r.stderr)
    assert line.startswith("pyramid diff: error: --heatmap needs matplotlib") and INSTALL in line


def test_heatmap_function_without_matplotlib(no_matplotlib):
    from pyramid_cli.diff.compare import heatmap

    with pytest.raises(UsageError, match=r"bilinear-pyramid\[plot\]"):
        heatmap(np.zeros((2, 2)), np.ones((2, 2)))


def test_the_commands_work_without_matplotlib(no_matplotlib, tmp_path):
    """Nothing else needs it: a plain diff and explain run."""
    a = str(tmp_path / "a.exr")
    pyr.write_image(a, np.zeros((8, 8, 3), np.float32))
    assert CliRunner().invoke(main, ["diff", a, a]).exit_code == 0
    assert CliRunner().invoke(main, ["explain", "box4 *v g"]).exit_code == 0
