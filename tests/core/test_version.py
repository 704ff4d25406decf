"""The package's version (pyramid_cli.core.version): one number, the same everywhere it is read."""

import re

import pyramid_cli
from helpers.paths import ROOT
from pyramid_cli.core.version import __version__


def test_the_version_is_pyprojects_and_the_packages():
    pyproject = (ROOT / "pyproject.toml").read_text()
    project = pyproject.split("[project]", 1)[1].split("\n[", 1)[0]  # tomllib is Python 3.11+
    assert re.search(r'^version = "([^"]+)"$', project, re.M).group(1) == __version__
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", __version__)
    assert pyramid_cli.__version__ == __version__
