"""Under CI, nothing the tests need may be missing: the skips elsewhere (no idiff, no chromium, no numba…)
are for machines that truly lack a tool, never a way for a broken install to pass CI quietly."""

from __future__ import annotations

import importlib.util
import os
import shutil
import sys

import pytest

BIN = os.path.dirname(sys.executable)
MODULES = ["numba", "fileseq", "dask", "distributed", "xmlschema", "flip_evaluator", "OpenImageIO", "moderngl",
           "importlinter", "sphinx", "numpydoc", "sphinx_click", "myst_parser", "matplotlib"]
PROGRAMS = ["idiff", "maketx", "oiiotool", "openjd", "chromium", "make"]


@pytest.mark.skipif(not os.environ.get("CI"), reason="only CI must have every tool (.ci/run installs them)")
@pytest.mark.parametrize("name", MODULES + PROGRAMS)
def test_ci_has_everything_the_tests_use(name):
    if name in MODULES:
        assert importlib.util.find_spec(name) is not None, f"{name} is not installed: see pyproject's test extra"
    else:
        assert shutil.which(name, path=BIN) or shutil.which(name), f"{name} is not on PATH: see .ci/run"
