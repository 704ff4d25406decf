"""The kernel cache of the CPU executor's test modules."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


@pytest.fixture(scope="module", autouse=True)
def cache_folder():
    """The kernel cache of this module (the environment variable every executor and child reads): one folder
    kept across test runs on a machine, so a rerun loads instead of compiling; the compile-then-load test
    (test_compile.py) uses a fresh one of its own."""
    import tempfile

    from pyramid_cli.exec import cpu

    folder = Path(tempfile.gettempdir()) / f"pyramid-cpu-test-cache-{os.getuid()}"
    folder.mkdir(exist_ok=True)
    saved = os.environ.get(cpu.CACHE_ENV)
    os.environ[cpu.CACHE_ENV] = str(folder)
    yield folder
    if saved is None:
        os.environ.pop(cpu.CACHE_ENV, None)
    else:
        os.environ[cpu.CACHE_ENV] = saved
