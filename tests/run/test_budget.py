"""The memory budget read from made-up /proc and /sys trees: cgroup v2 and v1, rlimits, the machine's memory."""

from __future__ import annotations

import resource
from pathlib import Path

import pytest

from helpers.proc_trees import MOUNTINFO_V1, MOUNTINFO_V2, cgroup_tree, put
from pyramid_cli.core.errors import UsageError
from pyramid_cli.run import budget, stream

MIB = 1 << 20
V1_UNLIMITED = 9223372036854771712

@pytest.fixture
def root(tmp_path, monkeypatch):
    """A fake root with 8 GiB available and no rlimit (the real rlimits would leak in otherwise)."""
    put(tmp_path, "/proc/meminfo", f"MemTotal: 16000000 kB\nMemFree: 100 kB\nMemAvailable: {8 << 20} kB")
    put(tmp_path, "/proc/self/status", f"Name: python\nVmSize: {1 << 20} kB\nVmData: {200 << 10} kB")
    monkeypatch.setattr(resource, "getrlimit", lambda which: (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    return tmp_path


def v2(root: Path, path: str, levels: dict[str, tuple]) -> None:
    """A cgroup v2 tree: ``levels`` maps each folder (relative to the mount) to (memory.max, memory.current)."""
    cgroup_tree(root, MOUNTINFO_V2, f"0::{path}", {f"/sys/fs/cgroup/{folder}": {
        "memory.max": limit, "memory.current": current} for folder, (limit, current) in levels.items()})


def v1(root: Path, path: str, limit, usage, stat: str = "") -> str:
    base = f"/sys/fs/cgroup/memory{path}".rstrip("/")
    cgroup_tree(root, MOUNTINFO_V1, f"12:memory:{path}\n11:cpu,cpuacct:{path}\n0::/", {base: {
        "memory.limit_in_bytes": limit, "memory.usage_in_bytes": usage,
        "memory.stat": stat or f"cache 0\nhierarchical_memory_limit {V1_UNLIMITED}"}})
    return base


def test_only_the_machine_s_memory_gives_a_quarter(root):
    b = budget.default_budget(str(root))
    assert b.size == (8 << 30) // 4
    assert b.source == "available" and not b.limit.hard
    assert "a quarter of the 8.0 GiB available" in b.describe()


def test_a_small_machine_gives_at_least_the_floor(root):
    put(root, "/proc/meminfo", "MemAvailable: 102400 kB")
    assert budget.default_budget(str(root)).size == budget.FLOOR


def test_cgroup_v2_limit_sets_the_budget(root):
    v2(root, "/job", {"job": (700 * MIB, 200 * MIB), "": (None, 10 * MIB)})
    b = budget.default_budget(str(root))
    assert b.source == "cgroup v2"
    assert b.limit.size == 700 * MIB and b.limit.left == 500 * MIB
    assert b.size == int(budget.HARD_FRACTION * (500 * MIB - budget.RESERVE["cgroup v2"]))
    assert b.limit.where == "/sys/fs/cgroup/job/memory.max"
    said = b.describe()
    assert "left under the cgroup v2 limit of 700.0 MiB" in said and "/sys/fs/cgroup/job/memory.max" in said


def test_a_limit_with_nothing_left_beyond_the_reserve_says_so(root):
    v2(root, "/job", {"job": (150 * MIB, 52 * MIB)})
    b = budget.default_budget(str(root))
    assert b.size == 0
    assert b.describe() == ("memory budget 0 B: the 98.0 MiB left under the cgroup v2 limit of 150.0 MiB "
                            "(/sys/fs/cgroup/job/memory.max) is no more than the 128.0 MiB kept back for the "
                            "process itself")


def test_cgroup_v2_max_is_no_limit(root):
    v2(root, "/job", {"job": ("max", 200 * MIB)})
    assert budget.cgroup_v2(str(root)) is None
    assert budget.default_budget(str(root)).source == "available"


def test_cgroup_v2_an_ancestor_s_smaller_limit_applies(root):
    v2(root, "/outer/inner", {"outer/inner": (2 << 30, 100 * MIB), "outer": (600 * MIB, 300 * MIB)})
    lim = budget.cgroup_v2(str(root))
    assert lim.size == 600 * MIB and lim.left == 300 * MIB
    assert lim.where == "/sys/fs/cgroup/outer/memory.max"


def test_cgroup_v2_reclaimable_page_cache_is_not_counted(root):
    v2(root, "/job", {"job": (700 * MIB, 400 * MIB)})
    put(root, "/sys/fs/cgroup/job/memory.stat", f"anon 1\ninactive_file {300 * MIB}")
    assert budget.cgroup_v2(str(root)).left == 600 * MIB


def test_cgroup_v2_in_a_namespace_reads_the_mount_itself(root):
    put(root, "/proc/self/mountinfo", "24 1 0:22 /kubepods/pod1 /sys/fs/cgroup rw - cgroup2 cgroup2 rw\n")
    put(root, "/proc/self/cgroup", "0::/")
    put(root, "/sys/fs/cgroup/memory.max", 1 << 30)
    put(root, "/sys/fs/cgroup/memory.current", 0)
    assert budget.cgroup_v2(str(root)).size == 1 << 30


def test_cgroup_v1_limit_sets_the_budget(root):
    base = v1(root, "/process_api/abc", 700 * MIB, 183 * MIB)
    b = budget.default_budget(str(root))
    assert b.source == "cgroup v1" and b.limit.left == 517 * MIB
    assert b.limit.where == base.replace(str(root), "") + "/memory.limit_in_bytes"
    assert b.describe().startswith(f"memory budget {budget.format_size(b.size)}: 60% of 389.0 MiB: the 517.0 MiB "
                                   "left under the cgroup v1 limit of 700.0 MiB "
                                   "(/sys/fs/cgroup/memory/process_api/abc/")
    assert b.describe().endswith("), less 128.0 MiB kept back for the process itself")


def test_cgroup_v1_huge_value_is_no_limit(root):
    v1(root, "/process_api/abc", V1_UNLIMITED, 183 * MIB)
    assert budget.cgroup_v1(str(root)) is None


def test_cgroup_v1_hierarchical_limit_from_memory_stat(root):
    v1(root, "/a/b", V1_UNLIMITED, 100 * MIB,
       f"hierarchical_memory_limit {900 * MIB}\ntotal_inactive_file {50 * MIB}")
    lim = budget.cgroup_v1(str(root))
    assert lim.size == 900 * MIB and lim.left == 850 * MIB
    assert lim.where.endswith("/a/b/memory.stat hierarchical_memory_limit")


def test_cgroup_v1_ancestor_limit_applies(root):
    v1(root, "/a/b", V1_UNLIMITED, 100 * MIB)
    put(root, "/sys/fs/cgroup/memory/a/memory.limit_in_bytes", 500 * MIB)
    put(root, "/sys/fs/cgroup/memory/a/memory.usage_in_bytes", 300 * MIB)
    lim = budget.cgroup_v1(str(root))
    assert (lim.size, lim.left) == (500 * MIB, 200 * MIB)
    assert lim.where == "/sys/fs/cgroup/memory/a/memory.limit_in_bytes"


def test_rlimit_as_counts_what_is_mapped_already(root, monkeypatch):
    limits = {resource.RLIMIT_AS: 3 << 30, resource.RLIMIT_DATA: resource.RLIM_INFINITY}
    monkeypatch.setattr(resource, "getrlimit", lambda which: (limits.get(which, resource.RLIM_INFINITY),) * 2)
    b = budget.default_budget(str(root))
    assert b.source == "RLIMIT_AS" and b.limit.left == 2 << 30  # VmSize 1 GiB
    assert b.size == int(budget.HARD_FRACTION * ((2 << 30) - budget.RESERVE["RLIMIT_AS"]))
    assert "RLIMIT_AS limit of 3.0 GiB" in b.describe()


def test_rlimit_data(root, monkeypatch):
    limits = {resource.RLIMIT_DATA: 1 << 30}
    monkeypatch.setattr(resource, "getrlimit", lambda which: (limits.get(which, resource.RLIM_INFINITY),) * 2)
    (lim,) = budget.rlimits(str(root))
    assert lim.kind == "RLIMIT_DATA" and lim.left == (1 << 30) - (200 << 20)


def test_the_smallest_budget_wins_and_is_named(root, monkeypatch):
    v2(root, "/job", {"job": (4 << 30, 0)})
    v1_base = v1(root, "/job", 2 << 30, 0)  # both hierarchies mounted: mountinfo of v1 replaces v2's
    put(root, "/proc/self/mountinfo", MOUNTINFO_V1.replace("/sys/fs/cgroup/unified", "/sys/fs/cgroup"))
    put(root, "/proc/self/cgroup", "12:memory:/job\n0::/job")
    monkeypatch.setattr(resource, "getrlimit", lambda which: (
        (8 << 30,) * 2 if which == resource.RLIMIT_AS else (resource.RLIM_INFINITY,) * 2))
    found = {lim.kind: lim for lim in budget.limits(str(root))}
    assert set(found) == {"cgroup v2", "cgroup v1", "RLIMIT_AS", "available"}
    b = budget.default_budget(str(root))
    assert b.source == "cgroup v1" and b.limit.where == v1_base.replace(str(root), "") + "/memory.limit_in_bytes"
    assert b.size == min(budget.budget_under(lim) for lim in found.values())


def test_a_hard_limit_above_the_machine_s_memory_leaves_the_quarter(root):
    v2(root, "/job", {"job": (64 << 30, 0)})
    assert budget.default_budget(str(root)).source == "available"


def test_nothing_left_gives_no_budget(root):
    v2(root, "/job", {"job": (100 * MIB, 90 * MIB)})
    assert budget.default_budget(str(root)).size == 0


def test_unreadable_and_malformed_files_give_no_limit(root):
    put(root, "/proc/self/mountinfo", "garbage\n" + MOUNTINFO_V2)
    put(root, "/proc/self/cgroup", "nonsense\n0::/job")
    put(root, "/sys/fs/cgroup/job/memory.max", "lots")
    put(root, "/sys/fs/cgroup/job/memory.current", 1)
    (root / "sys/fs/cgroup/job/memory.stat").mkdir()  # reading a folder fails
    assert budget.cgroup_v2(str(root)) is None and budget.cgroup_v1(str(root)) is None
    put(root, "/proc/meminfo", "MemAvailable: many kB")
    assert budget.available(str(root)).where == "physical memory"
    assert budget.default_budget(str(root / "missing")).source == "available"  # nothing there at all


def test_memory_given_is_said():
    b = budget.resolve(400 * MIB)
    assert b.size == 400 * MIB and b.source == "--memory"
    assert b.describe() == "memory budget 400.0 MiB: given by --memory"
    assert b.to_json() == {"budget": 400 * MIB, "source": "--memory"}


def test_to_json_names_the_limit(root):
    v2(root, "/job", {"job": (700 * MIB, 200 * MIB)})
    doc = budget.default_budget(str(root)).to_json()
    assert doc["source"] == "cgroup v2" and doc["limit"] == 700 * MIB and doc["left"] == 500 * MIB


def test_the_names_stay_importable_from_stream():
    assert stream.parse_size is budget.parse_size and stream.default_memory is budget.default_memory
    assert stream.available_memory() > 0 and stream.default_memory() >= 0


def test_parse_size():
    assert budget.parse_size("400M") == 400 * MIB
    with pytest.raises(UsageError):
        budget.parse_size("0")


def test_memory_cgroups_names_the_folders(root):
    v1(root, "/process_api/abc", 700 * MIB, 0)
    assert budget.memory_cgroups(str(root)) == {"cgroup v2": "/sys/fs/cgroup/unified",
                                                "cgroup v1": "/sys/fs/cgroup/memory/process_api/abc"}


@pytest.mark.slow  # loads the CPU executor
def test_a_run_says_its_budget_and_is_refused_when_nothing_fits(root, tmp_path, monkeypatch):
    """The CLI end to end under a made-up 129 MiB cgroup: -v names the limit; not even 8 rows fit: exit 5."""
    from helpers.cli import invoke
    from helpers.images import noise, write

    v2(root, "/job", {"job": (129 * MIB, 0)})
    real = budget.default_budget
    monkeypatch.setattr(budget, "default_budget", lambda r="/": real(str(root)))
    src = write(tmp_path / "in.exr", noise(64, 2048), "half")
    r = invoke("blur", "--levels", "5", "--backend", "cpu", "-v", src, tmp_path / "out.exr")
    assert r.exit_code == 5, r.output
    assert ("memory budget 614.4 KiB: 60% of 1.0 MiB: the 129.0 MiB left under the cgroup v2 limit of 129.0 MiB"
            in r.output and "less 128.0 MiB kept back for the process itself" in r.output)
    assert "/sys/fs/cgroup/job/memory.max" in r.output and "over the budget of 614.4 KiB" in r.output
    assert not (tmp_path / "out.exr").exists()
    for command in (["blur", "--levels", "5"], ["mipmap"]):  # without -v, the refusal's one line names the limit
        r = invoke(*command, "--backend", "cpu", src, tmp_path / "out.exr")
        lines = [line for line in r.output.splitlines() if line.strip()]
        assert r.exit_code == 5 and len(lines) == 1, r.output
        assert "over the budget of 614.4 KiB" in lines[0] and "under the cgroup v2 limit of 129.0 MiB" in lines[0]
        assert not (tmp_path / "out.exr").exists()


def test_cgroup_v1_mounted_at_the_container_s_own_cgroup(root):
    """Docker without a cgroup namespace: the mount's root is the container's cgroup, the path names it too."""
    put(root, "/proc/self/mountinfo",
        "35 31 0:32 /docker/abc /sys/fs/cgroup/memory ro,nosuid - cgroup cgroup rw,memory\n")
    put(root, "/proc/self/cgroup", "12:memory:/docker/abc")
    put(root, "/sys/fs/cgroup/memory/memory.limit_in_bytes", 700 * MIB)
    put(root, "/sys/fs/cgroup/memory/memory.usage_in_bytes", 100 * MIB)
    lim = budget.cgroup_v1(str(root))
    assert (lim.size, lim.left, lim.where) == (700 * MIB, 600 * MIB, "/sys/fs/cgroup/memory/memory.limit_in_bytes")
