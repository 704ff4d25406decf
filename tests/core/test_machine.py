"""What the machine lets the process use (``pyramid_cli.core.machine``), read from made-up /proc and /sys trees:
the CPU quota of cgroup v2 and v1 and the cores it leaves. The real cgroups: tests/system/test_cpu_cgroup.py."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from helpers.proc_trees import MOUNTINFO_V1, MOUNTINFO_V2, cgroup_tree
from pyramid_cli.core import machine


def v2(root: Path, path: str, levels: dict[str, str]) -> Path:
    """A cgroup v2 tree: ``levels`` maps each folder (relative to the mount) to its cpu.max."""
    cgroup_tree(root, MOUNTINFO_V2, f"0::{path}", {f"/sys/fs/cgroup/{f}": {"cpu.max": t} for f, t in levels.items()})
    return root


def v1(root: Path, path: str, levels: dict[str, tuple]) -> Path:
    """A cgroup v1 tree: ``levels`` maps each folder to (cpu.cfs_quota_us, cpu.cfs_period_us)."""
    cgroup_tree(root, MOUNTINFO_V1, f"12:memory:{path}\n11:cpu,cpuacct:{path}\n0::/", {
        f"/sys/fs/cgroup/cpu,cpuacct/{folder}": {"cpu.cfs_quota_us": quota, "cpu.cfs_period_us": period}
        for folder, (quota, period) in levels.items()})
    return root


@pytest.fixture
def cores(monkeypatch):
    """The process may run on 16 cores (its affinity)."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)))


def test_no_cgroup_files_leave_the_affinity(tmp_path, cores):
    assert machine.cpu_quota(str(tmp_path)) is None
    assert machine.usable_cores(str(tmp_path)) == 16


@pytest.mark.parametrize("levels, quota, usable", [
    ({"docker/abc": "150000 100000", "docker": "max 100000", "": "max 100000"}, 1.5, 2),  # --cpus=1.5: rounded up
    ({"docker/abc": "max 100000", "docker": "400000 100000"}, 4.0, 4),                    # an ancestor's limit
    ({"docker/abc": "800000 100000", "docker": "200000 100000"}, 2.0, 2),                 # the tightest wins
    ({"docker/abc": "max 100000"}, None, 16),
    ({"docker/abc": "3200000 100000"}, 32.0, 16),                                         # more than the affinity
    ({"docker/abc": "garbage"}, None, 16),
])
def test_cgroup_v2_cpu_max(tmp_path, cores, levels, quota, usable):
    root = str(v2(tmp_path, "/docker/abc", levels))
    assert machine.cpu_quota(root) == quota
    assert machine.usable_cores(root) == usable


@pytest.mark.parametrize("levels, quota, usable", [
    ({"kubepods/pod1": (50000, 100000)}, 0.5, 1),     # half a CPU still runs one thread
    ({"kubepods/pod1": (-1, 100000), "kubepods": (300000, 100000)}, 3.0, 3),
    ({"kubepods/pod1": (-1, 100000)}, None, 16),     # -1: no quota
    ({"kubepods/pod1": ("", 100000)}, None, 16),
])
def test_cgroup_v1_cfs_quota(tmp_path, cores, levels, quota, usable):
    root = str(v1(tmp_path, "/kubepods/pod1", levels))
    assert machine.cpu_quota(root) == quota
    assert machine.usable_cores(root) == usable
