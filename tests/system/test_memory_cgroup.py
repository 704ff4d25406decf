"""A default run inside a real 700 MiB memory cgroup (a Docker ``--memory``, a Kubernetes limit, a Slurm job).

Where the tests run as root with a writable memory controller (cgroup v1's, or v2's where the unified
hierarchy holds it), a child cgroup limited to 700 MiB (swap included) is made beside the test's own; the
command runs in it (a shell writes its pid into ``cgroup.procs``, then execs ``pyramid``) and must finish
(exit 0, not 137) with the pixels of the same command run unconstrained. With the budget read from
/proc/meminfo (the host's memory) both commands decided to run whole (1.6 and 1.1 GiB) and were killed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.cgroups import enable_v2, first_child, make_child, run_inside, v2_mount
from helpers.cli import CLI, run_cli
from helpers.images import write
from pyramid_cli.run import budget

pytestmark = pytest.mark.slow

LIMIT = 700 << 20
#: Large enough that the MIP map run whole (about 490 MiB) would not fit the budget the cgroup leaves (about 310 MiB)
#: and so streams; the blur streams at any size, and its whole run would take about 720 MiB.
H, W = 2880, 5120


@pytest.fixture
def cgroup():
    """A child memory cgroup of 700 MiB (swap included), removed afterwards (even when the test fails)."""
    found = budget.memory_cgroups()
    attempts = []
    if "cgroup v1" in found:
        attempts.append(("cgroup v1", lambda: make_child(Path(found["cgroup v1"]), {
            "memory.limit_in_bytes": str(LIMIT)}, {"memory.memsw.limit_in_bytes": str(LIMIT)})))
    if "cgroup v2" in found:
        def v2() -> Path:
            mount = Path(v2_mount())
            enable_v2(mount, "memory")  # a child of the hierarchy's root
            return make_child(mount, {"memory.max": str(LIMIT)}, {"memory.swap.max": "0"})
        attempts.append(("cgroup v2", v2))
    yield from first_child(attempts, "memory", bool(found))


def _picture(path: Path) -> Path:
    """A 5K RGBA half EXR (zip): smooth gradients and waves plus noise, so that it compresses as a photo does."""
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


def _same(ours: list[np.ndarray], theirs: list[np.ndarray]) -> None:
    """Every level of two outputs the same, to the bit (NaNs included)."""
    assert len(ours) == len(theirs) >= 1
    for a, b in zip(ours, theirs, strict=True):
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("name, command", [("blur", ["blur", "--levels", "5"]), ("mipmap", ["mipmap"])],
                         ids=["blur", "mipmap"])
def test_default_runs_and_batches_finish_inside_a_700_mib_cgroup(cgroup, tmp_path, name, command):
    """One picture, and a batch (``-o TEMPLATE``) of two, each command at its defaults inside the cgroup, write what
    the command writes of the picture unconstrained (run once). A batch holds the pictures it reads ahead and writes
    behind beside the one it computes: two 8K inputs held 1.8 GB and were killed; each now runs alone, streamed,
    in the container's budget (which the ``-v`` lines name). One test per command, so that the two can run on two
    test workers at once."""
    kind, child = cgroup
    first = _picture(tmp_path / "a.exr")
    second = tmp_path / "b.exr"
    second.write_bytes(first.read_bytes())
    free = tmp_path / f"{name}_free.exr"
    r = run_cli(*command, first, free)
    assert r.returncode == 0, r.stderr
    theirs = _levels(free)
    inside = tmp_path / f"{name}_cgroup.exr"
    r = run_inside(child, [*CLI, *command, "-v", first, inside])
    assert r.returncode == 0, f"{name} in the cgroup: exit {r.returncode}\n{r.stderr[-2000:]}"
    assert f"left under the {kind} limit of 700.0 MiB" in r.stderr, r.stderr
    assert "streams in bands" in r.stderr, r.stderr
    _same(_levels(inside), theirs)
    r = run_inside(child, [*CLI, *command, "-v", "-o", tmp_path / f"{name}_cgroup" / "{stem}.exr", first, second])
    assert r.returncode == 0, f"{name} batch in the cgroup: exit {r.returncode}\n{r.stderr[-2000:]}"
    assert f"left under the {kind} limit of 700.0 MiB" in r.stderr and "2 written" in r.stderr, r.stderr
    for stem in ("a", "b"):
        _same(_levels(tmp_path / f"{name}_cgroup" / f"{stem}.exr"), theirs)
