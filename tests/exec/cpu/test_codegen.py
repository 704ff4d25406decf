"""The generated numba kernel source (``pyramid_cli.exec.cpu.codegen``): one canonical text per pass shape,
taps expanded into texel terms, separable weights factored."""

from __future__ import annotations

from fractions import Fraction

import pytest

import pyramid_cli.plan.shapes as generate
from helpers.plans import planned

pytest.importorskip("numba")

from pyramid_cli.exec import cpu  # noqa: E402


def test_kernel_source_is_canonical_and_unrolled():
    _, a = planned("gauss7", (9, 9), "paper")
    _, b = planned("bartlett", (40, 3), "paper")
    texts = {cpu.kernel_source(generate.shape(ps)) for ps in a.passes + b.passes}
    assert len(texts) == 2
    _, ds = planned("doosabin", (8, 8))
    text = cpu.kernel_source(generate.shape(ds.passes[0]))
    assert "cache=True" in text and "v0_3 = t0[" in text and "if C == 4:" in text  # RGBA unrolled
    assert "np.float32(0.25)" in text and "np.float32(0.75)" in text  # one vertical (¼, ¾) sum per row phase
    # one text for float32, float16 and 8/16-bit code sources: such a row goes through the table once, into a
    # scratch row
    assert "def kernel(out, s0, h0, e0, lut, half, C," in text and "half_row(e0, " in text
    assert text.count("lut[") == text.count("= lut[hr[g]]") > 0


def test_rgb_is_unrolled_where_a_strided_loop_has_one_column_phase():
    """The analysis passes (stride 2, one phase) have a copy for C = 3; a synthesis pass's phased loops do not (its
    compile would take 1.2 s more, for four phases)."""
    _, p = planned("box4 *v g", (40, 40))
    texts = {generate.shape(ps).stride: cpu.kernel_source(generate.shape(ps)) for ps in p.passes}
    assert "if C == 3:" in texts[(2, 2)] and "v3_2 = t0[" in texts[(2, 2)]
    _, ds = planned("doosabin", (8, 8))
    assert "if C == 3:" not in cpu.kernel_source(generate.shape(ds.passes[0]))


def test_resampling_and_pointwise_passes_share_one_kernel_each():
    from pyramid_cli.exec.cpu import codegen

    assert "if axis == 0:" in codegen.resample_source()
    text = codegen.pointwise_source()
    for op, code in codegen.POINTWISE_CODES.items():
        assert f"op == {code}:  # {op}" in text and codegen.POINTWISE_EXPR[op] in text


def test_phase_terms_expand_taps_exactly():
    """A tap at a quarter position becomes its four texels, with the bilinear weights, summed per texel."""
    _, p = planned("doosabin", (8, 8))
    for _, taps in generate.shape(p.passes[0]).phases:
        terms = cpu.phase_terms(taps)
        assert sum(t.weight for t in terms) == 1 and len(terms) == 4
        assert sorted(t.weight for t in terms) == [Fraction(1, 16), Fraction(3, 16), Fraction(3, 16), Fraction(9, 16)]


def test_factor_splits_only_separable_weights():
    u, (v,) = cpu.factor([{(0, 0): Fraction(1, 4), (0, 1): Fraction(1, 4), (1, 0): Fraction(1, 4),
                           (1, 1): Fraction(1, 4)}])
    assert u == {0: Fraction(1, 2), 1: Fraction(1, 2)} and v == {0: Fraction(1, 2), 1: Fraction(1, 2)}
    assert cpu.factor([{(0, 0): Fraction(1), (1, 1): Fraction(1)}]) is None
