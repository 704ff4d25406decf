"""Which code this is (pyramid_cli.core.fingerprint): any edit to a folder's sources changes its digest."""

import os

import pytest

from pyramid_cli.core import fingerprint


@pytest.fixture
def package(tmp_path, monkeypatch):
    (tmp_path / "core").mkdir()
    (tmp_path / "core" / "a.py").write_text("x = 1\n")
    (tmp_path / "core" / "notes.txt").write_text("not code")
    monkeypatch.setattr(fingerprint, "PACKAGE", tmp_path)
    fingerprint.sources.cache_clear()
    yield tmp_path
    fingerprint.sources.cache_clear()


def digest(*folders):
    fingerprint.sources.cache_clear()
    return fingerprint.sources(*folders)


def test_an_edit_a_new_file_or_another_version_changes_the_digest(package, monkeypatch):
    before = digest("core")
    assert digest("core") == before
    (package / "core" / "notes.txt").write_text("still not code")
    assert digest("core") == before
    (package / "core" / "a.py").write_text("x = 2\n")  # same size: the modification time tells
    os.utime(package / "core" / "a.py", ns=(1, 1))
    edited = digest("core")
    assert edited != before
    (package / "core" / "b.json").write_text("{}")
    assert digest("core") != edited
    monkeypatch.setattr(fingerprint, "__version__", "9.9.9")
    assert digest("core") not in (before, edited)


def test_a_missing_folder_counts_but_does_not_fail(package):
    assert digest("core", "nowhere") != digest("core")


def test_the_real_package_has_a_digest():
    assert len(fingerprint.sources("core", "plan")) == 32
