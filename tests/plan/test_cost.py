"""The calibrated cost model (pyramid_cli/plan/cost.py): the committed constants, the size-dependent
choice it drives, exactness on both sides of every flip, and why the planner never fuses
written steps (docs/design.md §1, §5)."""

import datetime
import json
import sys
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from helpers.marks import slow_beyond
from helpers.paths import ROOT
from pyramid_cli import plan as planner
from pyramid_cli.cli import main
from pyramid_cli.core import algebra
from pyramid_cli.core.expr import Named, Op
from pyramid_cli.core.parse import parse
from pyramid_cli.exec import emulate
from pyramid_cli.plan import cost
from pyramid_cli.reference import filters as reference

# Named filters the planner chooses for: the paper's decomposition has several passes.
CHOICES = [(Op.CONV, "bartlett"), (Op.CONV, "gauss5"), (Op.CONV, "gauss7"), (Op.CONV, "quasi"),
           (Op.DOWN, "box4"), (Op.DOWN, "quadratic"), (Op.DOWN, "cubic"), (Op.DOWN, "bartlett"),
           (Op.DOWN, "gauss5"), (Op.UP, "cubic"), (Op.UP, "fourpoint")]
TEXT = {Op.CONV: "{} * g", Op.DOWN: "{} *v g", Op.UP: "{} *^ g"}


@pytest.fixture
def use_model(monkeypatch):
    """Plan with a given model instead of the committed one (caches cleared before and after)."""
    def use(model: cost.CostModel) -> None:
        monkeypatch.setattr(cost, "model", lambda: model)
        planner.choose_recipe.cache_clear()
        planner.plan.cache_clear()

    yield use
    planner.choose_recipe.cache_clear()
    planner.plan.cache_clear()


# ------------------------------------------------------------------ the committed file
def test_committed_model_has_every_field_and_sane_constants():
    d = cost.load_dict()
    assert set(cost.FIELDS) <= set(d), set(cost.FIELDS) - set(d)
    m = cost.model()
    assert m.pass_s > 0 and all(c >= 0 for c in m.constants)
    assert m.fetch_linear_s > 0 and m.fetch_nearest_s > 0 and m.pixel_s > 0
    # an empty pass costs microseconds to milliseconds on any GL, a pixel nanoseconds at most
    assert 1e-7 < m.pass_s < 1e-2 and m.pixel_s < 1e-6
    assert d["renderer"] and m.renderer == d["renderer"] and "(" in m.name
    datetime.date.fromisoformat(d["date"])
    assert "bench/calibrate.py" in d["command"] and "--write" in d["command"]
    assert 0 < d["residual"]["rms_relative"] < 1 and d["samples"] >= 20
    assert d["fetch_costs_merged"] == (m.fetch_linear_s == m.fetch_nearest_s)


def test_model_is_loaded_once_and_shipped_as_package_data():
    assert cost.model() is cost.model()
    if sys.version_info >= (3, 11):
        import tomllib

        setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
        assert "pyramid_cli.plan" in setup["packages"]
        assert cost.MODEL_FILE in setup["package-data"]["pyramid_cli.plan"]


@pytest.mark.parametrize("change, message", [
    (lambda d: d.pop("renderer"), "lacks renderer"),
    (lambda d: d.pop("residual"), "lacks residual"),
    (lambda d: d.update(fetch_linear_s=-1e-9), "non-negative"),
    (lambda d: d.update(pass_s=0), "pass_s positive"),
])
def test_a_broken_model_file_is_refused(change, message):
    d = json.loads(json.dumps(cost.load_dict()))
    change(d)
    with pytest.raises(ValueError, match=message):
        cost.from_dict(d)


def test_executed_fetches_mean_for_phase_tables_sum_for_branches():
    lin = [(0, True)]
    assert cost.executed_fetches([lin]) == (1, 0)
    assert cost.executed_fetches([lin * 2] * 4) == (2, 0)            # same layout: one phase runs
    assert cost.executed_fetches([lin, lin, lin, lin * 2]) == (5, 0)  # branches: SIMD runs them all
    assert cost.executed_fetches([[(0, False)], lin]) == (1, 1)      # two kinds branch too


def test_pass_seconds_is_the_documented_formula():
    m = cost.CostModel(1.0, 0.5, 0.01, 0.002, 0.001, 0.0001)
    assert m.pass_seconds(taps=3, size=(10, 10), linear=2, nearest=1, read=400) == pytest.approx(
        1.0 + 3 * 0.5 + 100 * (0.01 + 2 * 0.002 + 1 * 0.001) + 400 * 0.0001)
    # tiles of 64² on 4 workers: a 100×100 target has 4 tiles (all busy), a 64×64 one leaves 3 idle
    tiled = replace(m, tile=64, threads=4)
    assert tiled.share((100, 100)) == 1 and tiled.share((64, 64)) == 4 and tiled.share((64, 65)) == 2
    per_pixel = m.pass_seconds(3, (64, 64), 2, 1, 400) - 2.5
    assert tiled.pass_seconds(3, (64, 64), 2, 1, 400) - 2.5 == pytest.approx(4 * per_pixel)


# ------------------------------------------------------------------ the choice follows the model
def box4_seconds(m: cost.CostModel, n: int) -> tuple[float, float]:
    """box4 ⊗↓ on an n×n input from the model's constants (paper §4.2): the paper's box↖ ⊗↓ pass
    (one bilinear tap, output ⌈n/2⌉ plus a stored row and column 0) then box↘ ⊗ (one tap), against
    one fused pass of four bilinear taps at the output size; per-pixel work weighed by the share
    of idle workers on small targets."""
    k = -(-n // 2)
    a, b = m.share((k + 1, k + 1)), m.share((k, k))
    paper = (2 * m.pass_s + 2 * m.shader_tap_s
             + a * (k + 1) ** 2 * (m.pixel_s + m.fetch_linear_s) + b * k * k * (m.pixel_s + m.fetch_linear_s)
             + a * n * n * m.source_pixel_s + b * (k + 1) ** 2 * m.source_pixel_s)
    fused = (m.pass_s + 4 * m.shader_tap_s + b * k * k * (m.pixel_s + 4 * m.fetch_linear_s)
             + b * n * n * m.source_pixel_s)
    return paper, fused


def chosen_passes(op: Op, key: str, size: tuple[int, int]) -> int:
    return len(planner.plan(parse(TEXT[op].format(key)), size).passes)


def box4_flips(m: cost.CostModel, largest: int = 4200) -> list[int]:
    """Input sizes n where the closed form's choice differs from the one at n − 1."""
    fused = [box4_seconds(m, n)[1] < box4_seconds(m, n)[0] for n in range(1, largest + 1)]
    return [n for n in range(2, largest + 1) if fused[n - 1] != fused[n - 2]]


def check_box4_follows(m: cost.CostModel) -> list[int]:
    """The planner picks what the closed form says, at sampled sizes and on both sides of every
    flip; returns the flips."""
    flips = box4_flips(m)
    for n in sorted(set(range(1, 40)) | set(range(40, 4200, 97)) | {s for f in flips for s in (f - 1, f)}):
        paper, fused = box4_seconds(m, n)
        assert chosen_passes(Op.DOWN, "box4", (n, n)) == (1 if fused < paper else 2), (n, paper, fused)
    return flips


def test_box4_choice_follows_the_committed_model_at_every_size():
    check_box4_follows(cost.model())


def test_tiny_levels_fuse_and_large_ones_keep_the_paper_when_the_model_says_so(use_model):
    """A model where a pass costs 100 µs and a bilinear fetch 3 ns per pixel: box4 ⊗↓ fuses its two
    passes on small levels and keeps them on large ones, flipping once, where the closed form does."""
    m = cost.CostModel(pass_s=1e-4, shader_tap_s=1e-5, pixel_s=4e-9, fetch_linear_s=3e-9,
                       fetch_nearest_s=2e-9, source_pixel_s=0.0, renderer="test")
    use_model(m)
    flips = check_box4_follows(m)
    assert len(flips) == 1 and 16 < flips[0] < 2160
    assert chosen_passes(Op.DOWN, "box4", (16, 16)) == 1 and chosen_passes(Op.DOWN, "box4", (2160, 3840)) == 2
    # and the report says why, with both estimates
    why = planner.plan(parse("box4 *v g"), (2160, 3840)).passes[0].why
    paper = planner.recipe_seconds(planner.checked_recipe(Op.DOWN, Named("box4")), (2160, 3840), m)
    fused = planner.recipe_seconds(planner.direct_recipe(Op.DOWN, Named("box4")), (2160, 3840), m)
    assert why == (f"paper's 2 passes: {cost.format_seconds(paper)} ≤ {cost.format_seconds(fused)} "
                   f"for one fused pass (cost model: test)")


def test_the_choice_flips_back_when_passes_cost_nothing(use_model):
    free = cost.CostModel(pass_s=1e-12, shader_tap_s=0.0, pixel_s=1e-9, fetch_linear_s=3e-9,
                          fetch_nearest_s=3e-9, source_pixel_s=0.0)
    use_model(free)
    assert chosen_passes(Op.DOWN, "box4", (64, 64)) == 2  # 2 fetches beat 4 when passes are free
    use_model(replace(free, pass_s=1.0))
    assert chosen_passes(Op.DOWN, "box4", (2160, 3840)) == 1  # a second of overhead: always fuse
    assert chosen_passes(Op.CONV, "gauss7", (2160, 3840)) == 1


def test_strategy_paper_always_keeps_the_paper(use_model):
    use_model(cost.CostModel(pass_s=1.0, shader_tap_s=0.0, pixel_s=0.0, fetch_linear_s=0.0,
                             fetch_nearest_s=0.0, source_pixel_s=0.0))
    for op, key in CHOICES:
        p = planner.plan(parse(TEXT[op].format(key)), (16, 16), "paper")
        assert len(p.passes) == len(planner.checked_recipe(op, Named(key))) > 1
        assert not any(ps.why for ps in p.passes)


def test_plan_json_and_report_show_the_estimate():
    r = CliRunner().invoke(main, ["plan", "--json", "box4 *v g", "--size", "33x17"])
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["estimate_s"] == pytest.approx(sum(ps["estimate_s"] for ps in d["passes"]))
    assert d["estimate_s"] == pytest.approx(planner.estimate_seconds(planner.plan(parse("box4 *v g"), (17, 33))))
    assert d["cost_model"] == cost.model().name and "why" in d["passes"][0]
    r = CliRunner().invoke(main, ["plan", "gauss5", "--size", "3000x2000"])
    assert r.exit_code == 0, r.output
    assert "chosen: paper's 4 passes: " in r.output or "chosen: one fused pass: " in r.output
    assert "\nestimate " in r.output and cost.model().name in r.output.splitlines()[-1]


# ------------------------------------------------------------------ exact on both sides of every flip
SQUARES = [1, 2, 3, 4, 6, 9, 14, 21, 32, 47, 70, 105, 158, 237, 356]


def sides(op: Op, key: str) -> list[tuple[int, int]]:
    """Shapes around each flip of the model's choice: squares, odd rectangles, 1×N and N×1."""
    f = Named(key)
    out = []
    for family in (lambda n: (n, n), lambda n: (n | 1, (n + 2) | 1), lambda n: (1, 4 * n), lambda n: (4 * n, 1)):
        shapes = [family(n) for n in SQUARES]
        fused = [len(planner.choose_recipe(op, f, 1, s)[0]) == 1 for s in shapes]
        keep = {0, len(shapes) - 1}
        keep |= {i for i in range(1, len(shapes)) if fused[i] != fused[i - 1]}
        keep |= {i - 1 for i in range(1, len(shapes)) if fused[i] != fused[i - 1]}
        out += [shapes[i] for i in sorted(keep)]
    return out


@pytest.mark.parametrize("op, key", slow_beyond(CHOICES, 1, unpack=True),
                         ids=lambda x: x.value if isinstance(x, Op) else x)
def test_chosen_plans_equal_the_reference_on_both_sides_of_the_flip(op, key):
    expr = parse(TEXT[op].format(key))
    rng = np.random.default_rng(len(key))
    seen = set()
    for shape in sides(op, key):
        p = planner.plan(expr, shape)
        planner.check(p)
        seen.add(len(p.passes) == 1)
        g = rng.random(shape + (2,))
        np.testing.assert_allclose(emulate.run(p, g), reference.run(expr, g), rtol=0, atol=1e-12,
                                   err_msg=f"{key} {op.unicode} at {shape}, {len(p.passes)} pass(es)")
    # the shapes include the fused choice wherever the model ever makes it
    if any(len(planner.choose_recipe(op, Named(key), 1, (n, n))[0]) == 1 for n in SQUARES):
        assert True in seen


def test_fused_choices_are_exercised_at_small_odd_and_one_pixel_wide_sizes():
    """With the committed model, the small shapes the other suites use do plan fused passes,
    so their GL and emulator checks cover both recipes."""
    fused = {(op, key) for op, key in CHOICES for shape in [(1, 7), (5, 3), (17, 13)]
             if len(planner.choose_recipe(op, Named(key), 1, shape)[0]) == 1}
    assert len(fused) >= 3, fused


# ------------------------------------------------------------------ no fusion across written steps
def composed_pass_plan(text: str, size: tuple[int, int]) -> planner.Plan:
    """One pass with the equivalent kernel of all the chain's written steps (what 'fusing the
    small-level tail' across steps would run)."""
    kernel = algebra.kernel(parse(text))
    assert kernel.period == (1, 1) and kernel.stride[0] == kernel.stride[1]
    b = planner.Builder(size)
    b.add_stages(0, [planner.down(dict(kernel.phases[(0, 0)]), kernel.stride[0].bit_length() - 1)], "composed")
    return b.build(text)


@pytest.mark.parametrize("text", ["(box4)^2 *v g", "box4 *v (box4 *v (box4 *v g))", "quadratic *v (box4 *v g)"])
def test_fusing_written_steps_is_wrong_at_the_border(text):
    """Each written operator clamps at its own input's border (docs/design.md §1), so the composed kernel
    of two ⊗↓ steps, clamped once at the input, differs from the chain there: the planner fuses
    within a named filter (guard bands keep it exact) and never across written steps."""
    size = (97, 75)
    g = np.random.default_rng(3).random(size)
    want = reference.run(parse(text), g)
    got = emulate.run(composed_pass_plan(text, size), g)
    assert got.shape == want.shape
    err = np.abs(got - want)
    assert err[0, 0] > 1e-3 or err[0].max() > 1e-3       # wrong at the top border ...
    assert err[2:-2, 2:-2].max() < 1e-12                  # ... and exact inside: the kernel itself is right
    # the planner itself keeps the steps apart and is exact everywhere
    np.testing.assert_allclose(emulate.run(planner.plan(parse(text), size), g), want, rtol=0, atol=1e-12)


def test_recipe_estimates_count_guard_bands():
    """The box↖ ⊗↓ pass of box4 stores row and column 0 (§4.2): the estimate weighs the stored extent."""
    m = cost.CostModel(pass_s=1e-12, shader_tap_s=0.0, pixel_s=1.0, fetch_linear_s=0.0, fetch_nearest_s=0.0,
                       source_pixel_s=0.0)
    paper = planner.checked_recipe(Op.DOWN, Named("box4"))
    assert planner.recipe_seconds(paper, (8, 8), m) == pytest.approx(5 * 5 + 4 * 4)
