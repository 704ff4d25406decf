"""The benchmark suite runs and writes its JSON report (no timing is asserted, ever)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench" / "run.py"


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
