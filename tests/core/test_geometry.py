"""Sizes of levels, lattices and strides (pyramid_cli.core.geometry)."""

import pytest

from pyramid_cli.core import geometry


def test_levels_halve_rounding_up_down_to_one_pixel():
    assert geometry.level_sizes((5, 3), 3) == [(5, 3), (3, 2), (2, 1), (1, 1)]
    assert geometry.mip_levels((5, 3)) == 3 and geometry.mip_levels((1, 1)) == 0
    assert geometry.reduced(5) == 3 and geometry.ceil_div(5, 2) == 3 and geometry.ceil_div(4, 2) == 2


@pytest.mark.parametrize("n", [1, 2, 7, 64, 129])
def test_mip_levels_reach_one_pixel(n):
    sizes = geometry.level_sizes((n, 2 * n + 1), geometry.mip_levels((n, 2 * n + 1)))
    assert sizes[-1] == (1, 1) and sizes[-2] != (1, 1)
