"""The compiled CPU executor against the float64 oracle (``reference``) and the plan's living definition (``emulate``).

Kernels compile into a temporary cache folder made for this module (``PYRAMID_CACHE_DIR``), so
the run is cold: every pass shape of the grid compiles once (about a second each on 2 cores).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import pyramid_cli.plan.shapes as generate
from helpers.cases import CHAINS as WRITTEN
from helpers.cases import GRID_CHANNELS, GRID_SIZES, NAMED, step
from helpers.marks import slow_beyond
from pyramid_cli.core.border import Border
from pyramid_cli.core.errors import BackendError
from pyramid_cli.core.geometry import mip_levels
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import Builder, check, plan
from pyramid_cli.reference import filters as reference
from pyramid_cli.reference.pyramids import blur_reference
from pyramid_cli.workflows import pyramids

pytest.importorskip("numba")

from helpers.paths import ROOT
from pyramid_cli.exec import cpu  # noqa: E402

CHAINS = NAMED + [c for c in WRITTEN if c not in NAMED] + ["box *v (midpoint *^ g)", "g"]
SIZES = GRID_SIZES
CHANNELS = GRID_CHANNELS
BORDERS = ["clamp", "mirror", "wrap", "zero"]
BORDER_SIZES = [(1, 1), (1, 7), (7, 1), (5, 3), (17, 13), (40, 33), (90, 77)]  # the last: interior + strips
BORDER_CHAINS = NAMED + ["doosabin *^ (box4 *v g)", "box\\ *v bartlett", "(box4)^2 *v g",
                         "1/16 [1 2 1; 2 4 2; 1 2 1] * g", "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g"]


@pytest.fixture(scope="module", autouse=True)
def cache_folder():
    """The kernel cache of this module (the environment variable every executor and child reads): one folder
    kept across test runs on a machine, so a rerun loads instead of compiling; the compile-then-load test
    below uses a fresh one of its own."""
    import tempfile

    folder = Path(tempfile.gettempdir()) / f"pyramid-cpu-test-cache-{os.getuid()}"
    folder.mkdir(exist_ok=True)
    saved = os.environ.get(cpu.CACHE_ENV)
    os.environ[cpu.CACHE_ENV] = str(folder)
    yield folder
    if saved is None:
        os.environ.pop(cpu.CACHE_ENV, None)
    else:
        os.environ[cpu.CACHE_ENV] = saved


@pytest.fixture(scope="module")
def ex(cache_folder):
    with cpu.CPUExecutor(threads=2) as executor:
        assert executor.cache == cache_folder
        yield executor


def random_image(size, channels, seed, dtype=np.float32):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(size if channels is None else size + (channels,)).astype(dtype)


def _planned(text, size, strategy="cost", border="clamp"):
    expr = parse(text)
    p = plan(expr, size, strategy, border)
    check(p)
    return expr, p


@pytest.mark.parametrize("channels", [None, 1, 3, 4, 6, 2])
def test_every_channel_count(ex, channels):
    """C = 4 and 1 have unrolled loops; others (2, 3, 6) the generic one: all agree with the reference."""
    size = (23, 31)
    image = random_image(size, channels, 5)
    for text in ["doosabin *^ (box4 *v g)", "fourpoint", "cubic *v g", "quasi"]:
        expr, p = _planned(text, size)
        np.testing.assert_allclose(ex.run(p, image), reference.run(expr, image), rtol=0, atol=1e-5, err_msg=text)


@pytest.mark.slow
@pytest.mark.parametrize("threads", [1, 3])
def test_threads_split_rows_without_changing_a_bit(threads):
    """Large enough for the interior to run in bands on the worker threads: identical to one thread."""
    size = (601, 517)  # over cpu.SMALL output floats: the interior runs in bands on the workers
    image = random_image(size, 4, 8)
    with cpu.CPUExecutor(threads=1) as one, cpu.CPUExecutor(threads=threads) as many:
        for text in ["doosabin *^ (box4 *v g)", "bartlett", "fourpoint", "(box4)^3 *v g"]:
            expr, p = _planned(text, size)
            got = many.run(p, image)
            np.testing.assert_array_equal(got, one.run(p, image))
            if text != "(box4)^3 *v g":
                np.testing.assert_allclose(got, reference.run(expr, image), rtol=0, atol=1e-5)
    assert many.threads == threads


def test_blur_levels_collapse_and_mip(ex):
    size = (45, 70)
    image = random_image(size, 3, 12)
    for levels, analysis, synthesis in [(3, "box4", "doosabin"), (2, "cubic", "fourpoint"), (4, "quadratic", "cubic")]:
        p = pyramids.blur_plan(size, levels, analysis, synthesis)
        np.testing.assert_allclose(ex.run(p, image), blur_reference(image, levels, analysis, synthesis),
                                   rtol=0, atol=1e-5)
    p = pyramids.blur_plan(size, 2, quasi=True)
    np.testing.assert_allclose(ex.run(p, image), blur_reference(image, 2, quasi=True), rtol=0, atol=1e-5)
    sigma, _, _ = pyramids.blur_plan_sigma(size, 3.0)  # a blend: one combine pass reading two blurs
    np.testing.assert_allclose(ex.run(sigma, image), emulate.run(sigma, image), rtol=0, atol=1e-5)
    # the analysis pyramid and the Laplacian bands, every output
    for laplacian in (False, True):
        p = pyramids.levels_plan(size, 3, "box4", laplacian)
        outs = ex.run_outputs(p, [image])
        want = emulate.run_outputs(p, image)
        assert [o.shape for o in outs] == [w.shape for w in want]
        for o, w in zip(outs, want, strict=True):
            np.testing.assert_allclose(o, w, rtol=0, atol=1e-5)
    g = image
    for k, level in enumerate(ex.run_outputs(pyramids.levels_plan(size, 3), [image])):
        g = reference.run(parse("box4 *v g"), g)
        np.testing.assert_allclose(level, g, rtol=0, atol=1e-5, err_msg=f"level {k + 1}")
    # collapse rebuilds the input from its bands
    bands = ex.run_outputs(pyramids.levels_plan(size, 3, "box4", True), [image])
    back = ex.run(pyramids.collapse_plan(tuple(b.shape[:2] for b in bands)), bands)
    np.testing.assert_allclose(back, image, rtol=0, atol=1e-5)
    # MIP: quadratic down to 1×1, every level read back
    n = mip_levels(size)
    mip = pyramids.levels_plan(size, n, "quadratic")
    outs = ex.run_outputs(mip, [image])
    assert outs[-1].shape == (1, 1, 3)
    for o, w in zip(outs, emulate.run_outputs(mip, image), strict=True):
        np.testing.assert_allclose(o, w, rtol=0, atol=1e-5)


def test_half_input_read_back_and_borders(ex):
    size = (9, 11)
    image = random_image(size, 4, 3, np.float16)
    expr, p = _planned("bartlett", size, border="mirror")
    np.testing.assert_allclose(ex.run(p, image), reference.run(expr, image.astype(np.float32), Border("mirror")),
                               rtol=0, atol=1e-5)
    _, ident = _planned("g", size)
    b = Builder(size)
    done = step(b, 0, "box *v g")
    both = b.build("x", outputs=[0, done])
    first, _ = ex.run_outputs(both, [image], dtype=np.float16)
    np.testing.assert_array_equal(first, image)
    np.testing.assert_array_equal(ex.run(ident, image), image.astype(np.float32))


def test_other_dtypes_and_layouts(ex):
    size = (20, 30)
    base = random_image(size, 6, 4)
    expr, p = _planned("gauss5", size)
    want = reference.run(expr, base[:, :, 1:4])
    np.testing.assert_allclose(ex.run(p, base[:, :, 1:4]), want, rtol=0, atol=1e-5)  # a strided view
    np.testing.assert_allclose(ex.run(p, base[:, :, 1:4].astype(np.float64)), want, rtol=0, atol=1e-5)
    np.testing.assert_allclose(ex.run(p, [base[:, :, 1:4].tolist()]), want, rtol=0, atol=1e-5)  # nested lists


def test_bad_inputs_are_value_errors(ex):
    _, p = _planned("box *v g", (4, 5))
    with pytest.raises(ValueError, match="4x5"):
        ex.run(p, np.zeros((5, 4), np.float32))
    with pytest.raises(ValueError, match="input image"):
        ex.run_outputs(p, [np.zeros((4, 5)), np.zeros((4, 5))])
    with pytest.raises(ValueError, match="float32 or float16"):
        ex.run_outputs(p, [np.zeros((4, 5))], dtype=np.float64)
    with pytest.raises(ValueError, match="nonzero"):
        ex.run(p, np.zeros((4, 5, 0), np.float32))


def test_kernels_are_compiled_once_per_shape(cache_folder):
    _, p = _planned("gauss5", (17, 13), "paper")  # box↖ and box↘ alternate: 2 shapes, 4 passes
    shapes = {generate.shape(ps) for ps in p.passes}
    assert len(shapes) == 2 < len(p.passes)
    with cpu.CPUExecutor(threads=1) as fresh:
        fresh.prepare(p)
        assert len(fresh._kernels) == 2
        made = fresh.compiles + fresh.cache_loads
        fresh.run(p, random_image((17, 13), None, 0))
        _, other = _planned("gauss5", (64, 129), "paper")
        fresh.run(other, random_image((64, 129), 6, 2))
        _, box = _planned("box\\ * g", (5, 3))
        fresh.run(box, random_image((5, 3), 3, 4))
        assert fresh.compiles + fresh.cache_loads == made <= 2  # 0 where another executor of this process made them
        assert len(fresh._kernels) == 2
    sources = sorted(cache_folder.glob("k_*.py"))
    assert sources and all("def kernel(" in f.read_text() for f in sources)


def test_kernel_source_is_canonical_and_unrolled():
    _, a = _planned("gauss7", (9, 9), "paper")
    _, b = _planned("bartlett", (40, 3), "paper")
    texts = {cpu.kernel_source(generate.shape(ps), (False,)) for ps in a.passes + b.passes}
    assert len(texts) == 2
    _, ds = _planned("doosabin", (8, 8))
    text = cpu.kernel_source(generate.shape(ds.passes[0]), (False,))
    assert "cache=True" in text and "v0_3 = t0[" in text and "if C == 4:" in text  # RGBA unrolled
    assert "np.float32(0.25)" in text and "np.float32(0.75)" in text  # one vertical (¼, ¾) sum per row phase
    assert "lut[" not in text and "lut[" in cpu.kernel_source(generate.shape(ds.passes[0]), (True,))


def test_phase_terms_expand_taps_exactly():
    """A tap at a quarter position becomes its four texels, with the bilinear weights, summed per texel."""
    _, p = _planned("doosabin", (8, 8))
    for _, taps in generate.shape(p.passes[0]).phases:
        terms = cpu.phase_terms(taps)
        assert sum(t.weight for t in terms) == 1 and len(terms) == 4
        assert sorted(t.weight for t in terms) == [Fraction(1, 16), Fraction(3, 16), Fraction(3, 16), Fraction(9, 16)]


def test_factor_splits_only_separable_weights():
    u, (v,) = cpu.factor([{(0, 0): Fraction(1, 4), (0, 1): Fraction(1, 4), (1, 0): Fraction(1, 4),
                           (1, 1): Fraction(1, 4)}])
    assert u == {0: Fraction(1, 2), 1: Fraction(1, 2)} and v == {0: Fraction(1, 2), 1: Fraction(1, 2)}
    assert cpu.factor([{(0, 0): Fraction(1), (1, 1): Fraction(1)}]) is None


def test_cache_dir_follows_the_conventions(monkeypatch, tmp_path):
    monkeypatch.setenv(cpu.CACHE_ENV, str(tmp_path / "mine"))
    assert cpu.cache_dir() == tmp_path / "mine"
    monkeypatch.delenv(cpu.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cpu.cache_dir() == tmp_path / "xdg" / "bilinear-pyramid" / "cpu"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cpu.cache_dir() == tmp_path / "home" / ".cache" / "bilinear-pyramid" / "cpu"


def test_without_numba_is_a_backend_error_naming_the_fix(monkeypatch):
    import builtins

    real = builtins.__import__

    def no_numba(name, *args, **kwargs):
        if name == "numba" or name.startswith("numba."):
            raise ImportError("No module named 'numba'")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_numba)
    ok, why = cpu.available()
    assert not ok and "pip install numba" in why and "\n" not in why
    with pytest.raises(BackendError, match="pip install numba"):
        cpu.CPUExecutor()


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


@pytest.mark.parametrize("border", slow_beyond(BORDERS))
def test_cpu_plans_fuse_each_step_and_equal_reference(ex, border):
    """The "fused" strategy (the CPU executor's): one pass per written step, the same numbers at every pixel."""
    from pyramid_cli.core.expr import steps

    rng = np.random.default_rng(7)
    for text in BORDER_CHAINS + ["(doosabin)^2 *^ ((box4)^2 *v g)", "fourpoint *^ (cubic *v g)"]:
        expr = parse(text)
        for size in [(1, 1), (6, 9), (17, 13)]:
            p = plan(expr, size, cpu.CPUExecutor.strategy, border)
            check(p)
            assert len(p.passes) == sum(1 for _ in steps(expr))
            image = rng.standard_normal(size + (2,)).astype(np.float32)
            np.testing.assert_allclose(ex.run(p, image), reference.run(expr, image, Border(border)), rtol=0,
                                       atol=1e-5, err_msg=f"{text} {size}")


def test_cpu_blur_plan_equals_the_blur_reference(ex):
    size = (45, 70)
    image = random_image(size, 4, 13)
    p = pyramids.blur_plan(size, 3, strategy=cpu.CPUExecutor.strategy)
    assert len(p.passes) == 6
    np.testing.assert_allclose(ex.run(p, image), blur_reference(image, 3), rtol=0, atol=1e-5)


def test_an_unwritable_cache_folder_falls_back(tmp_path):
    """A cache path that cannot be a folder (here: a file) still runs, compiling into a private folder."""
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    _, p = _planned("1/5 [1 1 3] * g", (4, 6))  # a shape no other test compiles
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
