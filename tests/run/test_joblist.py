"""A batch's jobs (pyramid_cli.run.joblist): inputs a command line names, make's freshness rule, the report."""

import os

import pytest

from pyramid_cli.core.errors import DataError, InputError
from pyramid_cli.run.joblist import Job, Report, expand, is_fresh


def test_globs_are_expanded_sorted_and_plain_paths_kept(tmp_path):
    for name in ("b.png", "a.png", "c.exr"):
        (tmp_path / name).write_bytes(b"")
    assert expand([str(tmp_path / "*.png"), "missing.exr"]) == [str(tmp_path / "a.png"), str(tmp_path / "b.png"),
                                                                  "missing.exr"]
    with pytest.raises(InputError, match=r"\*\.tif: no file matches this pattern"):
        expand([str(tmp_path / "*.tif")])


def test_an_output_is_fresh_when_not_older_than_its_input(tmp_path):
    src, out = tmp_path / "in.png", tmp_path / "out.png"
    src.write_bytes(b"")
    job = Job(str(src), str(out))
    assert not is_fresh(job)  # no output
    out.write_bytes(b"")
    os.utime(src, (1000, 1000))
    assert is_fresh(job)
    os.utime(src, (os.path.getmtime(out) + 5,) * 2)
    assert not is_fresh(job)


def test_the_exit_code_is_the_first_failures():
    report = Report()
    assert report.exit_code == 0
    report.done.append(Job("a", "b"))
    report.failed += [(Job("c", "d"), DataError("bad")), (Job("e", "f"), InputError("missing"))]
    assert report.exit_code == DataError("bad").exit_code != InputError("x").exit_code
