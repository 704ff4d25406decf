"""What every bench's ``--quick`` smoke run must leave behind (bench/peers.py's ``finish`` ends them all)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

REPORT_KEYS = ("schema", "created", "machine", "quick", "repeat", "load_avg", "pyramids", "targets", "jobs",
               "skipped", "failed", "table")


def quick_report(proc: subprocess.CompletedProcess, out: Path, *keys: str) -> dict:
    """The JSON report a ``--quick`` run wrote at ``out``: the run exited 0, the report holds every key a bench
    report has (and ``keys``), ran one round, failed nowhere, and says the load at its start and end."""
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(out.read_text())
    for key in (*REPORT_KEYS, *keys):
        assert key in report, key
    assert report["quick"] is True and report["repeat"] == 1 and report["failed"] == []
    assert {"start", "end"} <= set(report["load_avg"])
    return report
