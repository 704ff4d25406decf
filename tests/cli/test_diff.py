"""`pyramid diff`'s command line (pyramid_cli.cli.diff); its comparisons: tests/diff/, the real idiff: tests/system."""

from pyramid_cli.cli.diff import idiff_argv


def test_idiff_spellings_become_options():
    assert idiff_argv(["-fail", "0.1", "-warn", "0.01", "a.exr", "b.exr"]) == ["--fail", "0.1", "--warn", "0.01",
                                                                             "a.exr", "b.exr"]
