"""core.cache: the one cache folder, atomic entries, silent when it cannot be written."""

import os

from pyramid_cli.core import cache


def test_root_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.HOME_ENV, str(tmp_path / "mine"))
    assert cache.root() == tmp_path / "mine"
    monkeypatch.delenv(cache.HOME_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.folder("plans") == tmp_path / "xdg" / "bilinear-pyramid" / "plans"


def test_entries_round_trip_and_leave_no_temporaries(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.HOME_ENV, str(tmp_path))
    name = cache.key("box", (5, 7), "clamp")
    assert name != cache.key("box", (7, 5), "clamp")
    assert cache.read("plans", name) is None
    assert cache.write("plans", name, b"abc")
    assert cache.read("plans", name) == b"abc"
    assert os.listdir(tmp_path / "plans") == [name]


def test_a_file_in_the_way_is_passed_over(monkeypatch, tmp_path):
    (tmp_path / "c").write_text("not a folder")
    monkeypatch.setenv(cache.HOME_ENV, str(tmp_path / "c"))
    assert cache.write("plans", "x", b"abc") is False
    assert cache.read("plans", "x") is None
