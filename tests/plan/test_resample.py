"""Domain-true MIP levels: the ResamplePass, its exact weights and every executor against the float64 reference.

The weights come from the analysis filter's continuous kernel (:mod:`pyramid_cli.plan.resample`); the
reference (:func:`pyramid_cli.reference.mip.mip_reference`) integrates the same kernel in float64 from the paper's
masks, without the planner. Every executor runs the plan and is held to the reference at every pixel.
"""

from __future__ import annotations

import json
from fractions import Fraction

import numpy as np
import pytest
from click.testing import CliRunner

import pyramid_cli as pyr
from helpers.marks import slow_beyond
from helpers.oracles import as_1d, paper_weights
from pyramid_cli.cli import main
from pyramid_cli.core import catalogue
from pyramid_cli.core.geometry import mip_sizes
from pyramid_cli.exec import emulate
from pyramid_cli.plan import Pass, ResamplePass, check
from pyramid_cli.plan.resample import axis_table, column_sums, dense
from pyramid_cli.reference.mip import mip_reference
from pyramid_cli.workflows.pyramids import mip_axis_weights, mip_plan

BORDERS = ["clamp", "mirror", "wrap", "zero"]
SYMMETRIC = ["box", "box4", "quadratic"]  # the dual-lattice filters: symmetric about the coarse pixel's centre
SIZES = [(37, 23), (3, 5), (1, 7), (7, 1), (2, 3), (9, 16)]





# ------------------------------------------------------------------ the weights
@pytest.mark.parametrize("key", catalogue.ANALYSIS_FILTERS)
@pytest.mark.parametrize("m", [1, 2, 5, 8])
def test_an_exact_halving_reproduces_the_papers_weights_as_fractions(key, m):
    w = paper_weights(key)
    assert tuple(sorted(w.items())) == mip_axis_weights(key)[0] == mip_axis_weights(key)[1]
    starts, table = axis_table(as_1d(key), 2 * m, m)
    for j in range(m):  # output r = j + 1 reads 1-based 2r − d, i.e. 0-based 2j + 1 − d
        got = {starts[j] + k: v for k, v in enumerate(table[j]) if v}
        assert got == {2 * j + 1 - d: v for d, v in w.items()}, (key, j)
        assert all(isinstance(v, Fraction) for v in table[j])


def test_the_box_kernel_is_area_resampling():
    starts, table = axis_table(as_1d("box"), 7, 3)
    s = Fraction(7, 3)
    for j in range(3):
        area = {i: (min(Fraction(i + 1), (j + 1) * s) - max(Fraction(i), j * s)) / s for i in range(7)}
        assert {starts[j] + k: v for k, v in enumerate(table[j]) if v} == {i: v for i, v in area.items() if v > 0}


@pytest.mark.parametrize("key", catalogue.ANALYSIS_FILTERS)
@pytest.mark.parametrize("n", [3, 5, 7, 13, 101])
def test_what_the_border_does_to_the_mean(key, n):
    """Every row sums to 1 before folding; after folding, wrap keeps every column at m/n, mirror too for
    symmetric kernels, clamp in the interior (the edge pixel takes what falls past it), zero loses mass."""
    m = max(1, n // 2)
    target = Fraction(m, n)
    starts, table = axis_table(as_1d(key), n, m)
    assert all(sum(row) == 1 for row in table)
    assert column_sums(as_1d(key), n, m, "wrap") == [target] * n
    if key in SYMMETRIC:
        assert column_sums(as_1d(key), n, m, "mirror") == [target] * n
    reach = max(-min(starts), max(s + len(r) for s, r in zip(starts, table, strict=True)) - n) + 1
    clamp = column_sums(as_1d(key), n, m, "clamp")
    assert sum(clamp) == m and clamp[reach:n - reach] == [target] * len(clamp[reach:n - reach])
    zero = dense(starts, table, n, "zero")
    assert all(sum(row) <= 1 for row in zero)
    assert all(c <= target for c in column_sums(as_1d(key), n, m, "zero")[reach:n - reach] or [target])


def _restricted(key, n, m, how):
    """The (m, n) matrix of the kernel restricted to the domain: ``mirror`` folds what falls past an edge back in
    by reflection, ``renormalised`` drops it and scales each row back to 1."""
    starts, table = axis_table(as_1d(key), n, m)
    if how == "mirror":
        return dense(starts, table, n, "mirror")
    return [[v / sum(row) for v in row] for row in dense(starts, table, n, "zero")]


@pytest.mark.parametrize("key", SYMMETRIC)
def test_the_mirror_fold_is_a_domain_restricted_filter_that_keeps_the_mean(key):
    """Issue 26's rule, exact: rows summing to 1 (each level a weighted average of texels inside the domain) do
    not keep the mean; that needs every column at m/n (each texel's total share). Folding by reflection gives
    both at every size of maketx's chain, odd included, and is the filter itself wherever it stays inside."""
    for n in [*range(2, 34), 67, 135]:
        m = n // 2
        target = Fraction(m, n)
        fold = _restricted(key, n, m, "mirror")
        assert all(sum(row) == 1 for row in fold), n
        assert column_sums(as_1d(key), n, m, "mirror") == [target] * n, n
        starts, table = axis_table(as_1d(key), n, m)
        for j, (start, row) in enumerate(zip(starts, table, strict=True)):
            if start >= 0 and start + len(row) <= n:  # reads inside: the filter as it is
                assert fold[j] == [row[i - start] if start <= i < start + len(row) else 0 for i in range(n)]
    # renormalising rows alone moves the mean: 5 → 2 gives the texels 12/35, 3/7, 16/35, 3/7, 12/35 (not 2/5)
    ren = _restricted("quadratic", 5, 2, "renormalised")
    assert [sum(row) for row in ren] == [1, 1]
    assert [ren[0][i] + ren[1][i] for i in range(5)] == [Fraction(12, 35), Fraction(3, 7), Fraction(16, 35),
                                                         Fraction(3, 7), Fraction(12, 35)]


def test_clamp_and_black_build_the_mirror_plan_and_round_up_keeps_its_border():
    """The lookup's border (the file's wrapmodes) is not the one the levels are built with: clamp and zero build
    as mirror does, in the planner and (written apart) in the oracle; --round up pads by the border as before."""
    from pyramid_cli.jobs.texture import TextureLevels
    from pyramid_cli.reference.mip import DOMAIN
    from pyramid_cli.workflows.pyramids import LEVEL_BORDER, level_border

    assert DOMAIN == LEVEL_BORDER and {b: level_border(b) for b in BORDERS} == LEVEL_BORDER
    assert LEVEL_BORDER["clamp"] == LEVEL_BORDER["zero"] == "mirror"
    # clamp keeps its own passes where it folds as mirror does (no read more than one texel past an edge:
    # power-of-two chains of box, box4 and quadratic, --resize's bilinear reads), so those stay bit for bit
    for key, size, resize, alike in [("quadratic", (37, 23), False, False), ("quadratic", (7, 1), False, False),
                                     ("quadratic", (64, 48), False, False), ("cubic", (64, 16), False, False),
                                     ("quadratic", (64, 16), False, True), ("box4", (5, 6), True, True)]:
        mirror = mip_plan(size, key, "mirror", "cost", resize)
        for border in ("clamp", "zero"):
            p = mip_plan(size, key, border, "cost", resize)
            if border == "clamp" and alike:
                assert p.border == "clamp" and p.expression == mirror.expression, (key, size)
                x = np.random.default_rng(2).random(size)
                for a, b in zip(emulate.run_outputs(p, x), emulate.run_outputs(mirror, x), strict=True):
                    np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)  # the same weights
                continue
            assert (p.passes, p.outputs, p.border) == (mirror.passes, mirror.outputs, "mirror"), (key, size, border)
            said = f", built inside the domain (edges folded by mirror; lookups read {border})"
            assert p.expression == mirror.expression + said
    up = {b: TextureLevels(levels=None, border=b, rounding="up").plan([(9, 5)]) for b in ("clamp", "mirror")}
    assert up["clamp"] != up["mirror"]


# ------------------------------------------------------------------ the plan
def test_exact_halvings_run_the_papers_passes_and_others_resample():
    p = mip_plan((64, 48), "quadratic")  # 32×24 16×12 8×6 4×3 halve exactly; 2×1 and 1×1 do not
    assert len(p.outputs) == 6
    for ps in p.passes:
        level = int(ps.label.split()[1])
        assert isinstance(ps, Pass) == (level <= 4), ps.label
    p = mip_plan((37, 50), "quadratic")
    check(p)
    kinds = [(type(ps).__name__, ps.label.split(":")[0]) for ps in p.passes]
    assert kinds[:2] == [("ResamplePass", "level 1 25×18"), ("ResamplePass", "level 1 25×18")]
    assert [p.images[k].size for k in p.outputs] == mip_sizes((37, 50))[1:]
    rows = p.passes[0]
    assert rows.axis == 0 and rows.sources() == {0} and len(rows.starts) == 18
    assert rows.reads((0, 18), (0, 50)) == {0: ((rows.starts[0], rows.starts[-1] + rows.width), (0, 50))}
    assert rows.reads((3, 4), (5, 9))[0][1] == (5, 9)
    assert 5 < rows.fetches <= rows.width


def test_a_one_pixel_axis_is_left_alone():
    p = mip_plan((1, 7), "quadratic")
    assert all(isinstance(ps, ResamplePass) and ps.axis == 1 for ps in p.passes)
    assert [p.images[k].size for k in p.outputs] == [(1, 3), (1, 1)]
    x = np.arange(7.0)[None, :]
    assert [lv.shape for lv in pyr.mipmap(np.ones((1, 1, 3)), backend="reference")] == [(1, 1, 3)]
    np.testing.assert_allclose(emulate.run_outputs(p, x)[-1], mip_reference(x, "quadratic")[-1], atol=1e-12)


def test_pyramid_plan_shows_each_level():
    r = CliRunner().invoke(main, ["plan", "--mipmap", "down", "quadratic *v g", "--size", "13x8"])
    assert r.exit_code == 0, r.output
    assert "level 1 6×4: quadratic kernel resampled, columns 13→6 (×2.167)" in r.output
    assert "level 2 3×2: h_quadratic ⊗↓ (exact halving: the paper's passes)" in r.output
    r = CliRunner().invoke(main, ["plan", "--json", "--mipmap", "down", "box *v g", "--size", "7x1"])
    info = json.loads(r.output)
    first = info["passes"][0]
    assert first["kind"] == "resample" and first["axis"] == "columns" and (first["from"], first["to"]) == (7, 3)
    assert first["weights"][0][:3] == ["3/7", "3/7", "1/7"]


# ------------------------------------------------------------------ executors against the reference
def _cases(sizes, keys=("quadratic", "box")):
    for size in sizes:
        for border in BORDERS:
            for key in keys:
                yield size, border, key


def _check(run, size, border, key, channels, atol):
    x = np.random.default_rng(abs(hash((size, border, key))) % 2 ** 32).random(
        size + ((channels,) if channels else ())).astype(np.float32)
    p = mip_plan(size, key, border)
    check(p)
    got = run(p, x)
    ref = mip_reference(x, key, border)[1:]
    assert [g.shape for g in got] == [r.shape for r in ref]
    for k, (g, r) in enumerate(zip(got, ref, strict=True)):
        np.testing.assert_allclose(g, r, rtol=0, atol=atol, err_msg=f"{size} {border} {key} level {k + 1}")


@pytest.mark.parametrize("size, border, key", slow_beyond(list(_cases(SIZES, catalogue.ANALYSIS_FILTERS)), 16,
                                                          unpack=True))
def test_emulator_equals_reference(size, border, key):
    _check(emulate.run_outputs, size, border, key, 3, 1e-12)


@pytest.mark.parametrize("size, border, key", slow_beyond(list(_cases(SIZES)), 8, unpack=True))
@pytest.mark.parametrize("channels", [None, 4])
def test_cpu_equals_reference(cpu_executor, size, border, key, channels):
    _check(cpu_executor.run_outputs, size, border, key, channels, 2e-6)


@pytest.mark.parametrize("size, border, key", slow_beyond(list(_cases(SIZES[:3])), 8, unpack=True))
def test_gl_equals_reference(gl, size, border, key):
    _check(gl.run_outputs, size, border, key, 6, 2e-6)


@pytest.mark.slow
@pytest.mark.parametrize("border", BORDERS)
def test_cpu_and_gl_equal_reference_at_1001x777(cpu_executor, gl, border):
    _check(cpu_executor.run_outputs, (1001, 777), border, "quadratic", 3, 2e-6)
    _check(gl.run_outputs, (777, 1001), border, "quadratic", 4, 2e-6)


def test_cpu_reads_half_inputs_and_prepares_resampling_kernels(cpu_executor):
    p = mip_plan((9, 5), "quadratic", "mirror")
    cpu_executor.prepare(p, np.float16)
    assert cpu_executor.uncached(p) == 0
    x = np.random.default_rng(1).random((9, 5, 3)).astype(np.float16)
    got = cpu_executor.run_outputs(p, x)
    for g, r in zip(got, mip_reference(x.astype(np.float64), "quadratic", "mirror")[1:], strict=True):
        np.testing.assert_allclose(g, r, atol=2e-6)


# ------------------------------------------------------------------ --resize (level 0 up to powers of two)
def test_bilinear_table_reads_at_the_new_texel_centres():
    from pyramid_cli.plan.resample import bilinear_table

    assert bilinear_table(5, 5) == (tuple(range(5)), tuple((Fraction(1), Fraction(0)) for _ in range(5)))
    starts, table = bilinear_table(3, 4)  # centres at (j + ½)·¾ − ½ = −1/8, 5/8, 11/8, 17/8
    assert starts == (-1, 0, 1, 2)
    assert table == ((Fraction(1, 8), Fraction(7, 8)), (Fraction(3, 8), Fraction(5, 8)),
                     (Fraction(5, 8), Fraction(3, 8)), (Fraction(7, 8), Fraction(1, 8)))


@pytest.mark.parametrize("size", [(5, 7), (3, 1), (8, 6), (1, 1)])
@pytest.mark.parametrize("border", BORDERS)
def test_resize_on_every_executor_equals_the_reference(cpu_executor, gl, size, border):
    x = np.random.default_rng(3).random(size + (3,)).astype(np.float32)
    p = mip_plan(size, "quadratic", border, "cost", True)
    check(p)
    ref = mip_reference(x, "quadratic", border, resize=True)
    assert [p.images[k].size for k in p.outputs] == [r.shape[:2] for r in ref]
    for name, run in [("emulator", emulate.run_outputs), ("cpu", cpu_executor.run_outputs), ("gl", gl.run_outputs)]:
        for k, (g, r) in enumerate(zip(run(p, x), ref, strict=True)):
            np.testing.assert_allclose(g, r, atol=2e-6, err_msg=f"{name} level {k}")
