"""What the machine lets this process use, read from /proc and /sys: its cgroups, and the cores it may run on.

``pyramid_cli.run.budget`` reads the memory limits through the cgroup helpers here; :func:`usable_cores` sizes
every pool of threads (the CPU executor's, OpenImageIO's and OpenEXR's: :mod:`pyramid_cli.imageio`). A
container's CPU limit (Docker ``--cpus``, a Kubernetes CPU limit, systemd's ``CPUQuota``) is a cgroup quota,
not an affinity: the process still sees every core of the host, and pools sized from the host's cores ran
that many threads in it (OpenImageIO's OpenEXR threads each hold line buffers: see
:mod:`pyramid_cli.imageio.codecs`).

Everything is read under a root folder (``root``, "/" by default) so that tests can feed made-up trees.
"""

from __future__ import annotations

import math
import os


def read_file(root: str, path: str) -> str | None:
    """The text of ``path`` under ``root``; None when it cannot be read."""
    try:
        with open(os.path.join(root, path.lstrip("/"))) as f:
            return f.read()
    except (OSError, UnicodeDecodeError):
        return None


def mounts(root: str, fstype: str) -> list[tuple[str, str, set[str]]]:
    """(mount root, mount point, super options) of each ``fstype`` mount in /proc/self/mountinfo."""
    out = []
    for line in (read_file(root, "/proc/self/mountinfo") or "").splitlines():
        head, sep, tail = line.partition(" - ")
        fields, rest = head.split(), tail.split()
        if not sep or len(fields) < 5 or len(rest) < 3 or rest[0] != fstype:
            continue
        out.append((fields[3], fields[4], set(rest[2].split(","))))
    return out


def cgroup_chain(mount_root: str, mount_point: str, cgroup: str) -> list[str]:
    """The folders of ``cgroup`` and of each ancestor visible under the mount, the process's own first."""
    rel = cgroup
    if mount_root != "/" and (cgroup == mount_root or cgroup.startswith(mount_root.rstrip("/") + "/")):
        rel = cgroup[len(mount_root.rstrip("/")):]
    elif mount_root != "/":
        rel = "/"  # a cgroup namespace or a bind mount of the process's own cgroup: the mount is its folder
    parts = [p for p in rel.split("/") if p]
    return [os.path.join(mount_point, *parts[:i]) for i in range(len(parts), -1, -1)]


def cgroup_paths(root: str) -> dict[str, str]:
    """The process's cgroup paths from /proc/self/cgroup: ``{"": v2 path, controller: v1 path}``."""
    out = {}
    for line in (read_file(root, "/proc/self/cgroup") or "").splitlines():
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[0] == "0" and parts[1] == "":
            out[""] = parts[2]
        for controller in parts[1].split(","):
            if controller:
                out[controller] = parts[2]
    return out


def _ratio(quota: str | None, period: str | None) -> float | None:
    try:
        q, p = int(quota or ""), int(period or "")
    except ValueError:
        return None
    return q / p if q > 0 and p > 0 else None


def cpu_quota(root: str = "/") -> float | None:
    """The CPUs' worth of time the process's cgroups allow it (the tightest of its cgroup's and its ancestors'):
    cgroup v2 ``cpu.max`` (``QUOTA PERIOD``; ``max``: none), cgroup v1 ``cpu.cfs_quota_us`` over
    ``cpu.cfs_period_us`` (-1: none); None without a quota."""
    paths, found = cgroup_paths(root), []
    if "" in paths:
        for mount_root, point, _ in mounts(root, "cgroup2"):
            for folder in cgroup_chain(mount_root, point, paths[""]):
                fields = (read_file(root, os.path.join(folder, "cpu.max")) or "").split()
                if len(fields) == 2:
                    found.append(_ratio(*fields))
    if "cpu" in paths:
        for mount_root, point, options in mounts(root, "cgroup"):
            if "cpu" not in options:
                continue
            for folder in cgroup_chain(mount_root, point, paths["cpu"]):
                found.append(_ratio(read_file(root, os.path.join(folder, "cpu.cfs_quota_us")),
                                    read_file(root, os.path.join(folder, "cpu.cfs_period_us"))))
    quotas = [q for q in found if q is not None]
    return min(quotas) if quotas else None


def usable_cores(root: str = "/") -> int:
    """The cores this process may use: those its affinity allows, no more than its cgroups' CPU quota (rounded
    up: a quota of 1.5 CPUs keeps two threads busy half the time)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        cores = os.cpu_count() or 1
    quota = cpu_quota(root)
    if quota is not None:
        cores = min(cores, math.ceil(quota))
    return max(1, cores)


__all__ = ["cgroup_chain", "cgroup_paths", "cpu_quota", "mounts", "read_file", "usable_cores"]
