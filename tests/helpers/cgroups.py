"""Real cgroups for the system tests (tests/system/test_memory_cgroup.py, test_cpu_cgroup.py): made beside the
test's own by root on Linux, a command run inside one, and a skip that CI turns into a failure."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from helpers.cli import TIMEOUT


def skip_or_fail(reason: str, ci_must_run: bool) -> None:
    """Skip; but under CI, where ``ci_must_run`` (root, the controller mounted), the test must run: fail."""
    if os.environ.get("CI") and os.geteuid() == 0 and ci_must_run:
        pytest.fail(f"CI must run this cgroup test: {reason}")
    pytest.skip(reason)


def write_file(path: Path, text: str) -> None:
    with open(path, "w") as f:
        f.write(text)


def v2_mount() -> str:
    """The unified hierarchy's mount point (its root cgroup as this process sees it)."""
    with open("/proc/self/mountinfo") as f:
        for line in f:
            head, _, tail = line.partition(" - ")
            if tail.split()[:1] == ["cgroup2"]:
                return head.split()[4]
    raise OSError("no cgroup2 mount in /proc/self/mountinfo")


def enable_v2(mount: Path, controller: str) -> None:
    """Hand ``controller`` down from the unified hierarchy's root to its children (a cgroup with processes of its
    own cannot: cgroup v2's "no internal processes" rule; the root can)."""
    if controller not in (mount / "cgroup.controllers").read_text().split():
        raise OSError(f"the {controller} controller is not in {mount / 'cgroup.controllers'}")
    if controller not in (mount / "cgroup.subtree_control").read_text().split():
        write_file(mount / "cgroup.subtree_control", f"+{controller}")


def run_inside(child: Path, args, env: dict | None = None) -> subprocess.CompletedProcess:
    """``args`` in a process that moves itself into the cgroup ``child`` before exec'ing."""
    shell = f'echo $$ > "{child / "cgroup.procs"}" && exec "$@"'
    return subprocess.run(["sh", "-c", shell, "sh", *[str(a) for a in args]], capture_output=True, text=True,
                          timeout=TIMEOUT, env=env)


def make_child(parent: Path, files: dict[str, str], optional: dict[str, str] | None = None) -> Path:
    """A new cgroup under ``parent`` with ``files`` written (and each of ``optional`` where the kernel offers
    it); removed again when a write fails (OSError)."""
    child = parent / f"pyramid-test-{uuid.uuid4().hex[:8]}"
    child.mkdir()
    try:
        for name, text in files.items():
            write_file(child / name, text)
        for name, text in (optional or {}).items():
            if (child / name).exists():
                write_file(child / name, text)
    except OSError:
        child.rmdir()
        raise
    return child


def first_child(attempts: list[tuple[str, Callable[[], Path]]], what: str, ci_must_run: bool
                ) -> Iterator[tuple[str, Path]]:
    """For a fixture: (kind, folder) of the first cgroup one of ``attempts`` (kind, maker) makes, removed after
    the test (even when it fails); skip (or fail under CI) where none can be made."""
    if not sys.platform.startswith("linux") or os.geteuid() != 0:
        pytest.skip(f"a {what} cgroup is made by root on Linux")
    if not attempts:
        skip_or_fail(f"no {what} cgroup hierarchy is mounted (/proc/self/cgroup, /proc/self/mountinfo)", ci_must_run)
    errors = []
    for kind, make in attempts:
        try:
            child = make()
        except OSError as exc:
            errors.append(f"{kind}: {exc}")
            continue
        try:
            yield kind, child
        finally:
            with contextlib.suppress(OSError):
                child.rmdir()
        return
    skip_or_fail(f"cannot make a {what} cgroup: " + "; ".join(errors), ci_must_run)
