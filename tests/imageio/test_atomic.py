"""Outputs appear whole or not at all (pyramid_cli.imageio.atomic); under real faults: tests/system/test_faults.py."""

import os

import pytest

from pyramid_cli.imageio.atomic import atomic_path


def test_the_output_appears_only_when_the_write_completes(tmp_path):
    final = tmp_path / "out.exr"
    with atomic_path(str(final)) as temporary:
        assert temporary != str(final)
        with open(temporary, "w") as f:
            f.write("x")
        assert not final.exists()
    assert final.read_text() == "x"
    assert os.listdir(tmp_path) == ["out.exr"]


def test_an_input_error_in_the_body_stays_an_input_error(tmp_path):
    from pyramid_cli.core.errors import InputError, OutputError

    with pytest.raises(InputError, match="^cannot read in.exr: truncated$"):  # an OSError, not made an OutputError
        with atomic_path(str(tmp_path / "out.exr")):
            raise InputError("cannot read in.exr: truncated")
    with pytest.raises(OutputError, match="^cannot write x: full$"):
        with atomic_path(str(tmp_path / "out.exr")):
            raise OutputError("cannot write x: full")
    assert os.listdir(tmp_path) == []


def test_a_failed_write_leaves_nothing(tmp_path):
    final = tmp_path / "out.exr"
    with pytest.raises(RuntimeError), atomic_path(str(final)) as temporary:
        with open(temporary, "w") as f:
            f.write("half")
        raise RuntimeError("disk full")
    assert os.listdir(tmp_path) == []
