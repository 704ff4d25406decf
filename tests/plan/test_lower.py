"""The planner: exact against the reference through the plan emulator, and the paper's fetch counts."""

import json
from fractions import Fraction

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.cases import CHAINS, NAMED, SHAPES
from helpers.marks import slow_beyond
from helpers.paths import ROOT
from pyramid_cli.cli import main
from pyramid_cli.core import catalogue
from pyramid_cli.core.expr import Named, Op
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import check, cost, estimate_seconds, plan, recipe, recipe_kernel_matches, taps_for
from pyramid_cli.reference import filters as reference


@pytest.mark.parametrize("strategy", slow_beyond(["cost", "paper"]))
@pytest.mark.parametrize("text", slow_beyond(NAMED + CHAINS, 12))
def test_emulated_plan_equals_reference_everywhere(text, strategy):
    expr = parse(text)
    rng = np.random.default_rng(abs(hash(text)) % 2 ** 32)
    for shape in SHAPES:
        g = rng.random(shape + (2,))
        p = plan(expr, shape, strategy)
        check(p)
        want = reference.run(expr, g)
        got = emulate.run(p, g)
        assert got.shape == want.shape, shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=f"{text} at {shape}")


@pytest.mark.parametrize("text", slow_beyond(NAMED + CHAINS, 12))
def test_every_tap_sits_on_a_quarter_texel(text):
    """GPU filtering quantises bilinear weights to 8 bits: quarter positions are exact."""
    p = plan(parse(text), (33, 21))
    for ps in p.passes:
        for taps in ps.phases.values():
            for t in taps:
                for o in t.offset:
                    assert (o * 4).denominator == 1, (text, t)
                    if not t.linear:
                        assert o.denominator == 1


PAPER = {"box * g": 1, "box^nw * g": 1, "bartlett": 2, "gauss5": 4, "gauss7": 6, "quasi": 3, "box *v g": 1,
         "box4 *v g": 2, "quadratic *v g": 3, "cubic *v g": 4, "midpoint": 1, "doosabin": 1, "cubic *^ g": 2,
         "fourpoint": 4.5, "nearest": 1}


@pytest.mark.parametrize("size", slow_beyond([(1, 1), (16, 16), (256, 256), (1080, 1920)], 2))
@pytest.mark.parametrize("text, count", PAPER.items())
def test_fetches_match_or_beat_the_paper(text, count, size):
    p = plan(parse(text), size, "paper")
    assert p.paper_fetches == count  # the catalogue records the paper's count
    assert p.fetches <= count
    # the cost model never makes its own estimate worse than the paper's decomposition
    assert estimate_seconds(plan(parse(text), size)) <= estimate_seconds(p)


def test_cost_model_fuses_quadratic_and_says_why():
    p = plan(parse("quadratic *v g"), (1080, 1920))
    assert len(p.passes) == 1 and p.fetches == 4 and p.fetches_per_output_pixel == 4
    why = p.passes[0].why
    assert why.startswith("one fused pass: ") and "for the paper's 3 passes" in why and "\n" not in why
    assert cost.model().name in why and why.count(" ms") + why.count(" µs") == 2


@pytest.mark.parametrize("key", ["bartlett", "gauss5", "gauss7", "gauss9", "quasi"])
def test_convolution_recipes_reproduce_their_masks(key):
    f = Named(key)
    assert recipe_kernel_matches(recipe(Op.CONV, f), Op.CONV, f)


@pytest.mark.parametrize("key", ["box", "box_nw", "bartlett", "box4", "quadratic", "cubic", "gauss5"])
def test_analysis_recipes_reproduce_their_masks(key):
    f = Named(key)
    assert recipe_kernel_matches(recipe(Op.DOWN, f), Op.DOWN, f)


@pytest.mark.parametrize("key", catalogue.synthesis_keys())
def test_synthesis_recipes_reproduce_their_masks(key):
    f = Named(key)
    assert recipe_kernel_matches(recipe(Op.UP, f), Op.UP, f)


def test_wrong_arrow_recipe_is_rejected():
    """The check really compares: the paper's printed box4 recipe (box↘ twice) fails it."""
    from pyramid_cli.core.algebra import mask_weights
    from pyramid_cli.plan import chain, conv, down

    box = mask_weights(catalogue.mask("box").mask)
    f = Named("box4")
    assert not recipe_kernel_matches(chain(down(box), conv(box)), Op.DOWN, f)


def test_tap_fitting_pairs_bilinear_weights_and_keeps_the_rest_nearest():
    w = {(0, 0): Fraction(3, 8), (0, 1): Fraction(1, 8), (2, 2): Fraction(-1, 2)}
    taps = taps_for(w, 0)
    assert len(taps) == 2
    lin = [t for t in taps if t.linear][0]
    assert lin.offset == (0, Fraction(1, 4)) and lin.weight == Fraction(1, 2)
    near = [t for t in taps if not t.linear][0]
    assert near.offset == (2, 2) and near.weight == Fraction(-1, 2)


def test_guard_band_keeps_row_zero_of_box4():
    p = plan(parse("box4 *v g"), (8, 8), "paper")
    assert p.images[1].guard == [1, 1, 0, 0]  # §4.2: the 0-th row and column are stored
    assert p.images[-1].guard == [0, 0, 0, 0]


def test_written_operators_share_no_guard():
    p = plan(parse("box\\ * (box\\ * g)"), (8, 8))
    assert all(img.guard == [0, 0, 0, 0] for img in p.images)


def test_fetches_per_output_pixel_weighs_pass_sizes():
    p = plan(parse("quadratic *v g"), (256, 256), "paper")
    # two full-resolution passes (+guard) and one at the output size
    assert p.fetches == 3
    assert 8.9 < p.fetches_per_output_pixel < 9.2


def test_plan_cli_json_schema():
    r = CliRunner().invoke(main, ["plan", "--json", "doosabin", "--size", "5x3"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["fetches"] == 1 and d["paper_fetches"] == 1 and d["output"] == [10, 6]
    (only,) = d["passes"]
    assert only["size"] == [10, 6] and only["guard"] == [0, 0, 0, 0]
    phases = {tuple(ph["phase"]): ph["taps"] for ph in only["phases"]}
    assert set(phases) == {(1, 1), (1, 0), (0, 1), (0, 0)}
    # h^{1,1} = 1/16 [9 3; 3 1] on g[R], g[R−1]: one bilinear tap a quarter texel up-left
    assert phases[(1, 1)] == [{"pos": [-0.25, -0.25], "weight": 1.0, "exact": "1", "sampler": "linear",
                               "source": 0}]


def test_plan_cli_report_and_bad_size():
    r = CliRunner().invoke(main, ["plan", "--strategy", "paper", "quadratic", "--size", "13x17"])
    assert r.exit_code == 0 and "fetches 3 (paper: 3)" in r.output
    r = CliRunner().invoke(main, ["plan", "quadratic", "--size", "13x17"])
    assert r.exit_code == 0 and "chosen: one fused pass" in r.output and "fetches 4 (paper: 3)" in r.output
    r = CliRunner().invoke(main, ["plan", "quadratic", "--size", "13"])
    assert r.exit_code == 2 and "WIDTHxHEIGHT" in r.output


@pytest.mark.slow
def test_readme_fetch_table_is_generated_and_current():
    import subprocess
    import sys

    script = ROOT / "scripts" / "fetch_table.py"
    r = subprocess.run([sys.executable, str(script), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_the_report_names_each_input_and_the_pass_that_writes_each_image():
    """Several inputs (a fill: colours and weights): sources are named ``input k`` or their writing pass."""
    from pyramid_cli.jobs.work import Fill
    from pyramid_cli.plan.report import render

    p = Fill(levels=2).plan(((5, 7), (5, 7)))
    lines = render(p).splitlines()
    passes = {int(line.split()[1]): line for line in lines if line.startswith("pass ")}
    for n, ps in enumerate(p.passes, 1):
        for s in ps.sources():
            name = (f"input {p.inputs.index(s) + 1}" if s in p.inputs
                    else f"pass {next(k for k, q in enumerate(p.passes, 1) if q.target == s)}")
            assert name in passes[n], (n, s, passes[n])
    assert "reads input 2" in passes[1] and "reads input 1" in passes[2]
