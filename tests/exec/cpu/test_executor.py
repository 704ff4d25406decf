"""The compiled CPU executor (``pyramid_cli.exec.cpu.executor``) against the float64 oracle (``reference``) and
the plan's living definition (``emulate``).

Kernels compile into the kernel cache folder of this module (``PYRAMID_CACHE_DIR``, see ``conftest.py`` here),
kept across test runs on a machine: a cold run compiles every pass shape once (about a second each on 2 cores).
"""

from __future__ import annotations

import numpy as np
import pytest

import pyramid_cli.plan.shapes as generate
from helpers.cases import NAMED, step
from helpers.marks import slow_beyond
from helpers.plans import planned, random_image
from pyramid_cli.core.border import Border
from pyramid_cli.core.geometry import mip_levels
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import Builder, check, plan
from pyramid_cli.reference import filters as reference
from pyramid_cli.reference.pyramids import blur_reference
from pyramid_cli.workflows import pyramids

pytest.importorskip("numba")

from pyramid_cli.exec import cpu  # noqa: E402

BORDERS = ["clamp", "mirror", "wrap", "zero"]
BORDER_CHAINS = NAMED + ["doosabin *^ (box4 *v g)", "box\\ *v bartlett", "(box4)^2 *v g",
                         "1/16 [1 2 1; 2 4 2; 1 2 1] * g", "1/8 [1 2 1; 0 2 0; 1 0 1] *v g", "[1 -1] * g"]


@pytest.fixture(scope="module")
def ex(cache_folder):
    with cpu.CPUExecutor(threads=2) as executor:
        assert executor.cache == cache_folder
        yield executor


@pytest.mark.parametrize("channels", [None, 1, 3, 4, 6, 2])
def test_every_channel_count(ex, channels):
    """C = 4 and 1 have unrolled loops, C = 3 too in one-phase strided passes (box4 *v g); others (2, 6) the
    generic one: all agree with the reference."""
    size = (23, 31)
    image = random_image(size, channels, 5)
    for text in ["doosabin *^ (box4 *v g)", "fourpoint", "cubic *v g", "quasi"]:
        expr, p = planned(text, size)
        np.testing.assert_allclose(ex.run(p, image), reference.run(expr, image), rtol=0, atol=1e-5, err_msg=text)


@pytest.mark.slow
@pytest.mark.parametrize("threads", [1, 3])
def test_threads_split_rows_without_changing_a_bit(threads):
    """Large enough for the interior to run in bands on the worker threads: identical to one thread."""
    size = (601, 517)  # over cpu.SMALL output floats: the interior runs in bands on the workers
    image = random_image(size, 4, 8)
    with cpu.CPUExecutor(threads=1) as one, cpu.CPUExecutor(threads=threads) as many:
        for text in ["doosabin *^ (box4 *v g)", "bartlett", "fourpoint", "(box4)^3 *v g"]:
            expr, p = planned(text, size)
            got = many.run(p, image)
            np.testing.assert_array_equal(got, one.run(p, image))
            if text != "(box4)^3 *v g":
                np.testing.assert_allclose(got, reference.run(expr, image), rtol=0, atol=1e-5)
    assert many.threads == threads


@pytest.mark.slow
@pytest.mark.parametrize("border", BORDERS)
def test_border_strips_run_beside_the_interior(border):
    """Over cpu.SMALL output floats the strips are gathered while the pool computes the interior, then computed
    in one task behind it: the same bits as one thread, and the plan's numbers, at every border."""
    size = (601, 517)
    image = random_image(size, 4, 9)
    with cpu.CPUExecutor(threads=1) as one, cpu.CPUExecutor(threads=2) as two:
        for text in ["doosabin *^ (box4 *v g)", "fourpoint"]:
            p = plan(parse(text), size, cpu.CPUExecutor.strategy, border)
            got = two.run(p, image)
            np.testing.assert_array_equal(got, one.run(p, image))
            np.testing.assert_allclose(got, emulate.run(p, image), rtol=0, atol=1e-5, err_msg=f"{text} {border}")


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
    expr, p = planned("bartlett", size, border="mirror")
    np.testing.assert_allclose(ex.run(p, image), reference.run(expr, image.astype(np.float32), Border("mirror")),
                               rtol=0, atol=1e-5)
    _, ident = planned("g", size)
    b = Builder(size)
    done = step(b, 0, "box *v g")
    both = b.build("x", outputs=[0, done])
    first, _ = ex.run_outputs(both, [image], dtype=np.float16)
    np.testing.assert_array_equal(first, image)
    np.testing.assert_array_equal(ex.run(ident, image), image.astype(np.float32))


def test_other_dtypes_and_layouts(ex):
    size = (20, 30)
    base = random_image(size, 6, 4)
    expr, p = planned("gauss5", size)
    want = reference.run(expr, base[:, :, 1:4])
    np.testing.assert_allclose(ex.run(p, base[:, :, 1:4]), want, rtol=0, atol=1e-5)  # a strided view
    np.testing.assert_allclose(ex.run(p, base[:, :, 1:4].astype(np.float64)), want, rtol=0, atol=1e-5)
    np.testing.assert_allclose(ex.run(p, [base[:, :, 1:4].tolist()]), want, rtol=0, atol=1e-5)  # nested lists


def test_bad_inputs_are_value_errors(ex):
    _, p = planned("box *v g", (4, 5))
    with pytest.raises(ValueError, match="4x5"):
        ex.run(p, np.zeros((5, 4), np.float32))
    with pytest.raises(ValueError, match="input image"):
        ex.run_outputs(p, [np.zeros((4, 5)), np.zeros((4, 5))])
    with pytest.raises(ValueError, match="float32, float16 or float64"):
        ex.run_outputs(p, [np.zeros((4, 5))], dtype=np.int32)
    with pytest.raises(ValueError, match="nonzero"):
        ex.run(p, np.zeros((4, 5, 0), np.float32))


def test_kernels_are_compiled_once_per_shape(cache_folder):
    _, p = planned("gauss5", (17, 13), "paper")  # box↖ and box↘ alternate: 2 shapes, 4 passes
    shapes = {generate.shape(ps) for ps in p.passes}
    assert len(shapes) == 2 < len(p.passes)
    with cpu.CPUExecutor(threads=1) as fresh:
        fresh.prepare(p)
        assert len(fresh._kernels) == 2
        made = fresh.compiles + fresh.cache_loads
        fresh.run(p, random_image((17, 13), None, 0))
        _, other = planned("gauss5", (64, 129), "paper")
        fresh.run(other, random_image((64, 129), 6, 2))
        _, box = planned("box\\ * g", (5, 3))
        fresh.run(box, random_image((5, 3), 3, 4))
        assert fresh.compiles + fresh.cache_loads == made <= 2  # 0 where another executor of this process made them
        assert len(fresh._kernels) == 2
    sources = sorted(cache_folder.glob("k_*.py"))
    assert sources and all("def kernel(" in f.read_text() for f in sources)


@pytest.mark.parametrize("make", [lambda: pyramids.blur_plan((37, 61), 5, strategy="fused"),
                                  lambda: pyramids.mip_plan((96, 90), strategy="fused")], ids=["blur5", "mip"])
def test_a_blur_and_a_mip_plan_run_on_at_most_two_kernels(ex, make):
    """A run loads one or two kernels from the cache, not one per pass shape and storage: half and float32
    sources share a kernel, and every resampling pass (both axes) shares one."""
    p = make()
    kinds = {type(ps).__name__ for ps in p.passes}
    with cpu.CPUExecutor(threads=1) as fresh:
        fresh.prepare(p, np.float16)  # a half file's first pass reads float16, the others float32
        fresh.prepare(p, np.float32)
        x = random_image(p.images[p.inputs[0]].size, 4, 5)
        half, full = (fresh.run_outputs(p, [x.astype(d)]) for d in (np.float16, np.float32))
        assert len(fresh._kernels) == len(fresh.kernel_digests(p)) <= 2
        assert fresh.uncached(p, np.float16) == fresh.uncached(p) == 0
    assert len(kinds) == (2 if "ResamplePass" in kinds else 1)  # the mip plan has both kinds of pass
    want = [o for o in ex.run_outputs(p, [x.astype(np.float16).astype(np.float32)])]
    for h, f, w in zip(half, full, want, strict=True):
        np.testing.assert_array_equal(h, w)  # a half input reads exactly its float32 values
        assert f.shape == w.shape


def test_dead_intermediates_are_reused_and_live_ones_are_not(ex):
    """A run writes a later target into a dead intermediate of its shape (the way up into the way down),
    never into an image still to be read or returned."""
    size = (64, 96)
    x = random_image(size, 3, 8)
    sigma, _, _ = pyramids.blur_plan_sigma(size, 5.0, strategy="fused")  # two ways up, blended at the end
    np.testing.assert_allclose(ex.run(sigma, x), emulate.run(sigma, x), rtol=0, atol=1e-5)
    lap = pyramids.levels_plan(size, 3, laplacian=True, strategy="fused")
    outs = ex.run_outputs(lap, [x])
    for o, want in zip(outs, emulate.run_outputs(lap, [x]), strict=True):
        np.testing.assert_allclose(o, want, rtol=0, atol=1e-5)
    assert not any(np.shares_memory(a, b) for i, a in enumerate(outs) for b in outs[i + 1:])


def test_the_last_output_is_written_into_out(ex):
    """``out=``: the last output's pixels in the caller's array (the tile scheduler's bands), the same values as
    without it: written by the last pass itself at float32, copied there at float16; the other outputs as ever."""
    size = (37, 53)
    x = random_image(size, 3, 9)
    p = pyramids.levels_plan(size, 3, strategy="fused")
    want = ex.run_outputs(p, [x])
    for dtype in (np.float32, np.float16):
        out = np.full(want[-1].shape, np.nan, dtype)
        got = ex.run_outputs(p, [x], dtype, out=out)
        assert got[-1] is out
        np.testing.assert_array_equal(out, want[-1].astype(dtype))
        for a, b in zip(got[:-1], want[:-1], strict=True):
            np.testing.assert_array_equal(a, b.astype(dtype))


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


def test_pointwise_kernel_equals_the_emulator_on_every_op_at_any_offset(ex):
    """Every pointwise op through the CPU kernel (its loops index unsigned, so LLVM vectorises them) against the
    emulator's formulas (NaN for NaN): zeros, negatives, NaN/Inf and subnormals included, over ranges that start
    and end off the vector width. Where ``min(1, k·a)`` meets a NaN the kernel's ``min`` gives 1 and numpy's NaN
    (a weight is never NaN: the fill's inputs refuse them), so those elements are left out there."""
    from pyramid_cli.exec.cpu.codegen import POINTWISE_CODES
    from pyramid_cli.plan.model import POINTWISE_OPS

    rng = np.random.default_rng(5)
    special = np.array([0, -0.0, 1, -1, 0.5, 2, np.nan, np.inf, -np.inf, 1e-40, 3e38], np.float32)
    ops = [np.concatenate([special, rng.normal(size=1000).astype(np.float32)]) for _ in range(3)]
    for a in ops:
        rng.shuffle(a)
    fn = ex.pointwise_kernel()
    for op, code in POINTWISE_CODES.items():
        arity = POINTWISE_OPS[op][0]
        want = emulate.pointwise(op, ops[:arity], 4).astype(np.float32)
        for i0, i1 in [(0, ops[0].size), (3, ops[0].size - 5)]:
            out = np.full(ops[0].size, 7, np.float32)
            fn(out, *ops, np.float32(4), code, i0, i1)
            keep = np.arange(i0, i1)
            if op == "pull_weight":
                keep = keep[~np.isnan(ops[0][keep])]
            np.testing.assert_array_equal(out[keep], want[keep], err_msg=op)
            assert np.all(out[:i0] == 7) and np.all(out[i1:] == 7)


@pytest.mark.parametrize("text, border", [("quadratic *v g", "clamp"), ("gauss5", "mirror"), ("bartlett", "zero"),
                                          ("doosabin *^ (box4 *v g)", "wrap")])
@pytest.mark.parametrize("bits", [8, 16])
def test_codes_read_through_a_table_equal_the_table_applied_first(ex, text, border, bits):
    """run_outputs(codes=table) on 8/16-bit codes gives, to the bit, what the floats ``table[codes]`` give: the
    table takes the float16 one's place in every kernel read (and an input read back is looked up too)."""
    rng = np.random.default_rng(bits)
    n = 256 if bits == 8 else 65536
    table = np.sort(rng.uniform(-0.5, 2.0, n)).astype(np.float32)
    table[0] = 0  # what a zero border reads
    codes = rng.integers(0, n, (13, 17, 3)).astype(np.uint8 if bits == 8 else np.uint16)
    _, p = planned(text, (13, 17), border=border)
    np.testing.assert_array_equal(ex.run_outputs(p, [codes], codes=table)[-1], ex.run(p, table[codes]))
    b = Builder((13, 17))
    done = step(b, 0, "box *v g")
    both = b.build("x", outputs=[0, done])
    for got, want in zip(ex.run_outputs(both, [codes], codes=table), ex.run_outputs(both, [table[codes]]),
                         strict=True):
        np.testing.assert_array_equal(got, want)
    mip = pyramids.levels_plan((13, 17), 4, "quadratic")  # resampling passes read the table too
    for got, want in zip(ex.run_outputs(mip, [codes], codes=table), ex.run_outputs(mip, [table[codes]]),
                         strict=True):
        np.testing.assert_array_equal(got, want)
    assert ex._table is None  # the run's table is forgotten after it
    with pytest.raises(ValueError, match="code 0"):
        ex.run_outputs(p, [codes], codes=table + 1)


def test_numba_s_version_is_read_without_importing_it_or_its_metadata(tmp_path, monkeypatch):
    """The version file in numba's folder, as installed (``importlib.metadata`` took 25–30 ms a run); where there
    is none, the metadata; where numba is not installed, "?"."""
    import importlib.util
    import subprocess
    import sys
    from importlib import metadata
    from types import SimpleNamespace

    from pyramid_cli.exec.cpu import executor

    code = ("import sys; from pyramid_cli.exec.cpu.executor import numba_version; v = numba_version(); "
            "print(v, 'numba' in sys.modules, 'importlib.metadata' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == [metadata.version("numba"), "False", "False"]

    monkeypatch.delitem(sys.modules, "numba", raising=False)
    try:
        executor.numba_version.cache_clear()  # once a process
        monkeypatch.setattr(importlib.util, "find_spec", lambda name: SimpleNamespace(origin=str(tmp_path / "x.py")))
        assert executor.numba_version() == metadata.version("numba")  # no version file there: the metadata
        executor.numba_version.cache_clear()
        monkeypatch.setattr(importlib.util, "find_spec", lambda name: None)
        assert executor.numba_version() == "?"
    finally:
        executor.numba_version.cache_clear()


def test_the_8bit_encoding_loop_gives_numpys_srgb8_codes(ex, monkeypatch):
    """The compiled 8-bit encoding (``encode8``, over image I/O's 16-bit buckets) against numpy's srgb8 lookups:
    every code boundary ±2 ulps of both signs, every 4099th bit pattern of all 2^32 (every exponent, the NaNs),
    +inf and the NaNs of its bucket; the elements outside ``[i0, i1)`` untouched. (All 2^32 patterns were compared
    once by hand: none differs.)"""
    from pyramid_cli.imageio import colour

    thresholds, _ = colour.srgb8_tables()
    t = thresholds.view(np.uint32).astype(np.int64)
    edges = np.concatenate([t + d for d in (-2, -1, 0, 1, 2)]).astype(np.uint32)
    sweep = np.arange(0, 1 << 32, 4099, dtype=np.uint64).astype(np.uint32)
    special = np.array([0x7F800000, 0x7F800001, 0x7F80FFFF, 0x7F810000, 0x7FC00000, 0xFF800000, 0xFFC00000,
                        0x80000000, 0x00000001, 0x7F7FFFFF], np.uint32)
    bits = np.concatenate([edges, edges | np.uint32(1 << 31), sweep, special])
    x = bits.view(np.float32)
    monkeypatch.setattr(colour, "_LOOP", [])  # numpy's route, even where a CPU run gave srgb8 the loop already
    want = colour.srgb8(x)
    out = np.full(x.size, 7, np.uint8)
    ex.encode8()(out, x, bits, *colour.srgb8_buckets(), 3, x.size - 2)
    np.testing.assert_array_equal(out[3:-2], want[3:-2])
    assert (out[:3] == 7).all() and (out[-2:] == 7).all()
