"""Every matrix and decomposition printed in the paper, derived by the algebra.

Expected values are the paper's printed matrices, read with the paper's index
formula (tests/oracles.py); the algebra derives the left-hand sides from the
decompositions, never from a copy of the answer.
"""

from fractions import Fraction

import numpy as np
import pytest

from helpers.marks import slow_beyond
from helpers.oracles import extended_chain, printed, printed_outer
from pyramid_cli.core import algebra, catalogue
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference


def kernel_weights(text):
    k = algebra.kernel(parse(text))
    assert k.period == (1, 1)
    return k.stride, k.phases[(0, 0)]


def test_bartlett_is_box_se_times_box_nw_both_orders():
    bartlett = printed([[1, 2, 1], [2, 4, 2], [1, 2, 1]], Fraction(1, 16))
    assert kernel_weights("box\\ * (box^nw * g)") == ((1, 1), bartlett)
    assert kernel_weights("box^nw * (box\\ * g)") == ((1, 1), bartlett)
    assert algebra.mask_weights(catalogue.mask("bartlett").mask) == bartlett


def test_same_arrow_twice_shifts_by_a_full_pixel():
    _, w = kernel_weights("box\\ * (box\\ * g)")
    centroid = sum(v * d[0] for d, v in w.items())
    assert centroid == 1  # §3.2: "shifted by one full pixel position"


GAUSS5 = [[1, 4, 6, 4, 1], [4, 16, 24, 16, 4], [6, 24, 36, 24, 6], [4, 16, 24, 16, 4], [1, 4, 6, 4, 1]]
GAUSS7 = [[1, 6, 15, 20, 15, 6, 1], [6, 36, 90, 120, 90, 36, 6], [15, 90, 225, 300, 225, 90, 15],
          [20, 120, 300, 400, 300, 120, 20], [15, 90, 225, 300, 225, 90, 15], [6, 36, 90, 120, 90, 36, 6],
          [1, 6, 15, 20, 15, 6, 1]]


def test_gauss5_and_gauss7_are_powers_of_bartlett():
    assert kernel_weights("bartlett * (bartlett * g)")[1] == printed(GAUSS5, Fraction(1, 16 ** 2))
    assert kernel_weights("(bartlett)^3 * g")[1] == printed(GAUSS7, Fraction(1, 16 ** 3))
    assert kernel_weights("gauss5")[1] == printed(GAUSS5, Fraction(1, 256))
    assert kernel_weights("h_Gauss^{7×7} ⊗ g")[1] == printed(GAUSS7, Fraction(1, 4096))


@pytest.mark.parametrize("text, vector, scale", [
    ("(h_box^{2×2})^2 ⊗↓ g", [0, 0, 0, 1, 1, 1, 1], Fraction(1, 4)),
    ("(h_box^{4×4})^2 ⊗↓ g", [0, 0, 0, 0, 1, 1, 2, 2, 2, 2, 2, 2, 1, 1, 0], Fraction(1, 16)),
    ("(h_quadratic^{4×4})^2 ⊗↓ g", [0, 0, 0, 0, 1, 3, 6, 10, 12, 12, 10, 6, 3, 1, 0], Fraction(1, 64)),
])
def test_squared_analysis_filters(text, vector, scale):
    stride, w = kernel_weights(text)
    assert stride == (4, 4)
    assert w == printed_outer(vector, scale)


@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_box_power_m_is_a_box_of_width_2_to_the_m(m):
    n = 2 ** m
    stride, w = kernel_weights(f"(box)^{m} *v g")
    vector = [0] * (n - 1) + [1] * n
    assert stride == (n, n)
    assert w == printed_outer(vector, Fraction(1, n))


def test_quasi_interpolation_identity():
    quasi = algebra.mask_weights(catalogue.mask("quasi").mask)
    assert quasi == printed([[-1, -2, -1], [-2, 36, -2], [-1, -2, -1]], Fraction(1, 24))
    bartlett = algebra.mask_weights(catalogue.mask("bartlett").mask)
    rhs = {d: -Fraction(16, 24) * v for d, v in bartlett.items()}
    rhs[(0, 0)] += Fraction(10, 6)
    assert quasi == rhs


def test_quasi_then_cubic_bspline_reproduces_cubics():
    # The cubic B-spline limit at the knots is [1 4 1]/6 per axis; quasi ⊗ that must have
    # the moments of the identity up to degree 3 (cubic precision, §5.5 / Litke et al.).
    quasi = algebra.mask_weights(catalogue.mask("quasi").mask)
    b = {-1: Fraction(1, 6), 0: Fraction(4, 6), 1: Fraction(1, 6)}
    total: dict = {}
    for (qr, qc), v in quasi.items():
        for br, x in b.items():
            for bc, y in b.items():
                key = (qr + br, qc + bc)
                total[key] = total.get(key, 0) + v * x * y
    for a in range(4):
        for c in range(4 - a):
            moment = sum(v * d[0] ** a * d[1] ** c for d, v in total.items())
            assert moment == (1 if a == c == 0 else 0), (a, c)


# (decomposition, atomic filter, the paper's printed form when it differs)
DECOMPOSITIONS = [
    ("box\\ * (box^nw *v g)", "box4 *v g", "box\\ * (box\\ *v g)"),
    ("box\\ *v (bartlett * g)", "quadratic *v g", None),
    ("box\\ *v (bartlett * (box^nw * g))", "cubic *v g", "box\\ *v (bartlett * (box\\ * g))"),
    ("box^nw * (midpoint *^ g)", "doosabin *^ g", "box\\ * (midpoint *^ g)"),
    ("box\\ * (doosabin *^ g)", "cubic *^ g", None),
    # §4.2 prints h_Bartlett ⊗↓ g ≡ h_box↘ ⊗↓ (h_box↘ ⊗ g) and mentions "an additional shift":
    # the masks say it holds exactly only with alternating arrows (an erratum docs/design.md §3 lacks).
    ("box\\ *v (box^nw * g)", "bartlett *v g", "box\\ *v (box\\ * g)"),
]


@pytest.mark.parametrize("chain, atomic, misprint", DECOMPOSITIONS)
def test_decomposition_interior(chain, atomic, misprint):
    assert algebra.kernel(parse(chain)) == algebra.kernel(parse(atomic))
    if misprint:
        assert algebra.kernel(parse(misprint)) != algebra.kernel(parse(atomic))


@pytest.mark.parametrize("chain, atomic, misprint", DECOMPOSITIONS)
@pytest.mark.parametrize("shape", slow_beyond([(1, 1), (2, 3), (5, 4), (7, 9)], 2))
def test_decomposition_at_borders_with_guard_rows(chain, atomic, misprint, shape):
    """With every intermediate computed where the next step reads it (row 0 of
    box↖ ⊗↓ g kept, §4.2), the decomposition equals the atomic filter at every pixel."""
    g = np.random.default_rng(7).random(shape)
    want = reference.run(parse(atomic), g)
    got = extended_chain(algebra.chain_steps(parse(chain)), g, want.shape)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_box4_decomposition_needs_row_zero():
    """Clamping the intermediate instead of keeping row 0 corrupts the first row (§4.2)."""
    g = np.random.default_rng(3).random((8, 8))
    written = reference.run(parse("box\\ * (box^nw *v g)"), g)
    atomic = reference.run(parse("box4 *v g"), g)
    assert not np.allclose(written[0], atomic[0])
    np.testing.assert_allclose(written[1:, 1:], atomic[1:, 1:], atol=1e-12)


@pytest.mark.parametrize("text, cls", [
    ("box *v g", "C^-1"), ("box4 *v g", "C^0"), ("quadratic *v g", "C^1"), ("cubic *v g", "C^2"),
    ("bartlett *v g", "C^0"), ("bartlett * (box\\ *v g)", "C^0"), ("box\\ * (bartlett *v g)", "C^1"),
    ("nearest", "C^-1"), ("midpoint", "C^0"), ("doosabin", "C^1"), ("cubic *^ g", "C^2"), ("fourpoint", "C^1"),
    # §5.3 calls midpoint ⊗↑ (box↘ ⊗ g) "only C⁰"; its mask is ¼(1+z)²(1+z²) = midpoint's (1+z)/2 times
    # box4's C⁰ mask, so it is C¹ (test_continuity_matches_subdivision_limits checks it numerically).
    ("midpoint *^ (box\\ * g)", "C^1"),
])
def test_continuity_classes_from_the_paper(text, cls):
    assert algebra.continuity_name(algebra.continuity(algebra.kernel(parse(text)))) == cls


def test_continuity_of_a_plain_convolution_is_undefined():
    assert algebra.continuity(algebra.kernel(parse("bartlett"))) is None


@pytest.mark.parametrize("text, lattice", [
    ("box *v g", "dual"), ("box4 *v g", "dual"), ("quadratic *v g", "dual"), ("cubic *v g", "primal"),
    ("midpoint", "primal"), ("doosabin", "dual"), ("cubic *^ g", "primal"), ("fourpoint", "primal"),
    ("doosabin *^ (box4 *v g)", "primal"), ("midpoint *^ (box4 *v g)", "shifted"),
])
def test_lattices_of_design_section_4(text, lattice):
    assert algebra.lattice(algebra.kernel(parse(text)))[0] == lattice


def _derivative_jumps(mask, order, levels):
    """Max jump of the order-th divided difference of the subdivision limit after ``levels`` steps."""
    f = np.zeros(16)
    f[8] = 1.0
    for _ in range(levels):
        up = np.zeros(2 * len(f))
        up[::2] = f
        f = np.convolve(up, mask)
    d = f
    for _ in range(order):
        d = np.diff(d) * 2 ** levels
    return np.max(np.abs(np.diff(d)))


@pytest.mark.parametrize("text", ["nearest", "midpoint", "doosabin", "cubic *^ g", "fourpoint",
                                  "midpoint *^ (box\\ * g)", "box^nw * (midpoint *^ g)"])
def test_continuity_matches_subdivision_limits(text):
    """An independent numeric check: C^k means the k-th derivative's jumps vanish as levels grow,
    and the (k+1)-th derivative's do not."""
    k = algebra.kernel(parse(text))
    cls = algebra.continuity(k)
    row_mask = {}
    for (pr, pc), w in k.phases.items():
        if pr == 0:
            for (dr, dc), v in w.items():
                if dr == 0:
                    e = (pc or 2) - 2 + 2 * dc  # a[c − 2⌈c/2⌉ + 2d], 1-D along columns
                    row_mask[e] = row_mask.get(e, 0) + float(v)
    lo = min(row_mask)
    mask = np.array([row_mask.get(i, 0.0) for i in range(lo, max(row_mask) + 1)])
    mask *= 2 / mask.sum()
    if cls >= 0:
        assert _derivative_jumps(mask, cls, 13) < 0.6 * _derivative_jumps(mask, cls, 11)
    assert _derivative_jumps(mask, cls + 1, 13) > 0.6 * _derivative_jumps(mask, cls + 1, 11)
