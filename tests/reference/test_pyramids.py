"""The pyramids' float64 oracle (pyramid_cli.reference.pyramids) checked against the filters' reference composed
level by level, and its analysis and synthesis halves against each other."""

import numpy as np
import pytest

from helpers.oracles import reference_blur
from pyramid_cli.core.geometry import level_sizes
from pyramid_cli.core.parse import parse
from pyramid_cli.reference import filters as reference
from pyramid_cli.reference.pyramids import (
    blur_blend_reference,
    blur_reference,
    collapse_reference,
    laplacian_reference,
    levels_reference,
)


def test_library_blur_reference_matches():
    g = np.random.default_rng(5).random((19, 23, 2))
    np.testing.assert_allclose(blur_reference(g, 3, "quadratic", "cubic", True),
                               reference_blur(g, 3, "quadratic", "cubic", True), atol=0)


def test_levels_reference_is_the_analysis_filter_repeated():
    g = np.random.default_rng(7).random((21, 17, 2))
    levels = levels_reference(g, 3, "box4")
    assert [x.shape[:2] for x in levels] == level_sizes(g.shape[:2], 3)
    np.testing.assert_array_equal(levels[0], g)
    np.testing.assert_allclose(levels[2], reference.run(parse("box4 *v g"), reference.run(parse("box4 *v g"), g)),
                               atol=0)


@pytest.mark.parametrize("synthesis", ["doosabin", "cubic"])
def test_laplacian_bands_collapse_back_to_the_input(synthesis):
    g = np.random.default_rng(8).random((19, 23))
    bands = laplacian_reference(g, 3, "quadratic", synthesis)
    assert len(bands) == 4 and bands[-1].shape == level_sizes(g.shape, 3)[-1]
    np.testing.assert_allclose(collapse_reference(bands, synthesis), g, atol=1e-12)


def test_blur_blend_reference_runs_from_one_blur_to_the_next():
    g = np.random.default_rng(9).random((16, 16))
    np.testing.assert_array_equal(blur_blend_reference(g, 0, 0.0), g)
    np.testing.assert_allclose(blur_blend_reference(g, 1, 1.0), blur_reference(g, 2), atol=1e-15)
    one, two = blur_reference(g, 1), blur_reference(g, 2)
    np.testing.assert_allclose(blur_blend_reference(g, 1, 0.25), 0.75 * one + 0.25 * two, atol=1e-15)
