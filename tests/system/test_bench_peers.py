"""bench/peers.py runs its jobs small and writes its JSON (no timing is asserted, ever).

The OpenImageIO peers (maketx, oiiotool) ship in the OpenImageIO wheel and must run; pyvips and OpenCV
come with the bench extra, which ``make test`` does not install: their jobs are then a "not installed"
entry in the JSON, not a failure.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

from helpers.bench import quick_report
from helpers.paths import ROOT

PEERS = ROOT / "bench" / "peers.py"
JOBS = {"png-blur", "png-blur-unfiltered", "tiff-blur", "exr-blur", "png-mipmap", "exr-mipmap", "cpu-opencv",
        "backend-1080p", "backend-4k", "backend-batch"}


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None and bool(__import__(module))
    except Exception:  # noqa: BLE001 - pyvips without libvips raises OSError
        return False


def _peers(tmp_path, *args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(PEERS), "--quick", "--data", str(tmp_path / "data"), *args],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)


@pytest.mark.slow
def test_peers_quick_writes_json_and_plot(tmp_path):
    out = tmp_path / "peers.json"
    p = _peers(tmp_path, "--json", str(out))
    report = quick_report(p, out, "inputs")
    assert {"cpu", "cores_usable", "versions", "versions_peers"} <= set(report["machine"])
    assert {"libvips", "numba", "maketx", "oiiotool"} <= set(report["machine"]["versions_peers"])
    jobs = {j["id"]: j for j in report["jobs"]}
    assert set(jobs) == JOBS == set(report["targets"])
    # the pyramid rows and the OpenImageIO peers ran: positive times and memory
    for job_id in ("exr-blur", "png-mipmap", "exr-mipmap"):
        (row,) = jobs[job_id]["rows"]
        assert row["pyramid_s"] > 0 and row["pyramid_mib"] > 0, row
        assert row["peer_s"] > 0 and row["peer_mib"] > 0, row
        assert row["pyramid_cpu_s"] > 0 and row["peer_cpu_s"] > 0 and row["cpu"]["verdict"] == "n/a", row
        assert row["time"]["verdict"] in ("PASS", "MISS") and row["memory"]["verdict"] in ("PASS", "MISS")
        assert jobs[job_id]["contenders"]["peer"]["output_bytes"] > 0
    floor = jobs["tiff-blur"]["contenders"]["OIIO read+write (floor)"]
    assert floor["median_s"] > 0 and floor["peak_rss_mib"] > 0
    for job_id in ("backend-1080p", "backend-4k", "backend-batch"):
        (row,) = jobs[job_id]["rows"]
        assert row["times_s"]["auto"] > 0 and row["times_s"]["cpu"] > 0, row
    # the optional peers: measured where installed, a "not installed" entry where not
    for job_id, module in (("png-blur", "pyvips"), ("tiff-blur", "pyvips"), ("cpu-opencv", "cv2")):
        if _installed(module):
            (row,) = jobs[job_id]["rows"]
            assert row["peer_s"] > 0 and row["time"]["ratio"] > 0, row
        else:
            assert "not installed" in jobs[job_id]["skipped"]
            assert any(s.startswith(f"{job_id}: ") for s in report["skipped"])
    assert out.with_suffix(".png").stat().st_size > 0 or not _installed("matplotlib")
    assert "exr-mipmap" in p.stdout and "wrote" in p.stdout


@pytest.mark.slow
def test_peers_profile_writes_the_top_entries(tmp_path):
    p = _peers(tmp_path, "--profile", "exr-blur", "--json", str(tmp_path / "peers.json"))
    assert p.returncode == 0, p.stderr[-2000:]
    (txt,) = tmp_path.glob("peers-profile-exr-blur-*.txt")
    text = txt.read_text()
    assert "cumulative" in text and "pyramid_cli" in text
    assert not list(tmp_path.glob("*.prof"))


def test_peers_rejects_an_unknown_job(tmp_path):
    p = subprocess.run([sys.executable, str(PEERS), "--only", "nope", "--data", str(tmp_path)],
                       capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert p.returncode == 2 and "unknown job" in p.stderr


def test_every_pyramid_timed_writes_its_bytecode(monkeypatch, tmp_path):
    """Under PYTHONDONTWRITEBYTECODE a tree would compile every module in every timed run (an installed package's
    are compiled once, by pip): the contenders' environments drop it, so the warm-up round writes the bytecode."""
    import argparse

    monkeypatch.syspath_prepend(str(ROOT / "bench"))
    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    import peers

    (tmp_path / "pyramid_cli").mkdir()
    found = peers.pyramids(argparse.Namespace(pyramid=peers.DEFAULT_PYRAMID, pyramid_tree=[str(tmp_path)]))
    assert [p.label for p in found] == ["pyramid", f"pyramid@{tmp_path.name}"]
    for p in found:
        assert p.env is not None and "PYTHONDONTWRITEBYTECODE" not in p.env and p.env["PYTHONSAFEPATH"] == "1"
