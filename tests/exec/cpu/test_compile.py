"""Compiling the CPU kernels (``pyramid_cli.exec.cpu.compile``): numba imported only when needed, the cache
folder's conventions, the disk cache a second process loads, and a cache that cannot be written.

Kernels compile into the kernel cache folder of this module (``PYRAMID_CACHE_DIR``, see ``conftest.py`` here).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import pyramid_cli.plan.shapes as generate
from helpers.paths import ROOT
from helpers.plans import planned, random_image
from pyramid_cli.core import cache
from pyramid_cli.core.errors import BackendError
from pyramid_cli.exec import emulate
from pyramid_cli.workflows import pyramids

pytest.importorskip("numba")

from pyramid_cli.exec import cpu  # noqa: E402


def test_cache_dir_follows_the_conventions(monkeypatch, tmp_path):
    monkeypatch.delenv(cache.HOME_ENV, raising=False)  # a run's own cache home would come before the conventions
    monkeypatch.setenv(cpu.CACHE_ENV, str(tmp_path / "mine"))
    assert cpu.cache_dir() == tmp_path / "mine"
    monkeypatch.delenv(cpu.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cpu.cache_dir() == tmp_path / "xdg" / "bilinear-pyramid" / "cpu"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cpu.cache_dir() == tmp_path / "home" / ".cache" / "bilinear-pyramid" / "cpu"


def test_without_numba_is_a_backend_error_naming_the_fix(monkeypatch, tmp_path):
    import builtins
    import importlib.util

    from pyramid_cli.exec.cpu import compile as cpu_compile

    real_find = importlib.util.find_spec
    monkeypatch.delitem(sys.modules, "numba", raising=False)  # put back by undo() below, before numba is used
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "numba" else real_find(name, *a))
    ok, why = cpu_compile.installed()
    assert not ok and "numba is not installed" in why and "pip install numba" in why
    with pytest.raises(BackendError, match="pip install numba"):
        cpu.CPUExecutor()
    monkeypatch.undo()

    real = builtins.__import__

    def no_numba(name, *args, **kwargs):
        if name == "numba" or name.startswith("numba."):
            raise ImportError("No module named 'numba'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_numba)
    ok, why = cpu.available()
    assert not ok and "pip install numba" in why and "\n" not in why
    # installed but not importable: said where a kernel first needs numba (a source no process has loaded)
    source = pyramids_source_nobody_loaded()
    with pytest.raises(BackendError, match=r"numba cannot be imported \(No module named 'numba'\); install numba"):
        cpu_compile.load(source, tmp_path)


def pyramids_source_nobody_loaded() -> str:
    """A kernel text of its own (a comment makes its digest new), so no process has it loaded."""
    import uuid

    plan = pyramids.blur_plan((9, 7), 1)
    return cpu.kernel_source(generate.shape(plan.passes[0])) + f"# {uuid.uuid4()}\n"


def test_importing_the_planner_does_not_import_numba():
    code = ("import sys, pyramid_cli.plan, pyramid_cli.exec.emulate, pyramid_cli.workflows.pyramids, "
            "pyramid_cli.exec.session; "
            "print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "False"


CHILD = r"""
import json, sys
import numpy as np
from pyramid_cli.exec import cpu
from pyramid_cli.workflows import pyramids
p = pyramids.blur_plan((40, 50), 3)
with cpu.CPUExecutor(threads=2) as ex:
    out = ex.run(p, np.ones((40, 50, 4), np.float32))
    print(json.dumps({"compiles": ex.compiles, "cache_loads": ex.cache_loads, "value": float(out.mean())}))
"""


@pytest.mark.slow
def test_a_second_process_compiles_nothing(tmp_path):
    """The first process compiles into an empty cache; a second one only loads the disk cache."""
    env = dict(os.environ, **{cpu.CACHE_ENV: str(tmp_path)})
    runs = []
    for _ in range(2):
        p = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, env=env, cwd=ROOT,
                           timeout=300)
        assert p.returncode == 0, p.stderr[-2000:]
        runs.append(json.loads(p.stdout.strip().splitlines()[-1]))
    shapes = len({generate.shape(ps) for ps in pyramids.blur_plan((40, 50), 3).passes})
    assert runs[0]["compiles"] == shapes and runs[0]["cache_loads"] == 0
    assert runs[1] == {"compiles": 0, "cache_loads": shapes, "value": pytest.approx(1.0, abs=1e-6)}


LOADER = r"""
import json, sys
import numpy as np
from pyramid_cli.exec import cpu
from pyramid_cli.workflows import pyramids
p = pyramids.blur_plan((40, 50), 5, strategy="fused")
with cpu.CPUExecutor(threads=1) as ex:
    ex.prepare(p, np.float16)
    out = ex.run_outputs(p, [np.ones((40, 50, 4), np.float16)])[0]
    print(json.dumps({"compiles": ex.compiles, "cache_loads": ex.cache_loads, "value": float(out.mean()),
                      "full_setup": "numba.np.linalg" in sys.modules or "scipy.linalg" in sys.modules}))
"""


@pytest.mark.slow
def test_a_cache_load_skips_numbas_full_setup(cache_folder):
    """Loading compiled kernels needs numba's runtime, not its whole library of implementations (about 0.15 s
    of imports and registrations in a fresh process): a process that only loads never imports them. (numba's
    own import checks scipy's version where scipy is installed, which imports the package but not scipy.linalg.)"""
    with cpu.CPUExecutor(threads=1) as ex:  # the kernels on disk (compiled once on a machine)
        ex.prepare(pyramids.blur_plan((40, 50), 5, strategy="fused"))
    p = subprocess.run([sys.executable, "-c", LOADER], capture_output=True, text=True, cwd=ROOT, timeout=300,
                       env=dict(os.environ, **{cpu.CACHE_ENV: str(cache_folder)}))
    assert p.returncode == 0, p.stderr[-2000:]
    got = json.loads(p.stdout.strip().splitlines()[-1])
    assert got == {"compiles": 0, "cache_loads": 2, "value": pytest.approx(1.0, abs=1e-6), "full_setup": False}


def test_an_unwritable_cache_folder_falls_back(tmp_path):
    """A cache path that cannot be a folder (here: a file) still runs, compiling into a private folder."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    _, p = planned("1/5 [1 1 3] * g", (4, 6))  # a shape no other test compiles
    image = random_image((4, 6), None, 1)
    with cpu.CPUExecutor(threads=1, cache=blocker / "cache") as odd:
        np.testing.assert_allclose(odd.run(p, image), emulate.run(p, image), rtol=0, atol=1e-5)
    assert list(cpu.fallback_cache().glob("k_*.py"))


@pytest.mark.slow
def test_a_cache_that_cannot_be_written_costs_the_cache_not_the_run(tmp_path):
    """A file-size limit (a full disk) hit while numba saves a fresh kernel: the run still succeeds."""
    import resource

    import OpenImageIO as oiio

    src, dst = tmp_path / "in.exr", tmp_path / "out.exr"
    assert oiio.ImageBuf(np.random.default_rng(2).random((9, 11, 3)).astype(np.float32)).write(str(src))

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (8_000, 8_000))  # the sources fit, numba's object code does not

    env = dict(os.environ, PYRAMID_CACHE_DIR=str(tmp_path / "fresh-cache"))
    p = subprocess.run([sys.executable, "-m", "pyramid_cli.cli", "apply", "--backend", "cpu", "-q",
                        "cubic *v (gauss5 * g)", str(src), str(dst)],
                       capture_output=True, text=True, preexec_fn=limit, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert dst.exists() and not p.stderr
