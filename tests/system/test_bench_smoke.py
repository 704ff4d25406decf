"""The benchmark suite runs and writes its JSON report (no timing is asserted, ever)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from helpers.paths import ROOT

BENCH = ROOT / "bench" / "run.py"


@pytest.mark.slow
def test_bench_quick_startup_writes_json(tmp_path):
    out = tmp_path / "bench.json"
    p = subprocess.run([sys.executable, str(BENCH), "--quick", "--only", "startup", "--reps", "1",
                        "--no-profile", "--json", str(out)],
                       capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    report = json.loads(out.read_text())
    for key in ("schema", "machine", "quick", "scenarios", "targets", "skipped", "profiles"):
        assert key in report, key
    assert report["quick"] is True
    assert {"cpu", "cores_logical", "versions"} <= set(report["machine"])
    startup = report["scenarios"]["startup"]["results"]
    assert {"pyramid --help", "pyramid explain 'quadratic *v g'"} <= set(startup)
    for result in startup.values():
        assert result["median_s"] > 0
    help_target = [t for t in report["targets"] if t["target"].startswith("pyramid --help")]
    assert len(help_target) == 1 and help_target[0]["met"] in (True, False)
    assert "targets" in p.stdout  # the table was printed


def test_bench_rejects_unknown_scenario(tmp_path):
    p = subprocess.run([sys.executable, str(BENCH), "--only", "nope", "--json", str(tmp_path / "x.json")],
                       capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert p.returncode == 2
    assert "unknown scenario" in p.stderr
    assert not (tmp_path / "x.json").exists()


def _run_gpu(tmp_path, *extra):
    out = tmp_path / "gpu.json"
    p = subprocess.run([sys.executable, str(BENCH), "--quick", "--only", "gpu", "--reps", "1", "--no-profile",
                        "--json", str(out), *extra], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(out.read_text()), p


@pytest.mark.slow
def test_bench_gpu_without_cuda_skips_in_one_line(tmp_path):
    """No torch, or torch without CUDA: one 'skipped' line, exit 0, no targets (CI has no torch)."""
    try:
        import torch
    except ImportError:
        torch = None
    if torch is not None and torch.cuda.is_available():
        pytest.skip("CUDA is present: the gpu scenario runs instead of skipping")
    report, p = _run_gpu(tmp_path)
    lines = [s for s in report["skipped"] if s.startswith("gpu:")]
    assert len(lines) == 1 and lines[0].endswith("skipped"), report["skipped"]
    assert "cases" not in report["scenarios"]["gpu"]
    assert report["targets"] == []
    assert lines[0] in p.stdout


def test_bench_gpu_scenario_on_cpu_torch(tmp_path):
    """--torch-device cpu runs the whole scenario small: GL, the torch peer, the copy floor, ratios, targets (n/a)."""
    pytest.importorskip("torch")
    report, p = _run_gpu(tmp_path, "--torch-device", "cpu")
    gpu = report["scenarios"]["gpu"]
    assert gpu["torch"]["device"] == "cpu" and gpu["size"] == [270, 480]
    assert [c["format"] for c in gpu["cases"]] == ["RGBA16F", "RGBA32F"]
    for case in gpu["cases"]:
        assert {"torch conv2d blur", "torch copy_ (device to device)"} <= set(case["results"])
        assert case["torch_blur_s"] > 0 and case["copy_s"] > 0
        if case["gl_renderer"]:
            assert case["gl_device_s"] > 0 and "torch blur / GL device" in case["ratios"]
    targets = [t for t in report["targets"] if t["target"].startswith("gpu")]
    assert len(targets) == 2 and all(t["met"] is None for t in targets)
    assert "== gpu" in p.stdout


@pytest.mark.slow
def test_codec_memory_bench_writes_each_figure(tmp_path):
    """bench/codec_memory.py (the figures behind pyramid_cli.imageio.codecs.EXR_CODEC_MEMORY) runs end to end on a
    made-up source: uncompressed and one compression, one width and thread count."""
    out = tmp_path / "codecs.json"
    p = subprocess.run([sys.executable, str(ROOT / "bench" / "codec_memory.py"), "--compressions", "dwab",
                        "--widths", "256", "--threads", "1", "--repeat", "1", "--source", str(tmp_path / "none.exr"),
                        "--json", str(out)], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    figures = json.loads(out.read_text())
    assert set(figures) == {"256 none 1", "256 dwab 1"} and figures["256 none 1"]["per_file_mib"] == 0
    assert all(f["peak_mib"] > 0 for f in figures.values())
    assert "one file's codec" in p.stdout
