"""The checked writer (pyramid_cli.imageio.write): atomic replacement, overwrite protection, output errors,
file modes. Under real faults (full disk, signals): tests/system/test_faults.py.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from helpers.images import write as write_raw
from pyramid_cli import imageio as pio
from pyramid_cli.core.errors import OutputError
from pyramid_cli.imageio import atomic
from pyramid_cli.imageio import write as pio_write

RNG = np.random.default_rng(12345)


# ---------------------------------------------------------------------------
# Atomic writes and overwrite protection


def listing(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


@pytest.fixture
def written(tmp_path):
    src = RNG.integers(0, 256, (8, 8, 3)).astype(np.uint8)
    write_raw(tmp_path / "in.png", src, "uint8")
    img = pio.read_image(tmp_path / "in.png")
    out = tmp_path / "out.png"
    pio.write_image(out, img)
    return img, out, out.read_bytes()


@pytest.mark.parametrize("exc", [RuntimeError("disk on fire"), KeyboardInterrupt()])
def test_failed_write_leaves_previous_output(tmp_path, monkeypatch, written, exc):
    img, out, before = written
    seen = []

    def broken(path, spec, pixels):
        seen.append(path)
        with open(path, "wb") as fh:  # half a file, then the failure
            fh.write(b"\x89PNG garbage")
        raise exc

    monkeypatch.setattr(pio_write, "_oiio_write", broken)  # where write_image looks it up
    brighter = pio.Image(img.pixels * 0.5, img.spec)
    with pytest.raises(type(exc)):
        pio.write_image(out, brighter)
    assert out.read_bytes() == before
    assert listing(tmp_path) == ["in.png", "out.png"]
    # The temporary file was hidden, beside the output, with its extension.
    name = os.path.basename(seen[0])
    assert os.path.dirname(seen[0]) == str(tmp_path)
    assert name.startswith(".out.png.tmp-") and name.endswith(".png")


def test_oiio_failure_is_output_error_and_cleans_up(tmp_path, written):
    img, out, before = written
    five = pio.Image(np.zeros((2, 2, 5), np.float32), img.spec)
    with pytest.raises(OutputError) as err:
        pio.write_image(out, five)
    assert str(out) in str(err.value) and "\n" not in str(err.value)
    assert ".tmp-" not in str(err.value)
    assert out.read_bytes() == before
    assert listing(tmp_path) == ["in.png", "out.png"]


def test_refuses_to_overwrite_input(tmp_path, written):
    img, _, _ = written
    inp = tmp_path / "in.png"
    before = inp.read_bytes()
    other = tmp_path / "sub"
    other.mkdir()
    for target in (inp, other / ".." / "in.png"):
        with pytest.raises(OutputError) as err:
            pio.write_image(target, pio.Image(img.pixels * 0.5, img.spec), inputs=[inp])
        assert "in.png" in str(err.value)
    link = tmp_path / "hard.png"
    os.link(inp, link)
    with pytest.raises(OutputError):
        pio.write_image(link, img, inputs=[str(inp)])
    assert inp.read_bytes() == before
    pio.write_image(inp, pio.Image(img.pixels * 0.5, img.spec), inputs=[inp], force=True)
    assert inp.read_bytes() != before


def test_output_errors(tmp_path, written):
    img, _, _ = written
    with pytest.raises(OutputError, match="out.xyz"):
        pio.write_image(tmp_path / "out.xyz", img)
    pio.write_image(tmp_path / "new" / "folder" / "out.png", img)  # missing folders are created
    assert (tmp_path / "new" / "folder" / "out.png").is_file()
    (tmp_path / "afile").write_text("")
    with pytest.raises(OutputError, match="afile"):
        pio.write_image(tmp_path / "afile" / "out.png", img)
    (tmp_path / "adir.png").mkdir()
    with pytest.raises(OutputError, match="adir.png"):
        pio.write_image(tmp_path / "adir.png", img)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_folder(tmp_path, written):
    img, _, _ = written
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o555)
    try:
        with pytest.raises(OutputError, match="locked"):
            pio.write_image(locked / "out.png", img)
    finally:
        locked.chmod(0o755)


def test_permission_error_becomes_output_error(tmp_path, monkeypatch, written):
    # Runs even as root, where the chmod-based test above is skipped.
    img, _, _ = written

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(atomic.tempfile, "mkstemp", denied)
    with pytest.raises(OutputError, match="Permission denied") as err:
        pio.write_image(tmp_path / "new.png", img)
    assert "new.png" in str(err.value)
    assert not (tmp_path / "new.png").exists()


def test_written_file_mode_follows_umask(tmp_path, written):
    _, out, _ = written
    mask = os.umask(0)
    os.umask(mask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~mask

