"""idiff's defaults, which `pyramid diff` follows (pyramid_cli.diff.idiff).

The real idiff against `pyramid diff`: tests/system/test_idiff.py."""

from pyramid_cli.diff import idiff


def test_defaults_warn_below_failing():
    assert 0 < idiff.DEFAULT_WARN < idiff.DEFAULT_FAIL
