"""Staging: a tile set built in a hidden folder beside its output and moved into place descriptor last; a discard
or a failed move leaves the previous output as it was and nothing hidden behind."""

from __future__ import annotations

import os

import pytest

from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio.tilesets import staging as staging_module
from pyramid_cli.imageio.tilesets.staging import Staging


def hidden(folder):
    return sorted(n for n in os.listdir(folder) if n.startswith("."))


def built(tmp_path) -> Staging:
    """The staging of ``pic_files`` and ``pic.dzi`` in ``tmp_path``, holding what a Deep Zoom writer puts there: a
    tile folder and a descriptor."""
    st = Staging([str(tmp_path / "pic_files"), str(tmp_path / "pic.dzi")])
    os.makedirs(os.path.join(st.staged[0], "0"))
    with open(os.path.join(st.staged[0], "0", "0_0.jpeg"), "w") as f:
        f.write("new tile")
    with open(st.staged[1], "w") as f:
        f.write("new descriptor")
    return st


def previous(tmp_path):
    (tmp_path / "pic_files" / "0").mkdir(parents=True)
    (tmp_path / "pic_files" / "0" / "0_0.jpeg").write_text("old tile")
    (tmp_path / "pic_files" / "0" / "1_0.jpeg").write_text("old tile only")
    (tmp_path / "pic.dzi").write_text("old descriptor")


def test_staged_paths_are_hidden_beside_the_first_output(tmp_path):
    st = Staging([str(tmp_path / "sub" / "pic_files"), str(tmp_path / "sub" / "pic.dzi")])
    assert os.path.dirname(st.root) == str(tmp_path / "sub")  # the missing folder is made; one file system
    assert os.path.basename(st.root).startswith(".pic_files.tmp-")
    assert [os.path.basename(p) for p in st.staged] == ["pic_files", "pic.dzi"]
    assert all(os.path.dirname(p) == st.root for p in st.staged)
    st.discard()
    assert not hidden(tmp_path / "sub")


def test_commit_replaces_the_previous_output_and_leaves_nothing_hidden(tmp_path):
    previous(tmp_path)
    st = built(tmp_path)
    st.commit()
    assert (tmp_path / "pic.dzi").read_text() == "new descriptor"
    assert os.listdir(tmp_path / "pic_files" / "0") == ["0_0.jpeg"]  # the old tile set is gone, not merged
    assert (tmp_path / "pic_files" / "0" / "0_0.jpeg").read_text() == "new tile" and not hidden(tmp_path)


def test_commit_moves_the_descriptor_last(tmp_path, monkeypatch):
    moves = []
    real = os.replace

    def record(src, dst):
        moves.append(os.path.basename(dst))
        real(src, dst)

    monkeypatch.setattr(staging_module.os, "replace", record)
    st = built(tmp_path)
    st.commit()
    assert moves == ["pic_files", "pic.dzi"]


def test_discard_keeps_the_previous_output(tmp_path):
    previous(tmp_path)
    st = built(tmp_path)
    st.discard()
    assert (tmp_path / "pic.dzi").read_text() == "old descriptor"
    assert sorted(os.listdir(tmp_path / "pic_files" / "0")) == ["0_0.jpeg", "1_0.jpeg"] and not hidden(tmp_path)


def test_a_commit_failing_part_way_puts_the_previous_output_back(tmp_path, monkeypatch):
    previous(tmp_path)
    real = os.replace
    failed = []

    def fail_on_the_descriptor(src, dst):
        if str(dst).endswith("pic.dzi") and not failed and os.path.basename(src) == "pic.dzi":
            failed.append(src)
            raise OSError(28, "No space left on device")
        real(src, dst)

    monkeypatch.setattr(staging_module.os, "replace", fail_on_the_descriptor)
    st = built(tmp_path)
    with pytest.raises(OutputError, match=r"^cannot write .*pic_files: No space left on device$"):
        st.commit()
    st.discard()
    assert (tmp_path / "pic.dzi").read_text() == "old descriptor"
    assert (tmp_path / "pic_files" / "0" / "0_0.jpeg").read_text() == "old tile" and not hidden(tmp_path)


def test_a_folder_that_cannot_be_made_is_one_line(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    with pytest.raises(OutputError, match="cannot write .*file/pic_files"):
        Staging([str(tmp_path / "file" / "pic_files")])


def test_a_folder_output_with_a_trailing_slash(tmp_path):
    st = Staging([str(tmp_path / "iiif") + os.sep])
    os.mkdir(st.staged[0])
    (tmp_path / "iiif").mkdir()
    st.commit()
    assert os.listdir(tmp_path / "iiif") == [] and not hidden(tmp_path)
