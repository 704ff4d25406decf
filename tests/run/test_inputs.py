"""Reading one input as the read settings say (pyramid_cli.run.inputs), and the NaN/Inf warning."""

import numpy as np
import pytest

import pyramid_cli as pyr
from pyramid_cli.core.errors import DataError
from pyramid_cli.run.inputs import read_input
from pyramid_cli.run.report import Reporter
from pyramid_cli.run.settings import ReadOptions


@pytest.fixture
def nan_exr(tmp_path):
    px = np.full((4, 5, 3), 0.5, np.float32)
    px[1, 1:4, 0] = np.nan
    path = tmp_path / "nan.exr"
    pyr.write_image(path, px)
    return str(path)


def test_nan_kept_is_counted_and_warned(nan_exr):
    said = []
    image = read_input(nan_exr, ReadOptions(), Reporter(err=said.append))
    assert image.pixels.shape == (4, 5, 3) and np.isnan(image.pixels).sum() == 3
    assert said == [f"pyramid: warning: {nan_exr}: 3 NaN/Inf value(s) kept; they spread through the filter "
                    "(--nan zero or --nan fail to change that)"]


def test_nan_kept_is_counted_once_as_read(nan_exr, monkeypatch):
    """The warning's count is the read's own (Image.nonfinite): the pixels are not scanned a second time."""
    import pyramid_cli.imageio as io
    from pyramid_cli.imageio import colour, read

    scans = []
    counted = colour.count_nonfinite
    for where in (io, colour, read):  # the package's name, the function's home and the reader's import
        monkeypatch.setattr(where, "count_nonfinite", lambda px: scans.append(px.size) or counted(px))
    said = []
    image = read_input(nan_exr, ReadOptions(), Reporter(err=said.append))
    assert image.nonfinite == 3 and "3 NaN/Inf" in said[0]
    assert scans == [4 * 5 * 3]


def test_nan_zero_reads_zeros_quietly_and_fail_refuses(nan_exr):
    said = []
    image = read_input(nan_exr, ReadOptions(nan="zero"), Reporter(err=said.append))
    assert said == [] and np.isfinite(image.pixels).all()
    with pytest.raises(DataError):
        read_input(nan_exr, ReadOptions(nan="fail"), Reporter(err=said.append))
