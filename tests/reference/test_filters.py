"""Properties of the reference executor, and its agreement with the exact algebra."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.marks import slow_beyond
from helpers.oracles import apply_kernel
from pyramid_cli.core import algebra
from pyramid_cli.core.border import Border
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference

ANALYSIS = ["box", "box^nw", "bartlett", "gauss5", "box4", "quadratic", "cubic"]
SYNTHESIS = ["nearest", "midpoint", "doosabin", "cubic", "fourpoint"]
BASIC = ["box", "box^nw", "bartlett", "gauss5", "gauss7", "quasi"]

sizes = st.sampled_from([1, 2, 3, 5, 7, 8, 11, 13, 16])
shapes = st.tuples(sizes, sizes)
channels = st.sampled_from([None, 1, 3, 4, 5])


def image(shape, ch, seed=0):
    rng = np.random.default_rng(seed)
    return rng.random(shape if ch is None else shape + (ch,))


@settings(max_examples=60, deadline=None)
@given(shape=shapes, name=st.sampled_from(ANALYSIS), value=st.floats(-10, 10), ch=channels)
def test_analysis_preserves_constants_and_halves_sizes(shape, name, value, ch):
    g = np.full(shape if ch is None else shape + (ch,), value)
    f = reference.run(parse(f"{name} *v g"), g)
    assert f.shape[:2] == (-(-shape[0] // 2), -(-shape[1] // 2))
    assert f.shape[2:] == g.shape[2:]
    np.testing.assert_allclose(f, value, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(shape=shapes, name=st.sampled_from(SYNTHESIS), value=st.floats(-10, 10), ch=channels)
def test_synthesis_preserves_constants_and_doubles_sizes(shape, name, value, ch):
    g = np.full(shape if ch is None else shape + (ch,), value)
    f = reference.run(parse(f"{name} *^ g"), g)
    assert f.shape[:2] == (2 * shape[0], 2 * shape[1])
    np.testing.assert_allclose(f, value, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(shape=shapes, seed=st.integers(0, 1000))
def test_fourpoint_and_midpoint_interpolate(shape, seed):
    g = image(shape, None, seed)
    for name in ("fourpoint", "midpoint"):
        f = reference.run(parse(f"{name} *^ g"), g)
        np.testing.assert_array_equal(f[1::2, 1::2], g)  # even 1-based indices copy the old pixel


@settings(max_examples=40, deadline=None)
@given(shape=shapes, m=st.integers(1, 3))
def test_stride_output_size(shape, m):
    f = reference.run(parse(f"box *v^{m} g"), np.zeros(shape))
    assert f.shape == (-(-shape[0] // 2 ** m), -(-shape[1] // 2 ** m))


@settings(max_examples=80, deadline=None)
@given(shape=shapes, seed=st.integers(0, 1000),
       text=st.sampled_from([f"{n} *v g" for n in ANALYSIS] + [f"{n} *^ g" for n in SYNTHESIS]
                            + [f"{n} * g" for n in BASIC] + ["box *v^2 g", "bartlett *v^3 g",
                                                              "1/8 [1 2 1; 0 2 0; 1 0 1] *v g"]))
def test_single_step_agrees_with_the_algebra_everywhere(shape, seed, text):
    """One named filter is atomic: its exact kernel, clamped, is the reference at every pixel."""
    expr = parse(text)
    g = image(shape, 2, seed)
    want = reference.run(expr, g)
    got = apply_kernel(algebra.kernel(expr), g, want.shape[:2])
    np.testing.assert_allclose(got, want, atol=1e-12)


CHAINS = ["bartlett * (bartlett * g)", "(box4)^2 *v g", "doosabin *^ (box4 *v g)", "box\\ * (doosabin *^ g)",
          "quadratic *v (quasi * g)", "(doosabin)^2 *^ ((box4)^2 *v g)", "fourpoint *^ (cubic *v g)",
          "box *v (midpoint *^ g)"]


@pytest.mark.parametrize("text", slow_beyond(CHAINS, 3))
def test_chains_agree_with_the_algebra_in_the_interior(text):
    expr = parse(text)
    g = image((37, 41), None, 5)
    want = reference.run(expr, g)
    k = algebra.kernel(expr)
    got = apply_kernel(k, g, want.shape[:2])
    assert want.shape == algebra.output_size(expr, g.shape)
    # the interior: output pixels whose whole chain reads only pixels inside the input
    margin = 12
    rate = k.rate
    rows = [r for r in range(want.shape[0]) if margin < (r + 1) * rate[0] < g.shape[0] - margin]
    cols = [c for c in range(want.shape[1]) if margin < (c + 1) * rate[1] < g.shape[1] - margin]
    assert rows and cols
    np.testing.assert_allclose(got[np.ix_(rows, cols)], want[np.ix_(rows, cols)], atol=1e-12)


def test_written_operators_clamp_in_between():
    """bartlett ⊗ (bartlett ⊗ g) differs from gauss5 ⊗ g in the outermost pixels only (docs/design.md §1)."""
    g = image((9, 9), None, 1)
    two = reference.run(parse("bartlett * (bartlett * g)"), g)
    one = reference.run(parse("gauss5"), g)
    np.testing.assert_allclose(two[1:-1, 1:-1], one[1:-1, 1:-1], atol=1e-12)
    assert not np.allclose(two[0], one[0])


def test_box_se_shifts_toward_down_right():
    """box↘ ⊗ g averages a pixel with its upper-left neighbours: the result moves down-right."""
    g = np.zeros((4, 4))
    g[1, 1] = 1
    f = reference.run(parse("box\\ * g"), g)
    assert f[1, 1] == f[1, 2] == f[2, 1] == f[2, 2] == 0.25 and f.sum() == 1


@pytest.mark.parametrize("border, expected", [
    (Border.CLAMP, [1, 1, 1, 2, 3]), (Border.MIRROR, [2, 1, 1, 2, 3]),
    (Border.WRAP, [2, 3, 1, 2, 3]), (Border.ZERO, [0, 0, 1, 2, 3]),
])
def test_border_modes_read_outside_the_image(border, expected):
    """Column 1 of a one-hot 1×5 mask at offset d reads g[1 − d]: indices −1, 0, 1, 2, 3."""
    g = np.array([[1.0, 2.0, 3.0]])
    got = []
    for d in (2, 1, 0, -1, -2):
        mask = ((tuple(1.0 if j == d + 2 else 0.0 for j in range(5))),)
        got.append(reference.convolve(mask, g, border)[0, 0])
    assert got == expected
