"""The float64 oracle of MIP levels (pyramid_cli.reference.mip): its resampling matrices against the planner's
exact tables, and what a level of it keeps. Executors against it: tests/plan/test_resample.py."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.marks import slow_beyond
from helpers.oracles import as_1d, paper_weights
from pyramid_cli.core import catalogue
from pyramid_cli.core.geometry import mip_sizes
from pyramid_cli.plan.resample import axis_table, dense
from pyramid_cli.reference.mip import bilinear_matrix, kernel_1d, mip_reference, resample_matrix

BORDERS = ["clamp", "mirror", "wrap", "zero"]





@pytest.mark.parametrize("key", slow_beyond(catalogue.ANALYSIS_FILTERS, 1))
@pytest.mark.parametrize("border", BORDERS)
def test_the_reference_matrix_equals_the_exact_table(key, border):
    """The two derivations (float64 integral of the kernel, exact Fractions) agree everywhere."""
    d, w = zip(*paper_weights(key).items(), strict=True)
    for n, m in [(7, 3), (13, 6), (8, 4), (3, 1), (2, 1), (1001, 500)]:
        exact = np.array([[float(v) if v else 0.0 for v in row]  # mostly zeros: float() of a Fraction is slow
                          for row in dense(*axis_table(as_1d(key), n, m), n, border)])
        np.testing.assert_allclose(resample_matrix(np.array(d), np.array(w, dtype=float), n, m, border), exact,
                                   atol=1e-15, err_msg=f"{n}→{m}")


@pytest.mark.parametrize("key", catalogue.ANALYSIS_FILTERS)
def test_kernel_1d_is_the_papers_index_formula(key):
    d, w = kernel_1d(key)
    got = {k: v for k, v in zip(d.tolist(), w.tolist(), strict=True) if v}
    assert got == {k: float(v) for k, v in paper_weights(key).items()}
    assert kernel_1d("box *v g") is None


def test_bilinear_matrix_is_the_identity_at_the_same_size_and_rows_sum_to_one():
    np.testing.assert_array_equal(bilinear_matrix(5, 5, "clamp"), np.eye(5))
    for border in ("clamp", "mirror", "wrap"):
        np.testing.assert_allclose(bilinear_matrix(3, 8, border).sum(axis=1), 1, atol=1e-15)


def test_mip_reference_keeps_the_mean_of_a_constant_down_to_one_texel():
    x = np.full((13, 6, 2), 0.25)
    levels = mip_reference(x, "quadratic", "clamp")
    assert [lv.shape[:2] for lv in levels] == mip_sizes((13, 6))
    for level in levels:
        np.testing.assert_allclose(level, 0.25, atol=1e-15)
    with pytest.raises(ValueError, match="axis_weights"):
        mip_reference(x, "box *v g")
