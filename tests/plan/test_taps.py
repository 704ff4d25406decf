"""Bilinear taps for exact weights (pyramid_cli.plan.taps)."""

from fractions import Fraction as F

from pyramid_cli.plan import taps


def test_a_2x2_box_is_one_linear_fetch_between_four_texels():
    (tap,) = taps.taps_for({(0, 0): F(1, 4), (0, 1): F(1, 4), (1, 0): F(1, 4), (1, 1): F(1, 4)}, 0)
    assert tap.linear and tap.offset == (F(1, 2), F(1, 2)) and tap.weight == 1 and tap.source == 0


def test_taps_reproduce_the_weights_they_replace():
    weights = {(0, 0): F(1, 16), (0, 1): F(3, 16), (1, 0): F(3, 16), (1, 1): F(9, 16)}
    total = sum(t.weight for t in taps.taps_for(weights, 2))
    assert total == 1
