"""Pools of threads sized by a real cgroup CPU quota (a Docker ``--cpus``, a Kubernetes CPU limit).

Where the tests run as root with a writable CPU controller (cgroup v1's, or v2's where the unified hierarchy
holds it), a child cgroup allowed one CPU is made beside the test's own, and commands run in it. The process
still sees every core of the host: before, the CPU executor and OpenImageIO's pools (OpenEXR's codec threads,
each holding line buffers) took one thread per host core there.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers.cgroups import enable_v2, first_child, make_child, run_inside, v2_mount
from helpers.cli import CLI, run_cli
from helpers.images import noise, write
from pyramid_cli import imageio as io
from pyramid_cli.core.machine import cgroup_chain, cgroup_paths, mounts

pytestmark = pytest.mark.slow

PERIOD = 100_000  # µs: one CPU's worth of time per period


def _v1_cpu_folder() -> str | None:
    """The process's own cgroup folder under the v1 CPU controller, if it is mounted."""
    path = cgroup_paths("/").get("cpu")
    for mount_root, point, options in mounts("/", "cgroup"):
        if path is not None and "cpu" in options:
            return cgroup_chain(mount_root, point, path)[0]
    return None


@pytest.fixture
def one_cpu():
    """A child cgroup whose quota is one CPU, removed afterwards."""
    attempts = []
    folder = _v1_cpu_folder()
    if folder is not None:
        attempts.append(("cgroup v1", lambda: make_child(Path(folder), {"cpu.cfs_period_us": str(PERIOD),
                                                                         "cpu.cfs_quota_us": str(PERIOD)})))
    if "" in cgroup_paths("/") and mounts("/", "cgroup2"):
        def v2() -> Path:
            mount = Path(v2_mount())
            enable_v2(mount, "cpu")
            return make_child(mount, {"cpu.max": f"{PERIOD} {PERIOD}"})
        attempts.append(("cgroup v2", v2))
    yield from first_child(attempts, "CPU", bool(attempts))


def test_every_pool_takes_the_quota_not_the_host_s_cores(one_cpu, tmp_path):
    _, child = one_cpu
    env = {k: v for k, v in os.environ.items() if k != "OPENIMAGEIO_THREADS"}
    probe = ("import pyramid_cli.imageio, OpenImageIO as oiio; from pyramid_cli.exec.cpu import default_threads; "
             "print(oiio.get_int_attribute('threads'), oiio.get_int_attribute('exr_threads'), default_threads())")
    r = run_inside(child, [sys.executable, "-c", probe], env=env)
    assert r.returncode == 0 and r.stdout.split() == ["1", "1", "1"], (r.stdout, r.stderr)
    src = write(tmp_path / "in.exr", noise(120, 90, seed=3), "half")
    r = run_inside(child, [*CLI, "blur", "--backend", "cpu", "--levels", "3", "-v", src, tmp_path / "q.exr"], env=env)
    assert r.returncode == 0 and "cpu (numba" in r.stderr and "1 thread(s)" in r.stderr, r.stderr
    free = run_cli("blur", "--backend", "cpu", "--levels", "3", src, tmp_path / "f.exr")
    assert free.returncode == 0, free.stderr
    a, b = (io.read_image(tmp_path / n, keep_half=True).pixels for n in ("q.exr", "f.exr"))
    assert np.array_equal(a, b)
