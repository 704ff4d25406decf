"""How a command's options become a run (pyramid_cli.cli.running): the reporter, the session, the read and
write settings."""

import numpy as np
import pytest

from helpers.cli import invoke
from helpers.images import read_with_spec as read
from helpers.images import write as write_exr
from pyramid_cli.cli.running import drop, make_reporter, open_session, read_write


def _opts(**changes):
    """The io options as a command receives them (the defaults of pyramid_cli.cli.params.io_options)."""
    opts = {"backend": "cpu", "threads": None, "precision": "float", "pixel_type": None, "colorspace": "auto",
            "alpha": "auto", "nan_policy": "keep", "dither": False, "compression": None, "force": False,
            "verbose": False, "quiet": False}
    return {**opts, **changes}


@pytest.mark.cli
def test_compression_option_reaches_the_file(tmp_path):
    src = tmp_path / "in.exr"
    write_exr(src, np.random.default_rng(4).random((16, 16, 3)))
    r = invoke("apply", "--backend", "cpu", "--compression", "piz", "bartlett", str(src), str(tmp_path / "o.exr"))
    assert r.exit_code == 0, r.output
    assert read(tmp_path / "o.exr")[1].get_string_attribute("compression") == "piz"
    r = invoke("apply", "--backend", "cpu", "bartlett", str(src), str(tmp_path / "same.exr"))
    assert read(tmp_path / "same.exr")[1].get_string_attribute("compression") == "zip"  # follows the input


def test_read_write_carries_every_io_option():
    ro, wo = read_write(_opts(colorspace="srgb", alpha="straight", nan_policy="zero", pixel_type="half",
                              dither=True, compression="piz", force=True))
    assert (ro.colorspace, ro.alpha, ro.nan) == ("srgb", "straight", "zero")
    assert (wo.pixel_type, wo.dither, wo.compression, wo.force) == ("half", True, "piz", True)


def test_make_reporter_follows_quiet_and_verbose():
    assert make_reporter(_opts(quiet=True)).quiet and not make_reporter(_opts(quiet=True)).verbose
    assert make_reporter(_opts(verbose=True)).verbose
    assert drop("anything") is None


def test_open_session_is_the_backend_asked_for_and_says_so_under_verbose():
    reporter = make_reporter(_opts(verbose=True))
    said = []
    reporter.err = said.append
    with open_session(_opts(threads=1), reporter) as session:
        assert session.name.startswith("cpu (")
    assert len(said) == 1 and said[0].startswith("pyramid: executor cpu (")
