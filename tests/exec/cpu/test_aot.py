"""Ahead-of-time kernels (``pyramid_cli.exec.cpu.aot``): built by a process of their own after a run that loaded
kernels through numba, then imported by later processes without numba, bit for bit the kernels numba runs; a
machine that cannot build, a module that does not load, a builder that died, and turning them off.

The build (numba's pycc, then the system's C compiler) takes a few seconds a kernel: one module-scoped fixture
builds the blur's two kernels once, into a cache folder of its own.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers.paths import ROOT
from pyramid_cli.exec.cpu import aot

pytest.importorskip("numba")

from pyramid_cli.exec import cpu  # noqa: E402
from pyramid_cli.exec.cpu.compile import source_digest  # noqa: E402
from pyramid_cli.exec.cpu.executor import _pass_source  # noqa: E402
from pyramid_cli.plan.shapes import shape  # noqa: E402
from pyramid_cli.workflows import pyramids  # noqa: E402

BUILD_TIMEOUT = 300
BORDERS = ("clamp", "mirror", "wrap", "zero")

# Runs the blur on 2 threads on every border, float32 and half, and a codes table; with OUT, saves the outputs.
CHILD = r"""
import atexit, json, sys
import numpy as np
from pyramid_cli.exec import cpu
from pyramid_cli.workflows import pyramids
rng = np.random.default_rng(7)
img = rng.random((37, 53, 4), dtype=np.float32)
codes = rng.integers(0, 256, (37, 53, 4), dtype=np.uint8)
table = np.linspace(0.0, 1.0, 256, dtype=np.float32) ** 2.2
outs = {}
with cpu.CPUExecutor(threads=2) as ex:
    for border in ("clamp", "mirror", "wrap", "zero"):
        p = pyramids.blur_plan((37, 53), 3, border=border, strategy="fused")
        outs[border] = ex.run(p, img)
        outs[border + "-half"] = ex.run_outputs(p, [img.astype(np.float16)], np.float16)[-1]
        outs[border + "-codes"] = ex.run_outputs(p, [codes], codes=table)[-1]
    kinds = sorted({type(k.fn).__name__ for k in ex._kernels.values()})
if len(sys.argv) > 1:
    np.savez(sys.argv[1], **outs)
print(json.dumps({"numba": "numba" in sys.modules, "llvmlite": "llvmlite" in sys.modules, "kinds": kinds}))
"""


def _child(env: dict, *args: str) -> dict:
    p = subprocess.run([sys.executable, "-c", CHILD, *args], capture_output=True, text=True, env=env, cwd=ROOT,
                       timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


def _digests() -> set[str]:
    plan = pyramids.blur_plan((37, 53), 3, strategy="fused")
    return {source_digest(_pass_source(shape(ps), "float32")) for ps in plan.passes}


def _wait_built(where: Path, digests: set[str]) -> None:
    deadline = time.monotonic() + BUILD_TIMEOUT
    while time.monotonic() < deadline:
        if all(aot.module_path(where, d).exists() for d in digests) and not list(where.glob("*.lock")):
            return
        if (where / aot.UNAVAILABLE).exists():  # no C compiler or no Python headers: CI has both (.ci/run)
            why = f"the builder could not build here: {(where / aot.UNAVAILABLE).read_text().strip()}"
            pytest.fail(why) if os.environ.get("CI") else pytest.skip(why)
        time.sleep(0.5)
    pytest.fail(f"no modules after {BUILD_TIMEOUT} s in {where}: {sorted(p.name for p in where.iterdir())}")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A cache folder where a first process ran the blur through numba and its builder built both kernels."""
    cache = tmp_path_factory.mktemp("aot-cache")
    env = dict(os.environ, **{cpu.CACHE_ENV: str(cache), aot.ENV: "1"})
    first = _child(env)
    assert first["numba"] and first["kinds"] == ["CPUDispatcher"]
    where = cache / "aot" / aot.machine_key()
    _wait_built(where, _digests())
    return cache, env


@pytest.mark.slow
def test_a_later_process_runs_the_modules_without_numba_bit_for_bit(built, tmp_path):
    cache, env = built
    later = _child(env, str(tmp_path / "aot.npz"))
    assert later == {"numba": False, "llvmlite": False, "kinds": ["builtin_function_or_method"]}
    jit = _child(dict(env, **{aot.ENV: "0"}), str(tmp_path / "jit.npz"))
    assert jit["numba"] and jit["kinds"] == ["CPUDispatcher"]
    with np.load(tmp_path / "aot.npz") as a, np.load(tmp_path / "jit.npz") as b:
        assert sorted(a.files) == sorted(b.files) and len(a.files) == 3 * len(BORDERS)
        for name in a.files:
            assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, name
            assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name


@pytest.mark.slow
def test_the_cli_runs_without_numba_once_the_modules_are_built(built, tmp_path):
    cache, env = built
    src = tmp_path / "in.exr"
    import OpenImageIO as oiio

    px = np.random.default_rng(3).random((37, 53, 4)).astype(np.float16)
    out = oiio.ImageOutput.create(str(src))
    assert out.open(str(src), oiio.ImageSpec(53, 37, 4, "half")) and out.write_image(px) and out.close()
    script = ("import atexit, sys; atexit.register(lambda: print('numba' in sys.modules, file=sys.stderr)); "
              "from pyramid_cli.cli import main; main()")
    results = {}
    for mode in ("1", "0"):
        dst = tmp_path / f"out-{mode}.exr"
        p = subprocess.run([sys.executable, "-c", script, "blur", "--levels", "3", "--backend", "cpu", str(src),
                            str(dst)], capture_output=True, text=True, env=dict(env, **{aot.ENV: mode}), cwd=ROOT,
                           timeout=300)
        assert p.returncode == 0, p.stderr[-3000:]
        results[mode] = (p.stderr.strip().splitlines()[-1], dst.read_bytes())
    assert results["1"][0] == "False" and results["0"][0] == "True"
    assert results["1"][1] == results["0"][1]


def test_the_machine_key_is_the_processor_and_numpy(monkeypatch):
    intel = "vendor_id\t: GenuineIntel\nmodel name\t: Xeon\nflags\t\t: fpu sse2 avx2"
    key = aot.machine_key(intel)
    assert aot.machine_key(intel) == aot.machine_key(intel)
    assert aot.machine_key(intel) != aot.machine_key(intel + " avx512f")  # a node with other instructions
    assert aot.machine_key(intel.replace("Xeon", "Core")) != aot.machine_key(intel)
    assert aot.machine_key("") is None
    assert aot.machine_key() is not None  # Linux: /proc/cpuinfo is read
    monkeypatch.setattr(np, "__version__", "1.26.4")  # another environment's numpy, sharing the home folder
    assert aot.machine_key(intel) != key


def test_turned_off_nothing_is_loaded_or_built(monkeypatch, tmp_path):
    monkeypatch.setenv(aot.ENV, "0")
    assert aot.folder(tmp_path) is None
    assert aot.load(tmp_path, "0" * 24) is None
    assert not aot.spawn(tmp_path, [("0" * 24, "k.py", "void()")])
    assert not (tmp_path / "aot").exists()


def test_a_module_that_does_not_load_is_left_to_numba(monkeypatch, tmp_path):
    monkeypatch.setenv(aot.ENV, "1")
    where = aot.folder(tmp_path)
    where.mkdir(parents=True)
    digest = "ab" * 12
    aot.module_path(where, digest).write_bytes(b"\x7fELF cut short")
    assert aot.ready(tmp_path, digest)
    assert aot.load(tmp_path, digest) is None


def test_a_build_lock_is_respected_until_its_builder_is_presumed_dead(monkeypatch, tmp_path):
    monkeypatch.setenv(aot.ENV, "1")
    where = aot.folder(tmp_path)
    where.mkdir(parents=True)
    digest = "cd" * 12
    assert aot._lock(where, digest)
    assert not aot._lock(where, digest)            # a builder has it
    assert not aot.spawn(tmp_path, [(digest, "k.py", "void()")])
    assert aot.building(where) == [digest]
    old = time.time() - aot.STALE_S - 1
    os.utime(where / f"k_{digest}.lock", (old, old))
    assert aot.building(where) == []               # nobody waits on a dead builder (bench/run.py)
    assert aot._lock(where, digest)                # its builder died: taken over


@pytest.mark.slow
def test_a_machine_that_cannot_build_says_why_and_is_left_alone(monkeypatch, tmp_path):
    """No working C compiler: the builder writes its reason, removes its locks, and no builder is started
    again for a day; the run itself was never affected."""
    monkeypatch.setenv(aot.ENV, "1")
    monkeypatch.setenv("CC", "/nonexistent/cc")
    where = aot.folder(tmp_path)
    plan = pyramids.blur_plan((9, 7), 1, strategy="fused")
    digest = source_digest(_pass_source(shape(plan.passes[0]), "float32"))
    source = tmp_path / f"k_{digest}.py"
    source.write_text(_pass_source(shape(plan.passes[0]), "float32"), encoding="utf-8")
    from pyramid_cli.exec.cpu.codegen import signature

    s = shape(plan.passes[0])
    assert aot.spawn(tmp_path, [(digest, str(source), signature(s.n_sources, s.period[1]))])
    deadline = time.monotonic() + BUILD_TIMEOUT
    while not (where / aot.UNAVAILABLE).exists() and time.monotonic() < deadline:
        time.sleep(0.5)
    reason = (where / aot.UNAVAILABLE).read_text()
    assert reason.strip() and "\n" not in reason.strip()
    deadline = time.monotonic() + 30
    while list(where.glob("*.lock")) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not list(where.glob("*.lock")) and not aot.module_path(where, digest).exists()
    assert aot.blocked(where)
    assert not aot.spawn(tmp_path, [(digest, str(source), "void()")])
    old = time.time() - aot.RETRY_S - 1
    os.utime(where / aot.UNAVAILABLE, (old, old))
    assert not aot.blocked(where)


def test_a_source_that_is_not_its_kernel_is_not_built(monkeypatch, tmp_path):
    monkeypatch.setenv(aot.ENV, "1")
    where = aot.folder(tmp_path)
    where.mkdir(parents=True)
    source = tmp_path / "k.py"
    source.write_text("# not the kernel the digest names\n", encoding="utf-8")
    with pytest.raises(ValueError, match="is not the kernel"):
        aot.build(where, "ef" * 12, str(source), "void()")
    assert not list(where.iterdir())


def test_an_interrupted_run_starts_no_builder(monkeypatch, tmp_path):
    from pyramid_cli.core import signals

    monkeypatch.setenv(aot.ENV, "1")
    monkeypatch.setattr(signals, "_received", [15])  # SIGTERM arrived: the run is cleaning up
    assert signals.interrupted()
    assert not aot.spawn(tmp_path, [("0" * 24, "k.py", "void()")])
    assert not list((tmp_path / "aot").rglob("*.lock"))


def test_no_builder_is_started_from_an_applications_own_interpreter(monkeypatch, tmp_path):
    monkeypatch.setenv(aot.ENV, "1")
    monkeypatch.setattr(aot.sys, "executable", "/opt/dcc/bin/maya")  # a DCC's embedded Python
    assert not aot.spawn(tmp_path, [("0" * 24, "k.py", "void()")])
    assert not list((tmp_path / "aot").rglob("*.lock"))


def test_build_ahead_writes_each_missing_kernel_once_and_starts_one_builder(monkeypatch, tmp_path):
    """What auto's GL run leaves for the next process: the CPU plan's kernels and the 8-bit encoding loop, numba
    not imported for them (an 8-bit output's next run would otherwise import numba for the loop alone)."""
    from pyramid_cli.exec.cpu.codegen import ENCODE8_SIGNATURE, encode8_source, signature
    from pyramid_cli.exec.cpu.executor import build_ahead

    monkeypatch.setenv(aot.ENV, "1")
    started = []
    monkeypatch.setattr(aot, "spawn", lambda cache, kernels: started.append(kernels) or len(kernels))
    plan = pyramids.blur_plan((37, 53), 3, strategy="fused")
    assert build_ahead(plan, tmp_path) == 3
    (kernels,) = started
    wanted = {source_digest(encode8_source()): ENCODE8_SIGNATURE}
    for ps in plan.passes:
        s = shape(ps)
        wanted[source_digest(_pass_source(s, "float32"))] = signature(s.n_sources, s.period[1])
    assert {d: sig for d, _, sig in kernels} == wanted and len(kernels) == len(wanted) == 3
    for digest, path, _ in kernels:
        assert source_digest(Path(path).read_text(encoding="utf-8")) == digest  # what the builder checks
    where = aot.folder(tmp_path)
    where.mkdir(parents=True)
    first = kernels[0][0]
    aot.module_path(where, first).write_bytes(b"built")
    started.clear()
    assert build_ahead(plan, tmp_path) == 2
    assert [d for d, _, _ in started[0]] == [d for d, _, _ in kernels[1:]]  # one is built already
    monkeypatch.setenv(aot.ENV, "0")
    started.clear()
    assert not build_ahead(plan, tmp_path) and started == []
