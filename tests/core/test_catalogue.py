"""The named filters of the paper (pyramid_cli.core.catalogue)."""

from fractions import Fraction

import pytest

from pyramid_cli.core import catalogue


@pytest.mark.parametrize("key", catalogue.ANALYSIS_FILTERS)
def test_analysis_masks_sum_to_one(key):
    mask = catalogue.mask(key).mask
    assert sum(sum(row) for row in mask) == 1


def test_box4_is_the_paper_s_4x4_box():
    box4 = catalogue.mask("box4")
    assert box4.kind == "analysis" and box4.mask == tuple((Fraction(1, 16),) * 4 for _ in range(4))



@pytest.mark.parametrize("key", catalogue.SYNTHESIS_FILTERS)
def test_every_synthesis_phase_sums_to_one(key):
    filt = catalogue.synthesis(key)
    assert filt.key == key and len(filt.phases) == 4
    assert all(sum(sum(row) for row in mask) == 1 for mask in filt.phases.values())
