"""Made-up /proc and /sys trees under a temporary root, for the code that reads what the machine allows
(``pyramid_cli.core.machine``, ``pyramid_cli.run.budget``): mounts, the process's cgroups and their files."""

from __future__ import annotations

from pathlib import Path

MOUNTINFO_V2 = ("24 1 0:22 / /sys/fs/cgroup rw,nosuid - cgroup2 cgroup2 rw,nsdelegate\n"
                "25 1 8:1 / / rw - ext4 /dev/sda1 rw\n")
MOUNTINFO_V1 = ("31 23 0:28 / /sys/fs/cgroup rw,relatime - tmpfs tmpfs rw,mode=755\n"
                "32 31 0:29 / /sys/fs/cgroup/cpu,cpuacct rw,relatime - cgroup cgroup rw,cpu,cpuacct\n"
                "35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n"
                "41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw\n")


def put(root: Path, path: str, text) -> None:
    """``text`` (and a newline) as the file ``path`` under ``root``, its folders made."""
    f = root / path.lstrip("/")
    f.parent.mkdir(parents=True, exist_ok=True)
    f.write_text(str(text) + "\n")


def cgroup_tree(root: Path, mountinfo: str, cgroup: str, folders: dict[str, dict]) -> None:
    """/proc/self/mountinfo and /proc/self/cgroup, and in each folder (absolute, under ``root``) its files, name to
    text (None: no such file)."""
    put(root, "/proc/self/mountinfo", mountinfo)
    put(root, "/proc/self/cgroup", cgroup)
    for folder, files in folders.items():
        for name, text in files.items():
            if text is not None:
                put(root, f"{folder.rstrip('/')}/{name}", text)
