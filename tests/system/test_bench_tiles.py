"""bench/tiles.py runs its parts small and writes its JSON (no timing is asserted, ever), and the ideal reduction
its quality part measures against is what it claims to be.

pyvips (the libvips peer) comes with the test extra; without it the quality part and the peers' jobs are a
"not installed" entry. ``pyramid tiles`` may be missing from a checkout: its rows then say "not available".
"""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys

import numpy as np
import pytest

from helpers.bench import quick_report
from helpers.paths import ROOT

TILES = ROOT / "bench" / "tiles.py"
if str(ROOT / "bench") not in sys.path:
    sys.path.insert(0, str(ROOT / "bench"))
import tiles_quality  # noqa: E402


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None and bool(__import__(module))
    except Exception:  # noqa: BLE001 - pyvips without libvips raises OSError
        return False


def _dct_basis(n: int, j: int) -> np.ndarray:
    """The j-th cosine of the DCT-II of size n at the pixel centres, along both axes (an n × n picture)."""
    c = np.cos(np.pi * j * (np.arange(n) + 0.5) / n)
    return np.outer(c, c)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_the_ideal_keeps_what_the_level_can_hold_and_drops_the_rest(k):
    n, m = 32, 32 >> k
    ideal = tiles_quality.ideal_operators(n, k)
    for a in ideal.values():
        assert a.shape == (m, n)
        np.testing.assert_allclose(a @ np.ones((n, n)) @ a.T, 1.0, atol=1e-12)   # a flat picture stays flat
        np.testing.assert_allclose(a @ _dct_basis(n, m) @ a.T, 0.0, atol=1e-12)  # the level's Nyquist is dropped
    # below the cut-off, the point ideal is the cosine itself at the level's pixel centres 2^k (i + 1/2)
    j = m - 1
    centres = np.cos(np.pi * j * (2 ** k * (np.arange(m) + 0.5)) / n)
    np.testing.assert_allclose(ideal["point"] @ _dct_basis(n, j) @ ideal["point"].T, np.outer(centres, centres),
                               atol=1e-12)


def test_the_ideal_needs_a_power_of_two():
    with pytest.raises(ValueError, match="power-of-two"):
        tiles_quality.ideal_operators(48, 5)


def test_the_pictures_are_what_they_say():
    assert tiles_quality.LINEAR_HALF_CODE == 188
    pattern = tiles_quality.checkerboard(4)[..., 0]
    assert set(np.unique(pattern)) == {0, 255} and pattern[0, 0] != pattern[0, 1] != pattern[1, 1]
    disc = tiles_quality.red_disc(32)
    seen = disc[..., 3] > 0
    assert (disc[..., 0][seen] == 255).all() and (disc[..., :3][~seen] == 0).all()
    assert ((disc[..., 3] > 0) & (disc[..., 3] < 255)).any()
    # the coarsen contender is the truncated 2×2 mean of the codes: the checkerboard's level 1 is 127
    assert (tiles_quality.coarsen_levels(tiles_quality.checkerboard(4))[1] == 127).all()
    assert math.isclose(tiles_quality.rms(np.zeros(4), np.ones(4)), 1.0)


@pytest.mark.slow
def test_tiles_quick_writes_json(tmp_path):
    out = tmp_path / "tiles.json"
    p = subprocess.run([sys.executable, str(TILES), "--quick", "--data", str(tmp_path / "data"), "--json", str(out),
                        "--plot", str(tmp_path / "tiles.png"), "--sizes", "8k"],
                       capture_output=True, text=True, timeout=600, cwd=ROOT)
    report = quick_report(p, out, "flat")
    assert "libvips" in report["machine"]["versions_peers"]
    (ours,) = report["pyramids"]
    assert {j["id"] for j in report["jobs"]} == {"dz-8k", "tif-8k"}  # --sizes 8k (the smoke run's tiny stand-in)
    if not _installed("pyvips"):
        assert all("not installed" in j["skipped"] for j in report["jobs"]) and "quality" not in report
        return
    for job in report["jobs"]:
        peer = job["contenders"]["peer"]
        assert peer["median_s"] > 0 and peer["peak_rss_mib"] > 0 and peer["median_cpu_s"] > 0, job["id"]
        assert peer["output_files"] > 1 if job["id"].startswith("dz") else peer["output_bytes"] > 0, job["id"]
        (row,) = job["rows"]
        if ours["tiles"]:
            assert row["pyramid_s"] > 0 and row["time"]["verdict"] in ("PASS", "MISS"), row
            # CPU seconds beside the time, their ratio reported without a target
            assert row["pyramid_cpu_s"] > 0 and row["peer_cpu_s"] > 0 and row["cpu"]["target"] is None, row
            assert row["cpu"]["ratio"] == row["pyramid_cpu_s"] / row["peer_cpu_s"], row
        else:
            assert "not available" in row["not_available"] and row["peer_s"] > 0, row
    assert ("skipped" in report["flat"]) != ours["tiles"]
    sizes = [line for line in report["table"] if " output: " in line]  # every job's output size, libvips's too
    assert [line.split()[0] for line in sizes] == [j["id"] for j in report["jobs"]] and "libvips" in sizes[0]
    q = report["quality"]
    assert q["ours"] == ("cli" if ours["tiles"] else "api")
    levels = q["zone_plate"]["levels"]
    assert [r["reduction"] for r in levels] == list(range(1, 7))  # 64² down to 1×1
    for r in levels:
        for ref in ("point", "area"):
            assert {"ours", "dzsave", "coarsen", "box-linear"} <= set(r[ref]), r
            assert r[ref]["verdict"] in ("PASS", "MISS") and r[ref]["ratio_linear"] > 0
    # the 1-pixel pattern: linear light in ours, the mean of the codes in dzsave
    assert q["pattern"]["ours"]["1"]["median_code"] == 188
    assert not list((tmp_path / "data" / "out").rglob(".set-aside")), "the runs' trees are deleted at the end"
    assert abs(q["pattern"]["dzsave"]["1"]["mean_code"] - 127.5) <= 1
    # the disc's edge: straight averaging darkens it, premultiplied does not
    assert q["alpha_fringe"]["ours"]["1"]["weighted_darkness"] < 0.01
    assert q["alpha_fringe"]["coarsen"]["4"]["weighted_darkness"] > 0.01
    assert "zone plate" in p.stdout and "wrote" in p.stdout


def test_tiles_rejects_an_unknown_part(tmp_path):
    p = subprocess.run([sys.executable, str(TILES), "--only", "nope", "--data", str(tmp_path)],
                       capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert p.returncode == 2 and "unknown part" in p.stderr


def test_a_run_set_aside_is_moved_not_deleted_until_the_end(tmp_path):
    """The timed runs never follow a mass delete (ext4's inode allocator passes over recently deleted inodes):
    the previous tree is moved aside whole and deleted by clear_aside when the timing is over."""
    import tiles

    run = tmp_path / "out" / "job" / "ours"
    for i in range(3):
        run.mkdir(parents=True)
        (run / "tile.jpg").write_bytes(b"x" * i)
        tiles.set_aside(run)
        assert not run.exists()
    kept = sorted(p.read_bytes() for p in (tmp_path / "out").rglob("tile.jpg"))
    assert kept == [b"", b"x", b"xx"]
    tiles.clear_aside(tmp_path / "out")
    assert not list((tmp_path / "out").rglob("tile.jpg"))
