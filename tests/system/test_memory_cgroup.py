"""A default run inside a real 700 MiB memory cgroup (a Docker ``--memory``, a Kubernetes limit, a Slurm job).

Where the tests run as root with a writable memory controller (cgroup v1's, or v2's where the unified
hierarchy holds it), a child cgroup limited to 700 MiB (swap included) is made beside the test's own; the
command runs in it (a shell writes its pid into ``cgroup.procs``, then execs ``pyramid``) and must finish
(exit 0, not 137) with the pixels of the same command run unconstrained. With the budget read from
/proc/meminfo (the host's memory) both commands decided to run whole (1.6 and 1.1 GiB) and were killed.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cli import CLI, TIMEOUT, run_cli
from helpers.images import write
from pyramid_cli.run import budget

pytestmark = pytest.mark.slow

LIMIT = 700 << 20
H, W = 4320, 7680


def _skip_or_fail(reason: str) -> None:
    """Skip; but under CI on a root Linux machine with a memory controller mounted, the test must run."""
    if os.environ.get("CI") and os.geteuid() == 0 and budget.memory_cgroups():
        pytest.fail(f"CI must run the memory cgroup test: {reason}")
    pytest.skip(reason)


def _write(path: Path, text: str) -> None:
    with open(path, "w") as f:
        f.write(text)


def _make_v1(parent: Path) -> Path:
    child = parent / f"pyramid-test-{uuid.uuid4().hex[:8]}"
    child.mkdir()
    try:
        _write(child / "memory.limit_in_bytes", str(LIMIT))
        if (child / "memory.memsw.limit_in_bytes").exists():  # swap must not hide the limit
            _write(child / "memory.memsw.limit_in_bytes", str(LIMIT))
    except OSError:
        child.rmdir()
        raise
    return child


def _make_v2(mount: Path) -> Path:
    # A child of the hierarchy's root: a cgroup with processes of its own cannot hand the memory controller
    # down to children (cgroup v2's "no internal processes" rule), the root can.
    if "memory" not in (mount / "cgroup.controllers").read_text().split():
        raise OSError(f"the memory controller is not in {mount / 'cgroup.controllers'}")
    if "memory" not in (mount / "cgroup.subtree_control").read_text().split():
        _write(mount / "cgroup.subtree_control", "+memory")
    child = mount / f"pyramid-test-{uuid.uuid4().hex[:8]}"
    child.mkdir()
    try:
        _write(child / "memory.max", str(LIMIT))
        if (child / "memory.swap.max").exists():
            _write(child / "memory.swap.max", "0")
    except OSError:
        child.rmdir()
        raise
    return child


@pytest.fixture
def cgroup():
    """A child memory cgroup of 700 MiB, removed afterwards (even when the test fails)."""
    if not sys.platform.startswith("linux") or os.geteuid() != 0:
        pytest.skip("a memory cgroup is made by root on Linux")
    found = budget.memory_cgroups()
    attempts = []
    if "cgroup v1" in found:
        attempts.append(("cgroup v1", lambda: _make_v1(Path(found["cgroup v1"]))))
    if "cgroup v2" in found:
        attempts.append(("cgroup v2", lambda: _make_v2(Path(_v2_mount()))))
    if not attempts:
        _skip_or_fail("no memory cgroup hierarchy is mounted (/proc/self/cgroup, /proc/self/mountinfo)")
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
    _skip_or_fail("cannot make a memory cgroup: " + "; ".join(errors))


def _v2_mount() -> str:
    """The unified hierarchy's mount point (its root cgroup as this process sees it)."""
    with open("/proc/self/mountinfo") as f:
        for line in f:
            head, _, tail = line.partition(" - ")
            if tail.split()[:1] == ["cgroup2"]:
                return head.split()[4]
    raise OSError("no cgroup2 mount in /proc/self/mountinfo")


def _inside(child: Path, *args) -> subprocess.CompletedProcess:
    """``pyramid ARGS…`` in a process that moves itself into ``child`` before exec'ing."""
    shell = f'echo $$ > "{child / "cgroup.procs"}" && exec "$@"'
    return subprocess.run(["sh", "-c", shell, "sh", *CLI, *[str(a) for a in args]], capture_output=True,
                          text=True, timeout=TIMEOUT)


def _picture(path: Path) -> Path:
    """An 8K RGBA half EXR (zip): smooth gradients and waves plus noise, so that it compresses as a photo does."""
    y = np.linspace(0.0, 1.0, H, dtype=np.float32)[:, None]
    x = np.linspace(0.0, 1.0, W, dtype=np.float32)[None, :]
    grain = np.random.default_rng(24).standard_normal((H // 4, W // 4, 4), dtype=np.float32)
    px = np.tile(grain * np.float32(0.004), (4, 4, 1))  # repeats too far apart for zip to see
    for c in range(4):
        px[..., c] += 0.5 + 0.4 * np.sin(6.0 * x + 3 * c) * np.cos(4.0 * y + c)
    return write(path, px, "half", compression="zip")


def _levels(path: Path) -> list[np.ndarray]:
    """Every MIP level's pixels as stored (one level for a plain image)."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    out, level = [], 0
    try:
        while inp.seek_subimage(0, level):
            out.append(inp.read_image(inp.spec().format))
            level += 1
    finally:
        inp.close()
    return out


def test_default_runs_finish_inside_a_700_mib_cgroup(cgroup, tmp_path):
    kind, child = cgroup
    src = _picture(tmp_path / "in8k.exr")
    for name, command in (("blur", ["blur", "--levels", "5"]), ("mipmap", ["mipmap"])):
        inside, outside = tmp_path / f"{name}_cgroup.exr", tmp_path / f"{name}_free.exr"
        r = _inside(child, *command, "-v", src, inside)
        assert r.returncode == 0, f"{name} in the cgroup: exit {r.returncode}\n{r.stderr[-2000:]}"
        assert f"left under the {kind} limit of 700.0 MiB" in r.stderr, r.stderr
        assert "streams in bands" in r.stderr, r.stderr
        free = run_cli(*command, src, outside)
        assert free.returncode == 0, free.stderr
        ours, theirs = _levels(inside), _levels(outside)
        assert len(ours) == len(theirs) >= 1
        for a, b in zip(ours, theirs, strict=True):
            assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
        inside.unlink()
        outside.unlink()
