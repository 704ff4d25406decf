"""What a fresh ``pyramid`` process loads before it answers: nothing heavy for ``--help``, ``--version``,
``explain``, ``plan`` or a ``diff`` of two PNGs (docs/performance.md, "Fixed costs").

Each command runs in a new interpreter that then lists ``sys.modules``; numba and llvmlite (about 0.2 s),
moderngl, matplotlib and Dask belong to the commands that need them, numpy and OpenImageIO to those that
touch pixels, and the version comes from the package, not from reading every installed distribution's
metadata (``importlib.metadata``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio
import pytest

from helpers.marks import slow_beyond

pytestmark = pytest.mark.cli

LIST_MODULES = """
import atexit, json, os, runpy, sys
def listed():  # the console script ends the process after its atexit handlers
    with open(os.environ["MODULES_TO"], "w") as f:
        json.dump(sorted(sys.modules), f)
atexit.register(listed)
sys.argv = ["pyramid", *sys.argv[1:]]
runpy.run_module("pyramid_cli.cli", run_name="__main__")
"""

NEVER = {"numba", "llvmlite", "moderngl", "glcontext", "matplotlib", "dask", "distributed", "scipy",
         "importlib.metadata"}
NO_PIXELS = NEVER | {"numpy", "OpenImageIO"}
# a diff reads two files: it needs neither the band streams, the texture writer, nor any executor or planner
DIFF = NEVER | {"pyramid_cli.imageio.bands", "pyramid_cli.imageio.texture", "pyramid_cli.exec", "pyramid_cli.plan",
                "pyramid_cli.run.stream"}

COMMANDS = [
    (["--help"], NO_PIXELS),
    (["explain", "box\\ *v bartlett"], NO_PIXELS),
    (["plan", "quadratic *v g", "--size", "1920x1080"], NO_PIXELS),
    (["diff", "a.png", "b.png"], DIFF),
    (["--version"], NO_PIXELS),
    (["blur", "--help"], NO_PIXELS),
    (["mipmap", "--help"], NO_PIXELS),
    (["diff", "--help"], NO_PIXELS),
    (["explain", "--json", "h_Doo-Sabin ⊗↑ g"], NO_PIXELS),
    (["plan", "--json", "h_Doo-Sabin ⊗↑ g", "--size", "64x64"], NO_PIXELS),
    (["plan", "--mipmap", "down", "quadratic *v g", "--size", "1001x777"], NO_PIXELS),
    (["plan", "gauss7", "--size", "32768x32768", "--memory", "1G"], NEVER),  # run.stream's estimate: numpy
    (["diff", "--json", "a.png", "b.png"], DIFF),
    (["tiles", "--help"], NO_PIXELS),
    # a local tile set loads no cluster client, and no library of another layout
    (["tiles", "a.png", "a.dzi"], {"dask", "distributed", "matplotlib", "zarr", "ome_zarr", "tifffile"}),
    # OME-Zarr through zarr alone: ome-zarr's writer imports dask.array and SciPy (1.9 s)
    (["tiles", "a.png", "a.ome.zarr"], {"dask", "distributed", "matplotlib", "ome_zarr", "scipy", "tifffile"}),
]


def loaded(args: list[str], cwd) -> set[str]:
    """The modules a fresh ``pyramid ARGS`` process has loaded when it ends."""
    out = cwd / "modules.json"
    env = dict(os.environ, MODULES_TO=str(out), PYRAMID_CACHE_HOME=str(cwd / "cache"))
    subprocess.run([sys.executable, "-c", LIST_MODULES, *args], cwd=cwd, env=env, capture_output=True, timeout=120,
                   check=False)
    return set(json.loads(out.read_text()))


def png(path, seed: int) -> None:
    pixels = np.random.default_rng(seed).integers(0, 256, (16, 16, 3), dtype=np.uint8)
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(16, 16, 3, "uint8"))
    out.write_image(pixels)
    out.close()


@pytest.mark.parametrize("args, forbidden", slow_beyond(COMMANDS, 4, unpack=True),
                         ids=[" ".join(args) for args, _ in COMMANDS])
def test_a_command_loads_only_what_it_uses(args, forbidden, tmp_path):
    png(tmp_path / "a.png", 1)
    png(tmp_path / "b.png", 2)
    modules = loaded(args, tmp_path)
    assert "pyramid_cli.cli" in modules  # it ran
    heavy = sorted(m for m in modules if m in forbidden or m.split(".")[0] in forbidden
                   or any(m.startswith(f + ".") for f in forbidden))
    assert not heavy, f"pyramid {' '.join(args)} loaded {heavy}"


AUTO_ESTIMATES = """
import json, sys
startup = sorted(sys.modules)  # what the interpreter's site (a .pth file, say) loaded before any of ours
import numpy as np
from pyramid_cli.exec import session
from pyramid_cli.exec.gl import context
from pyramid_cli.jobs.work import Blur
chosen = []
session.Session._use_gl = lambda self, info: chosen.append("gl")  # record the choice, make nothing
session.Session._use_cpu = lambda self: chosen.append("cpu")
context.machine_gl = lambda key=None: {"ok": True, "renderer": "llvmpipe (LLVM 15.0.6, 256 bits)"}
s = session.Session("auto")
s.decide(Blur(levels=5), [(1080, 1920, 4)], 1, np.float16)
print(json.dumps({"chosen": chosen, "estimated": sorted(s.estimates), "modules": sorted(sys.modules),
                  "startup": startup}))
"""


def test_auto_weighs_gl_without_loading_the_gl_executor(tmp_path):
    """``auto`` estimates GL from its textures' sizes (:mod:`pyramid_cli.exec.gl.textures`), the shipped cost
    models read without ``importlib.resources`` (which brings tempfile, shutil and zipfile) and the EGL driver's key
    made without ``socket``: a run that then picks the CPU executor never loads the GL executor and its shader
    generator (about 5 ms of a fresh process). The renderer is said to be llvmpipe, whose costs ship. Modules the
    interpreter had loaded before the run are not the run's (on an H100 host's Python 3.12 a site file had loaded
    ``importlib.resources``)."""
    env = dict(os.environ, PYRAMID_CACHE_HOME=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", AUTO_ESTIMATES], capture_output=True, text=True, timeout=120,
                         check=True, env=env)
    got = json.loads(out.stdout)
    assert got["estimated"] == ["cpu", "gl"] and len(got["chosen"]) == 1, got["chosen"]
    loaded_too = {"moderngl", "pyramid_cli.exec.gl.executor", "pyramid_cli.exec.gl.shaders", "importlib.resources",
                  "socket", "numba"} & (set(got["modules"]) - set(got["startup"]))
    assert not loaded_too


@pytest.mark.slow
def test_the_check_sees_a_heavy_import(tmp_path):
    """The listing is the process's own: a command that draws a plot does load matplotlib."""
    pytest.importorskip("matplotlib")
    modules = loaded(["explain", "--plot", str(tmp_path / "p.png"), "box4 *v g"], tmp_path)
    assert "matplotlib" in modules


def test_the_python_api_loads_no_image_io_until_it_reads_a_file():
    """``pyr.blur`` on arrays needs numpy and an executor, not OpenImageIO (``pyr.read_image`` loads it)."""
    script = "import json, sys, pyramid_cli as pyr; pyr.blur, pyr.Session; print(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    modules = set(json.loads(out.stdout))
    assert "pyramid_cli.api" in modules
    assert not {"OpenImageIO", "numba", "moderngl", "matplotlib", "dask"} & modules
