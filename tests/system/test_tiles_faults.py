"""``pyramid tiles`` in real processes (issue 27): SIGTERM mid-run, a full disk, odd shapes, flat memory.

The tile set is written by the streaming :class:`helpers.fake_tiles.FileWriter` (rows into one staged file,
a trailer last, moved into place at the end), so that these check the run layer's promises whatever layout
is merged: every failure aborts the writer, the previous output stays, no temporary is left, one line. A real
full disk (a tiny tmpfs, as root) is also met by every real layout (Deep Zoom, IIIF, OME-Zarr, pyramidal TIFF).
"""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers.cli import run_cli
from helpers.disks import leftovers, mounted
from helpers.fake_tiles import complete
from helpers.images import write
from helpers.tilesets import tree

pytestmark = [pytest.mark.cli, pytest.mark.slow]  # real processes and signals: seconds each

TIMEOUT = 120
TESTS = str(Path(__file__).resolve().parents[1])
FAKE = [sys.executable, "-c", f"import sys; sys.path.insert(0, {TESTS!r}); from helpers.fake_tiles import main; "
        "main()", "tiles", "--backend", "cpu"]


def run(args, *, fsize=None):
    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    r = subprocess.run(FAKE + [str(a) for a in args], capture_output=True, timeout=TIMEOUT,
                       preexec_fn=limit if fsize is not None else None)
    return r.returncode, r.stdout.decode(errors="replace"), r.stderr.decode(errors="replace")


@pytest.fixture(scope="module")
def big(tmp_path_factory):
    path = tmp_path_factory.mktemp("big") / "big.png"
    write(path, (np.random.default_rng(3).random((1536, 1024, 3)) * 255).astype(np.uint8), "uint8")
    return path


def test_sigterm_mid_run_keeps_the_previous_output_or_writes_it_whole(big, tmp_path, monkeypatch):
    from helpers.interrupt import interrupt_runs

    monkeypatch.setenv("FAKE_TILES_DELAY", "0.02")  # about a second of writing level 0's 48 bands
    out = tmp_path / "out.tif"
    stopped = interrupt_runs(FAKE + ["--memory", "16M", big, out], out, (0.9, 1.4, 2.0), complete)
    assert stopped >= 1  # at least one signal came mid-run


def test_a_full_disk_is_exit_4_with_the_previous_output_intact(big, tmp_path):
    out = tmp_path / "out.tif"
    out.write_bytes(b"previous output\n")
    code, stdout, err = run(["--memory", "16M", big, out], fsize=2_000_000)
    assert code == 4, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1 and str(out) in err
    assert out.read_bytes() == b"previous output\n" and not leftovers(tmp_path) and "wrote" not in stdout


def test_odd_shapes_and_a_tile_size_the_layout_refuses(tmp_path):
    wide = tmp_path / "wide.png"
    write(wide, (np.random.default_rng(4).random((1, 100000, 1)) * 255).astype(np.uint8), "uint8")
    dot = tmp_path / "dot.png"
    write(dot, np.full((1, 1, 3), 200, np.uint8), "uint8")
    code, _, err = run(["--json", wide, tmp_path / "wide.tif"])
    assert code == 0, err
    assert complete(tmp_path / "wide.tif")
    code, _, err = run([dot, tmp_path / "dot.tif"])
    assert code == 0 and complete(tmp_path / "dot.tif"), err
    code, _, err = run(["--tile-size", "1", dot, tmp_path / "one.tif"])
    assert code == 2 and err.strip() == "pyramid: error: --tile-size 1: the fake layout needs at least 2"
    code, _, err = run([tmp_path / "wide.tif", tmp_path / "bad.tif"])  # not a picture
    assert code == 3 and "Traceback" not in err and not (tmp_path / "bad.tif").exists()
    assert not leftovers(tmp_path)


@pytest.mark.parametrize("name, extra", [("a.dzi", []), ("a", ["--layout", "iiif3"]), ("a.ome.zarr", []),
                                         ("a.tif", [])], ids=["dz", "iiif3", "ome-zarr", "tiff"])
def test_a_real_full_disk_keeps_each_layout_s_previous_output(tmp_path, name, extra):
    """Every real layout, in a real process, on a tmpfs too small for the new set: exit 4, one line naming the
    output, the previous set (written there first) unchanged file for file, nothing left beside it."""
    small, noise = tmp_path / "small.png", tmp_path / "noise.png"
    write(small, (np.random.default_rng(5).random((64, 64, 3)) * 255).astype(np.uint8), "uint8")
    write(noise, (np.random.default_rng(6).random((1024, 1024, 3)) * 255).astype(np.uint8), "uint8")
    with mounted(tmp_path / "disk", "size=600k") as disk:
        out = disk / name
        first = run_cli("tiles", "-q", *extra, small, out, timeout=TIMEOUT)
        assert first.returncode == 0, first.stderr
        old = tree(disk)
        r = run_cli("tiles", "--force", *extra, noise, out, timeout=TIMEOUT)
        assert r.returncode == 4, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "the disk is full" in lines[0] and str(out) in lines[0], r.stderr
        assert tree(disk) == old and not leftovers(disk)
